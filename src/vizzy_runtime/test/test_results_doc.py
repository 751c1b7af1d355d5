"""docs/results.md is generated from experiments/results/*.json by scripts/results_table.py: a
changed result (or table rule) without the regenerated page fails here."""

from __future__ import annotations

import subprocess
import sys

from vizzy_runtime.testing import repo_root


def test_results_page_is_generated_from_the_results_json() -> None:
    root = repo_root()
    run = subprocess.run([sys.executable, str(root / 'scripts' / 'results_table.py'), '--check'],
                         capture_output=True, text=True, timeout=120, cwd=root)
    assert run.returncode == 0, (run.stdout + run.stderr)[-2000:]
