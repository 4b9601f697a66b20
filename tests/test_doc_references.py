# Copyright 2026 Actuator control team
# SPDX-License-Identifier: Apache-2.0

"""Every documentation reference names a file, and a heading, that exist.

Code cites the documentation by path and anchor (``docs/safety.md#recovery-policy``), never a
section of the README by name. Checked here:

- every ``*.md`` path cited in ``src/``, ``tests/`` and ``scripts/`` (a path with a folder,
  relative to the repository root, optionally with ``#anchor``) names an existing file, and the
  anchor a heading of it;
- every relative link of the repository's Markdown files (``[text](target)``, images and
  reference definitions) names an existing file or folder, and its anchor a heading;
- no code names the README without a path (``README "Safety"``, ``the README's table``).

Anchors follow GitHub's rule: the heading's text in lower case, punctuation dropped, spaces to
``-``, and ``-1``, ``-2`` ... for repeated headings.
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Iterator, NamedTuple

import pytest

ROOT = Path(__file__).resolve().parent.parent
#: Where code may cite documentation.
CODE_DIRS = ('src', 'tests', 'scripts')
#: Files read as code (scripts without a suffix too, e.g. scripts/ros2run).
CODE_SUFFIXES = {'.py', '.sh', '.toml', '.cfg', '.ini', '.xml', '.yaml', '.yml', ''}
#: Folders never read: build products, the environment, run outputs.
SKIPPED_DIRS = {
    '.git',
    '.venv',
    'build',
    'install',
    'log',
    'results',
    '__pycache__',
    '.pytest_cache',
    '.ruff_cache',
    'mutants',
}
#: A cited Markdown path in code: at least one folder, optional $VAR/ prefix, optional anchor.
CITED = re.compile(r'(?<![\w./-])(?:\$\{?\w+\}?/)?((?:[\w.-]+/)+[\w.-]+\.md)(#[\w-]*)?')
#: The README named without its path, and a section cited by name after a path.
README_BY_NAME = re.compile(r'\bREADME\b(?!\.md)')
SECTION_BY_NAME = re.compile(r'\.md\)?,?\s+"[^"]+"')
#: Inline and image links, and reference definitions.
INLINE_LINK = re.compile(r'!?\[[^\]]*\]\(\s*<?([^)\s>]+)>?(?:\s+"[^"]*")?\s*\)')
REFERENCE_DEF = re.compile(r'^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s|$)', re.M)
FENCE = re.compile(r'^\s*(```|~~~)')
HEADING = re.compile(r'^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$')
CODE_SPAN = re.compile(r'(`+)(.+?)\1')


class Problem(NamedTuple):
    """One reference that does not resolve: where it is, what it names, why it fails."""

    where: str
    target: str
    why: str

    def __str__(self) -> str:
        """Return the problem as one line."""
        return f'{self.where}: {self.target}: {self.why}'


def github_anchor(heading: str) -> str:
    """Return the anchor GitHub gives a heading (without the duplicate suffix)."""
    text = re.sub(r'!?\[([^\]]*)\]\([^)]*\)', r'\1', heading)  # a link's text only
    text = text.strip().lower()
    text = re.sub(r'[^\w\- ]', '', text)  # punctuation dropped; letters, digits, _ and - kept
    return text.replace(' ', '-')


def _walk(root: Path, top: str) -> Iterator[Path]:
    """Yield every file below root/top, skipping build products and run outputs."""
    for folder, dirs, files in os.walk(root / top):
        dirs[:] = sorted(d for d in dirs if d not in SKIPPED_DIRS)
        for name in sorted(files):
            yield Path(folder) / name


def _prose_lines(text: str) -> Iterator[tuple[int, str]]:
    """Yield (line number, line) of Markdown outside fenced code blocks."""
    fenced = None
    for number, line in enumerate(text.splitlines(), 1):
        match = FENCE.match(line)
        if match:
            if fenced is None:
                fenced = match.group(1)
            elif match.group(1) == fenced:
                fenced = None
            continue
        if fenced is None:
            yield number, line


def anchors(path: Path) -> set[str]:
    """Return every anchor of a Markdown file's headings, duplicates numbered as GitHub does."""
    seen: dict[str, int] = {}
    out = set()
    for _, line in _prose_lines(path.read_text(encoding='utf-8')):
        match = HEADING.match(line)
        if not match:
            continue
        base = github_anchor(match.group(2))
        count = seen.get(base, 0)
        seen[base] = count + 1
        out.add(base if count == 0 else f'{base}-{count}')
    return out


def markdown_files(root: Path) -> list[Path]:
    """Return the repository's Markdown files (bags/ and results/ hold runs, not docs)."""
    found = [p for p in sorted(root.glob('*.md'))]
    for top in sorted(p.name for p in root.iterdir() if p.is_dir() and p.name not in SKIPPED_DIRS):
        found += [p for p in _walk(root, top) if p.suffix == '.md']
    return found


def check_target(root: Path, base: Path, target: str, where: str) -> list[Problem]:
    """Check one reference: path relative to base (a folder), optional #anchor."""
    path_text, _, anchor = target.partition('#')
    path = (base / path_text).resolve() if path_text else None
    if path is not None:
        try:
            rel = path.relative_to(root).as_posix()
        except ValueError:
            return [Problem(where, target, 'points outside the repository')]
        if not path.exists():
            return [Problem(where, target, f'no file {rel}')]
        if path.is_dir():
            return [Problem(where, target, 'an anchor on a folder')] if anchor else []
    if not anchor:
        return []
    page = path if path is not None else None
    if page is None or page.suffix != '.md':
        return [Problem(where, target, 'an anchor on a file that is not Markdown')]
    if anchor not in anchors(page):
        return [Problem(where, target, f'no heading with the anchor #{anchor}')]
    return []


def markdown_problems(root: Path) -> list[Problem]:
    """Return every relative link of the Markdown files that does not resolve."""
    problems = []
    for md in markdown_files(root):
        text = md.read_text(encoding='utf-8')
        rel = md.relative_to(root).as_posix()
        for number, line in _prose_lines(text):
            line = CODE_SPAN.sub('', line)
            for target in INLINE_LINK.findall(line) + REFERENCE_DEF.findall(line):
                if re.match(r'[a-z][a-z0-9+.-]*:', target, re.I):  # http:, mailto:, ...
                    continue
                if target.startswith('#'):
                    problems += check_target(root, md.parent, md.name + target, f'{rel}:{number}')
                else:
                    problems += check_target(root, md.parent, target, f'{rel}:{number}')
    return problems


def code_files(root: Path, skip: tuple[Path, ...] = ()) -> Iterator[Path]:
    """Yield the files of src/, tests/ and scripts/ read as code."""
    for top in CODE_DIRS:
        if not (root / top).is_dir():
            continue
        for path in _walk(root, top):
            if path.suffix in CODE_SUFFIXES and path.resolve() not in skip:
                yield path


def code_problems(root: Path, skip: tuple[Path, ...] = ()) -> list[Problem]:
    """Return every Markdown path cited in code that does not resolve, and every README by name."""
    problems = []
    for path in code_files(root, skip):
        try:
            text = path.read_text(encoding='utf-8')
        except UnicodeDecodeError:
            continue
        rel = path.relative_to(root).as_posix()
        for number, line in enumerate(text.splitlines(), 1):
            where = f'{rel}:{number}'
            for match in CITED.finditer(line):
                cited = match.group(1) + (match.group(2) or '')
                if cited.startswith('../'):  # outside the repository (a sibling checkout)
                    continue
                problems += check_target(root, root, cited, where)
            if README_BY_NAME.search(line):
                problems.append(
                    Problem(where, line.strip(), 'names the README without a path and anchor')
                )
            elif SECTION_BY_NAME.search(line):
                problems.append(Problem(where, line.strip(), 'a section by name: cite #anchor'))
    return problems


def test_github_anchor_rule():
    assert github_anchor("Tuned for the drive's delay") == 'tuned-for-the-drives-delay'
    assert github_anchor('CiA 402 driver (`actuator_cia402 cia402_driver`)') == (
        'cia-402-driver-actuator_cia402-cia402_driver'
    )
    assert github_anchor('Middleware: UDP only in real time') == 'middleware-udp-only-in-real-time'
    assert github_anchor('See [the guide](x.md) now') == 'see-the-guide-now'


def test_every_markdown_link_resolves():
    problems = markdown_problems(ROOT)
    assert not problems, '\n'.join(map(str, problems))


@pytest.mark.slow
def test_every_document_cited_in_code_resolves_and_no_code_names_the_readme():
    problems = code_problems(ROOT, skip=(Path(__file__).resolve(),))
    assert not problems, '\n'.join(map(str, problems))


def test_a_made_up_reference_fails(tmp_path):
    """A synthetic tree: each broken reference is found, each sound one is not."""
    (tmp_path / 'docs').mkdir()
    (tmp_path / 'src' / 'pkg').mkdir(parents=True)
    (tmp_path / 'docs' / 'a.md').write_text(
        '# A page\n\n## Real heading\n\n## Real heading\n\n'
        'See [b](b.md), [itself](#real-heading-1), [gone](#gone), [out](../../x.md).\n'
        '```\n[not a link](nowhere.md)\n```\n'
        'And `[code](nowhere.md)` and [web](https://example.com/x.md).\n'
    )
    (tmp_path / 'src' / 'pkg' / 'mod.py').write_text(
        '# docs/a.md#real-heading is fine, and so is docs/a.md\n'
        '# docs/a.md#made-up-heading is not\n'
        '# nor docs/missing.md\n'
        '# "$ROOT/docs/missing.md" neither\n'
        '# ../shared/outside.md is another checkout: not checked\n'
        '# README_FIGURE is a name, README.md a path, ' + 'README "Safety" a section by name\n'
        '# and docs/a.md "Real heading" a section by name too\n'
    )
    md = markdown_problems(tmp_path)
    assert sorted((p.where, p.target) for p in md) == [
        ('docs/a.md:7', '../../x.md'),
        ('docs/a.md:7', 'a.md#gone'),
        ('docs/a.md:7', 'b.md'),
    ], md
    code = code_problems(tmp_path)
    assert sorted((p.where, p.target) for p in code) == [
        ('src/pkg/mod.py:2', 'docs/a.md#made-up-heading'),
        ('src/pkg/mod.py:3', 'docs/missing.md'),
        ('src/pkg/mod.py:4', 'docs/missing.md'),
        (
            'src/pkg/mod.py:6',
            '# README_FIGURE is a name, README.md a path, README "Safety" a section by name',
        ),
        ('src/pkg/mod.py:7', '# and docs/a.md "Real heading" a section by name too'),
    ], code
