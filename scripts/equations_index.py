#!/usr/bin/env python3
"""docs/equations.md: which code cites each numbered equation of the thesis (issue 30 item 4).

Every "Eq. 3.41", "Eqs. 3.9-3.18" (a range stands for each equation in it, within one chapter),
"Eqs. 3.36, 3.38" or "Eqs. 5.16-5.20 and 5.23" in a string, docstring or comment of the code
under src/ (tests and build outputs left out) is found with `tokenize`, and placed in the
function, method or class around it with `ast`'s line ranges. The page has one table per thesis
chapter, one row per cited equation: the thesis section it belongs to and where the code cites it.

The sections, the chapter titles and the equations no code cites come from the thesis text
(its equation labels "(3.41)" / "\\tag{3.41}" and its numbered headings). Where the thesis is not
at hand they are read back from the page itself, so `--check` still judges the code's side.

    .venv/bin/python scripts/equations_index.py           # writes docs/equations.md
    .venv/bin/python scripts/equations_index.py --check   # exit 1 if docs/equations.md is stale
"""

from __future__ import annotations

import argparse
import ast
import io
import re
import sys
import tokenize
from bisect import bisect_right
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / 'docs' / 'equations.md'
THESIS_NAME = 'space-variant-vision-thesis.txt'
# where a checkout keeps the thesis: a shared/ beside or inside the repository
THESIS_PLACES = (ROOT.parent / 'shared' / 'thesis' / THESIS_NAME,
                 ROOT / 'shared' / 'thesis' / THESIS_NAME, ROOT / 'thesis' / THESIS_NAME)
SKIP_DIRS = {'test', 'tests', 'build', 'install', 'log', '__pycache__'}

Eq = tuple[int, int]          # (chapter, number): Eq. 3.41 is (3, 41)

_NUM = r'\(?\d+\.\d+(?!\d|\.\d)\)?'       # not the 3.3 of a section number 3.3.2
_ITEM = rf'{_NUM}(?:\s*[-\u2013\u2014]\s*{_NUM})?'
# "Eq." / "Eqs." / "Equation(s)", then a number or range, then more joined by ',', 'and', '&'
CITE = re.compile(rf'\b(?:Eqs?\.?|Equations?)\s*(?P<items>{_ITEM}(?:\s*(?:,|and|&|,\s*and)\s*'
                  rf'{_ITEM})*)')
ITEM = re.compile(r'\(?(\d+)\.(\d+)\)?(?:\s*[-\u2013\u2014]\s*\(?(\d+)\.(\d+)\)?)?')


def fmt(eq: Eq) -> str:
    return f'{eq[0]}.{eq[1]}'


def parse_citations(text: str) -> Iterator[tuple[int, list[Eq], list[str]]]:
    """(offset, equations, problems) of each citation in `text`: ranges expanded within their
    chapter; a range across chapters or backwards stands for its two ends only, with a problem
    saying so."""
    for m in CITE.finditer(text):
        eqs: list[Eq] = []
        problems: list[str] = []
        for it in ITEM.finditer(m.group('items')):
            a = (int(it.group(1)), int(it.group(2)))
            if it.group(3) is None:
                eqs.append(a)
                continue
            b = (int(it.group(3)), int(it.group(4)))
            if a[0] == b[0] and a[1] <= b[1]:
                eqs.extend((a[0], n) for n in range(a[1], b[1] + 1))
            else:
                problems.append(f'range {fmt(a)}-{fmt(b)} is not within one chapter in order: '
                                'indexed as its two ends')
                eqs.extend((a, b))
        yield m.start(), eqs, problems


@dataclass(frozen=True, order=True)
class Citation:
    eq: Eq
    path: str        # repository-relative, posix
    line: int
    scope: str       # 'Class.method', 'function.inner', or '' at module level


def scopes(tree: ast.AST) -> list[tuple[int, int, str]]:
    """(first line, last line, qualified name) of every def and class, outer ones first."""
    out: list[tuple[int, int, str]] = []

    def visit(node: ast.AST, prefix: str) -> None:
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.FunctionDef | ast.AsyncFunctionDef | ast.ClassDef):
                name = f'{prefix}{child.name}'
                first = min([child.lineno] + [d.lineno for d in child.decorator_list])
                out.append((first, child.end_lineno or child.lineno, name))
                visit(child, name + '.')
            else:
                visit(child, prefix)
    visit(tree, '')
    return out


def scope_at(table: list[tuple[int, int, str]], line: int) -> str:
    """The innermost def or class whose lines hold `line` ('' for the module)."""
    best = ''
    best_first = 0
    for first, last, name in table:
        if first <= line <= last and first >= best_first:
            best, best_first = name, first
    return best


def _string_body(tok: str) -> tuple[str, int]:
    """A string token's text between its quotes, and the body's column offset in the token."""
    i = 0
    while i < len(tok) and tok[i] not in '\'"':
        i += 1
    q = 3 if tok[i:i + 3] in ('"""', "'''") else 1
    return tok[i + q:len(tok) - q], i + q


def _text_runs(source: str) -> Iterator[list[tuple[int, str]]]:
    """Runs of (first line, text) pieces to search as one text: the comments on consecutive
    lines, the strings of one implicit concatenation, so that a citation broken over lines is
    whole."""
    run: list[tuple[int, str]] = []
    kind = ''
    last_line = 0
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type == tokenize.COMMENT:
            if kind != 'comment' or tok.start[0] != last_line + 1:
                if run:
                    yield run
                run, kind = [], 'comment'
            run.append((tok.start[0], tok.string.lstrip('#')))
            last_line = tok.start[0]
        elif tok.type == tokenize.STRING:
            if kind != 'string' and run:
                yield run
                run = []
            kind = 'string'
            body, _ = _string_body(tok.string)
            run.append((tok.start[0], body))
        elif tok.type in (tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT):
            continue
        else:
            if run:
                yield run
            run, kind = [], ''
    if run:
        yield run


def scan_source(source: str, path: str,
                problems: list[str] | None = None) -> list[Citation]:
    """Every equation citation in one file's source, with its line and enclosing def/class."""
    table = scopes(ast.parse(source))
    out: list[Citation] = []
    for run in _text_runs(source):
        text = '\n'.join(body for _, body in run)
        starts = []
        at = 0
        for _, body in run:
            starts.append(at)
            at += len(body) + 1
        for offset, eqs, probs in parse_citations(text):
            k = bisect_right(starts, offset) - 1
            first_line, body = run[k]
            line = first_line + body[:offset - starts[k]].count('\n')
            scope = scope_at(table, line)
            out.extend(Citation(eq, path, line, scope) for eq in eqs)
            if problems is not None:
                problems.extend(f'{path}:{line}: {p}' for p in probs)
    return out


def source_files(root: Path) -> list[Path]:
    """src/**/*.py without tests, build outputs and hidden folders, in a stable order."""
    return sorted(p for p in (root / 'src').rglob('*.py')
                  if not any(part in SKIP_DIRS or part.startswith('.')
                             for part in p.relative_to(root).parts[:-1])
                  and not p.name.startswith('test_'))


def scan_tree(root: Path, problems: list[str]) -> list[Citation]:
    out: list[Citation] = []
    for p in source_files(root):
        rel = p.relative_to(root).as_posix()
        try:
            out.extend(scan_source(p.read_text(encoding='utf-8'), rel, problems))
        except (SyntaxError, UnicodeDecodeError, tokenize.TokenError) as e:
            problems.append(f'{rel}: not read ({e.__class__.__name__}: {e}): '
                            'its citations left out')
    return out


@dataclass
class Thesis:
    """What the page needs of the thesis: chapter titles, how many equations each chapter
    numbers, and the section each equation is in ('' where it cannot be told)."""
    titles: dict[int, str] = field(default_factory=dict)
    count: dict[int, int] = field(default_factory=dict)
    sections: dict[Eq, str] = field(default_factory=dict)
    source: str = ''


CHAPTER = re.compile(r'^Chapter (\d+)[ \t]*\n\s*\n?(\S[^\n]*)$', re.M)
HEADING = re.compile(r'^(\d+)((?:\.\d+)+)[ \t]+([A-Z][^\n]{2,90})$', re.M)
# an equation's own label: \tag{3.41}, or (3.41) ending a line or before the closing $$
LABEL = re.compile(r'\\tag\{(\d+)\.(\d+)\}|\((\d+)\.(\d+)\)[ \t]*(?=\$\$|$)', re.M)


def read_thesis(text: str) -> Thesis:
    th = Thesis(source='the thesis text')
    for m in CHAPTER.finditer(text):
        th.titles.setdefault(int(m.group(1)), m.group(2).strip())
    heads = [(m.start(), int(m.group(1)), f'{m.group(1)}{m.group(2)} {m.group(3).strip()}')
             for m in HEADING.finditer(text)]
    found: dict[Eq, str] = {}
    for m in LABEL.finditer(text):
        c, n = int(m.group(1) or m.group(3)), int(m.group(2) or m.group(4))
        if (c, n) in found:
            continue                          # a later mention, not the label
        sec = ''
        for pos, chap, name in heads:
            if pos > m.start():
                break
            if chap == c:
                sec = name
        found[(c, n)] = sec
    for c, n in found:
        th.count[c] = max(th.count.get(c, 0), n)
    for c, last in th.count.items():
        for n in range(1, last + 1):
            if (c, n) in found:
                th.sections[(c, n)] = found[(c, n)]
                continue
            # a label the text extraction lost: the section its labelled neighbours share
            below = [found[(c, k)] for k in range(n - 1, 0, -1) if (c, k) in found][:1]
            above = [found[(c, k)] for k in range(n + 1, last + 1) if (c, k) in found][:1]
            th.sections[(c, n)] = below[0] if below and below == above else ''
    return th


NOT_IN_THESIS = 'not in the thesis'
PAGE_CHAPTER = re.compile(r'^## Chapter (\d+): (.+)$', re.M)
PAGE_ROW = re.compile(r'^\| (\d+)\.(\d+) \| ([^|]*) \|', re.M)
PAGE_UNCITED = re.compile(r'^Cited nowhere: (.+)\.$', re.M)


def read_page(text: str) -> Thesis:
    """The thesis facts as an earlier run wrote them on the page."""
    th = Thesis(source='docs/equations.md (the thesis text was not found)')
    for m in PAGE_CHAPTER.finditer(text):
        th.titles[int(m.group(1))] = m.group(2).strip()
    for m in PAGE_ROW.finditer(text):
        sec = m.group(3).strip()
        if sec != NOT_IN_THESIS:
            th.sections[(int(m.group(1)), int(m.group(2)))] = sec
    for m in PAGE_UNCITED.finditer(text):
        for _, eqs, _ in parse_citations('Eqs. ' + m.group(1)):
            th.sections.update((eq, th.sections.get(eq, '')) for eq in eqs)
    for c, n in th.sections:
        th.count[c] = max(th.count.get(c, 0), n)
    return th


def load_thesis() -> Thesis:
    for p in THESIS_PLACES:
        if p.is_file():
            return read_thesis(p.read_text(encoding='utf-8'))
    return read_page(DOC.read_text(encoding='utf-8')) if DOC.is_file() else Thesis(source='')


def ranges(nums: Iterable[int]) -> list[tuple[int, int]]:
    out: list[tuple[int, int]] = []
    for n in sorted(nums):
        if out and out[-1][1] == n - 1:
            out[-1] = (out[-1][0], n)
        else:
            out.append((n, n))
    return out


def link(c: Citation) -> str:
    # the path without src/<package>/, which repeats the package's name; no line anchor: the
    # function names the place, and a line number would make every edit elsewhere in the file
    # stale the page
    parts = c.path.split('/')
    short = '/'.join(parts[2:]) if parts[0] == 'src' and len(parts) > 3 else c.path
    where = f'{short}:{c.scope}' if c.scope else short
    return f'[{where}](../{c.path})'


def render(cites: list[Citation], th: Thesis) -> str:
    by_eq: dict[Eq, list[Citation]] = {}
    for c in sorted(cites, key=lambda c: (c.eq, c.path, c.line)):
        same = [d for d in by_eq.get(c.eq, []) if (d.path, d.scope) == (c.path, c.scope)]
        if not same:                  # one link per function: its first citation's line
            by_eq.setdefault(c.eq, []).append(c)
    files = {c.path for c in cites}
    sites = sum(len(v) for v in by_eq.values())
    total = sum(th.count.values())
    in_thesis = sum(1 for eq in by_eq if eq in th.sections)
    lines = [
        '# Equation index', '',
        '<!-- generated by scripts/equations_index.py from the citations in src/ '
        '(`.venv/bin/python scripts/equations_index.py`, `--check` tells whether it is stale) -->',
        '',
        'Which code implements or cites each numbered equation of the thesis: every "Eq. 3.41", '
        '"Eqs. 3.9-3.18" (a range counts for each equation in it) or "Eqs. 3.36, 3.38" in a '
        'docstring, string or comment under src/ (tests left out), with the function, method or '
        'class it is in; a link goes to the first such line in that function. Sections, chapter '
        'titles and the equations no code cites are read from the thesis\'s equation labels and '
        'headings.', '',
        f'{len(by_eq)} equations cited ({in_thesis} of the thesis\'s {total}), at {sites} places '
        f'(function and equation) in {len(files)} files.', '',
    ]
    chapters = sorted({eq[0] for eq in by_eq} | set(th.count))
    for ch in chapters:
        title = th.titles.get(ch, '')
        lines += [f'## Chapter {ch}: {title}' if title else f'## Chapter {ch}', '']
        rows = sorted(eq for eq in by_eq if eq[0] == ch)
        if rows:
            lines += ['| Eq. | Section | Cited in |', '|---|---|---|']
            for eq in rows:
                sec = th.sections.get(eq, NOT_IN_THESIS if th.count else '')
                lines.append(f'| {fmt(eq)} | {sec} | '
                             + '<br>'.join(link(c) for c in by_eq[eq]) + ' |')
            lines.append('')
        uncited = [n for n in range(1, th.count.get(ch, 0) + 1) if (ch, n) not in by_eq]
        if uncited:
            lines += ['Cited nowhere: ' + ', '.join(
                f'{ch}.{a}' if a == b else f'{ch}.{a}-{ch}.{b}' for a, b in ranges(uncited))
                + '.', '']
    return '\n'.join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or '').splitlines()[0])
    ap.add_argument('--check', action='store_true', help='exit 1 if docs/equations.md is stale')
    args = ap.parse_args(argv)
    problems: list[str] = []
    cites = scan_tree(ROOT, problems)
    th = load_thesis()
    text = render(cites, th)
    for p in problems:
        print(p, file=sys.stderr)
    rel = DOC.relative_to(ROOT) if DOC.is_relative_to(ROOT) else DOC
    if args.check:
        if not DOC.is_file() or DOC.read_text(encoding='utf-8') != text:
            print(f'{rel} is stale: run scripts/equations_index.py', file=sys.stderr)
            return 1
        return 0
    if not th.source:
        print('the thesis text was not found: sections and uncited equations left out',
              file=sys.stderr)
    DOC.write_text(text, encoding='utf-8')
    eqs = {c.eq for c in cites}
    print(f'wrote {rel}: {len(eqs)} equations, {len(cites)} citations '
          f'in {len({c.path for c in cites})} files (thesis facts from {th.source or "nowhere"})')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
