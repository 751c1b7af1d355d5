"""docs/equations.md is generated from the code's equation citations by
scripts/equations_index.py (issue 30 item 4): a citation added, moved or dropped without the
regenerated page fails here. The citation parser and the def/class it places each citation in
are checked on small made-up sources."""

from __future__ import annotations

import importlib.util
import subprocess
import sys
from pathlib import Path
from types import ModuleType

import pytest

from vizzy_runtime.testing import repo_root, scaled


def test_equations_page_is_generated_from_the_code() -> None:
    root = repo_root()
    run = subprocess.run([sys.executable, str(root / 'scripts' / 'equations_index.py'), '--check'],
                         capture_output=True, text=True, timeout=scaled(120), cwd=root)
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]


@pytest.fixture(scope='module')
def ei() -> ModuleType:
    """scripts/equations_index.py as a module (it is a script, not a package)."""
    path = repo_root() / 'scripts' / 'equations_index.py'
    spec = importlib.util.spec_from_file_location('equations_index', path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules['equations_index'] = mod        # dataclasses resolve the module by name
    spec.loader.exec_module(mod)
    return mod


def eqs(ei: ModuleType, text: str) -> list[str]:
    return [ei.fmt(eq) for _, found, _ in ei.parse_citations(text) for eq in found]


def test_single_equations_ranges_and_lists(ei: ModuleType) -> None:
    assert eqs(ei, 'the midpoint (Eq. 3.8).') == ['3.8']
    assert eqs(ei, 'Eqs. 3.9-3.12') == ['3.9', '3.10', '3.11', '3.12']
    assert eqs(ei, 'Eqs. 3.36, 3.38') == ['3.36', '3.38']
    assert eqs(ei, 'Eqs. 5.3, 5.18-5.20, 5.24') == ['5.3', '5.18', '5.19', '5.20', '5.24']
    assert eqs(ei, 'regions (Eqs. 5.16-5.17 and 5.23)') == ['5.16', '5.17', '5.23']
    assert eqs(ei, 'Equation (2.9) becomes') == ['2.9']
    assert eqs(ei, 'J = -mu (Eqs.\n    3.39-3.40; the thesis') == ['3.39', '3.40']
    # what is not an equation: figures, sections, a section number after a citation
    assert eqs(ei, 'Fig. 3.8 and section 3.3.2') == []
    assert eqs(ei, 'Eq. 4.3 and the normals-only baseline') == ['4.3']
    assert eqs(ei, 'Eqs. 3.6-3.7, 3.3.2 (sensors)') == ['3.6', '3.7']


def test_a_range_across_chapters_is_its_two_ends_with_a_message(ei: ModuleType) -> None:
    (_, found, problems), = ei.parse_citations('Eqs. 3.56-4.2')
    assert [ei.fmt(e) for e in found] == ['3.56', '4.2']
    assert len(problems) == 1 and 'not within one chapter' in problems[0]


SOURCE = '''"""Module docstring: the sensor (Eqs. 3.6-3.7)."""

# a module comment citing Eq. 1.1


class Sensor:
    """The class (Eq. 3.17)."""

    @staticmethod
    def project(x):
        y = x  # the midpoint, Eq. 3.8
        return y

    def weights(self):
        def inner():
            return 0
        # the weights of Eqs.
        # 3.14-3.15, then
        help = ("an implicit concatenation: (Eqs. "
                "3.16, 3.18)")
        return inner, help


def free():
    pass
# after free(), at module level: Eq. 5.2
'''


def test_each_citation_is_placed_in_its_def(ei: ModuleType) -> None:
    problems: list[str] = []
    got = {(ei.fmt(c.eq), c.scope, c.line)
           for c in ei.scan_source(SOURCE, 'src/pkg/pkg/m.py', problems)}
    assert got == {('3.6', '', 1), ('3.7', '', 1), ('1.1', '', 3), ('3.17', 'Sensor', 7),
                   ('3.8', 'Sensor.project', 11),
                   ('3.14', 'Sensor.weights', 17), ('3.15', 'Sensor.weights', 17),
                   ('3.16', 'Sensor.weights', 19), ('3.18', 'Sensor.weights', 19),
                   ('5.2', '', 26)}
    assert problems == []


THESIS = '''Chapter 3

Visual Search

3.3 Methodologies

3.3.2 Stereo Sensor Model

$$x = y$$
(3.1)

$$y = z \\tag{3.2}$$

$$broken by the text extraction

3.3.3 Randomized Sensory Ego-Sphere

$$w = v$$ (3.4)

As Equation (3.1) shows
'''


def test_sections_and_uncited_equations_from_the_thesis_text(ei: ModuleType) -> None:
    th = ei.read_thesis(THESIS)
    assert th.titles == {3: 'Visual Search'}
    assert th.count == {3: 4}
    assert th.sections[(3, 1)] == '3.3.2 Stereo Sensor Model'
    assert th.sections[(3, 4)] == '3.3.3 Randomized Sensory Ego-Sphere'
    assert th.sections[(3, 3)] == ''              # lost label between two sections
    cites = ei.scan_source('# Eqs. 3.1, 3.4 and Eq. 3.9\n', 'src/pkg/pkg/m.py')
    page = ei.render(cites, th)
    assert '| 3.1 | 3.3.2 Stereo Sensor Model | [pkg/m.py](../src/pkg/pkg/m.py) |' in page
    assert '| 3.9 | not in the thesis |' in page
    assert 'Cited nowhere: 3.2-3.3.' in page
    # without the thesis, the page's own facts give the same page back
    assert ei.render(cites, ei.read_page(page)) == page


def test_check_fails_on_a_stale_page_and_needs_no_thesis(
        ei: ModuleType, tmp_path: Path, monkeypatch: pytest.MonkeyPatch,
        capsys: pytest.CaptureFixture[str]) -> None:
    page = (repo_root() / 'docs' / 'equations.md').read_text(encoding='utf-8')
    doc = tmp_path / 'equations.md'
    monkeypatch.setattr(ei, 'DOC', doc)
    monkeypatch.setattr(ei, 'THESIS_PLACES', ())     # a checkout without the thesis
    doc.write_text(page, encoding='utf-8')
    assert ei.main(['--check']) == 0
    doc.write_text(page.replace('| 3.8 |', '| 3.80 |', 1), encoding='utf-8')
    assert ei.main(['--check']) == 1
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and 'is stale: run scripts/equations_index.py' in err[0]
