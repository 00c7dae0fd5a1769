"""The repository stands alone: every file a text cites must be in the repository.

A newcomer with only a clone must be able to follow every reference. This test reads the
tracked text files (py, md, yaml, cfg, xml, txt, toml, ini, sh) and reports:

- any pointer outside the repository to the design notes or the paper it was built from
  (`FORBIDDEN`, e.g. a parent-directory path into a shared folder);
- a design page named without its path (the names the outside notes had, `NOTE_STEMS`, used as
  "<stem> 5.3"): cite docs/design/<page>.md instead;
- any `*.md` path that does not exist: relative to the repository root or to the citing file's
  folder; a bare file name (no folder) may also sit in one of the citing file's ancestor folders
  (a package's protocol spec next to its setup.py);
- a `#fragment` after an existing `.md` file that names no heading of that file (GitHub slugs);
- a section number after a `docs/design/` page ("docs/design/models-rft.md 4.8") that is not
  the number of one of its headings;
- in Markdown files, a relative link target `](path)` that does not exist.

No ROS. Reasonable false-positive guards: URLs are ignored, and `GENERATED` names the output
files that tools write (cited as what they produce, not as repository files).
"""
from __future__ import annotations

import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
TEXT_SUFFIXES = {'.py', '.md', '.yaml', '.yml', '.cfg', '.xml', '.txt', '.toml', '.ini', '.sh'}
# Binary files whose metadata carries text (HDF5 attributes, bag metadata): their bytes are read
# as Latin-1 and checked like text, so a stored provenance string cannot cite a missing file.
BINARY_WITH_TEXT = {'.h5', '.mcap'}
# Written without the literal strings, so this file does not cite them itself.
FORBIDDEN = ('..' + '/shared', 'shared' + '/design', 'shared' + '/paper')
# Files a tool writes when it runs; texts name them as outputs.
# Stems of the design notes the docs were first written from; without `.md` they still name a
# file (e.g. "<stem> 5.3"), so they must be written as a docs/design/<stem>.md path.
NOTE_STEMS = ('models-rft', 'limit-surfaces', 'ros2-from-pip', 'minirquad-hardware', 'peers',
              'architecture')
_NOTE_STEM = re.compile(r'(?<![\w/.#-])(' + '|'.join(NOTE_STEMS) + r')(?=\s+(?:section\s+)?\d)')
GENERATED = {'table.md': 'written by rftgls_ros.lab.evaluate (see src/rftgls_ros/lab_README.md)'}
# Generated files (lab sample bags, shipped maps) are checked in their own test: a failure
# there is fixed by regenerating them with their recorded command.
GENERATED_FILES = ('src/rftgls_ros/rftgls_ros/lab/', 'maps/prototype_glass_beads.h5',
                   'maps/minirquad_m90_sand.h5', 'maps/minirquad_m90_sand_gaits_sled400g.h5',
                   'maps/minirquad_m90_sand_gaits_sled600g.h5')
# Directories that are never part of the repository (fallback walk without git).
_IGNORED_DIRS = {'.git', '.venv', 'build', 'install', 'log', 'out', '__pycache__', '.pytest_cache'}

_URL = re.compile(r'[a-zA-Z][a-zA-Z0-9+.-]*://\S+')
_MD_PATH = re.compile(r'(?<![\w./-])((?:\.{1,2}/)*(?:[\w.-]+/)*[\w.-]*\w\.md)(#[\w-]+)?\b')
_SECTION = re.compile(r'[,:]?\s+(?:sections?\s+|§\s*)?(\d+(?:\.\d+)?)(?:[a-z])?(?![\w.])')
_MD_LINK = re.compile(r'\]\(([^)\s]+)\)')
_LINK_LABEL = re.compile(r'\[[^\]]*\]\(')
_HEADING = re.compile(r'^\s{0,3}(#{1,6})\s+(.*?)\s*#*\s*$')


@dataclass(frozen=True)
class Problem:
    path: str
    line: int
    what: str

    def __str__(self) -> str:
        return f'{self.path}:{self.line}: {self.what}'


def slugify(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces to hyphens."""
    text = re.sub(r'[^\w\- ]', '', heading.strip().lower())
    return text.replace(' ', '-')


def headings(markdown: str) -> list[str]:
    """Heading texts of a Markdown document, outside fenced code blocks."""
    out, fenced = [], False
    for line in markdown.splitlines():
        if line.lstrip().startswith('```'):
            fenced = not fenced
            continue
        m = None if fenced else _HEADING.match(line)
        if m:
            out.append(m.group(2))
    return out


def anchors(markdown: str) -> set[str]:
    seen: dict[str, int] = {}
    result = set()
    for h in headings(markdown):
        slug = slugify(h)
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        result.add(slug if n == 0 else f'{slug}-{n}')
    return result


def section_numbers(markdown: str) -> set[str]:
    """'4.8' for '### 4.8 Reference values', '8' for '## 8. Media presets'."""
    nums = set()
    for h in headings(markdown):
        m = re.match(r'(\d+(?:\.\d+)*)[.\s]', h + ' ')
        if m:
            nums.add(m.group(1))
    return nums


class Repo:
    """The repository's files: which paths exist and the text of Markdown targets."""

    def __init__(self, root: Path, files: set[str], read=None):
        self.root = root
        self.files = files                      # repo-relative POSIX paths
        self.dirs = {str(Path(f).parent.as_posix()) for f in files}
        self._read = read or (lambda rel: (root / rel).read_text(encoding='utf-8'))

    def exists(self, rel: str) -> bool:
        rel = os.path.normpath(rel).replace(os.sep, '/')
        return rel in self.files or rel in self.dirs

    def text(self, rel: str) -> str:
        return self._read(os.path.normpath(rel).replace(os.sep, '/'))

    def resolve(self, token: str, citing: str) -> str | None:
        """Repo-relative path of `token` cited from file `citing`, or None if nowhere."""
        folder = Path(citing).parent
        candidates = [folder / token, Path(token)]
        if '/' not in token:
            candidates += [p / token for p in folder.parents]
        for c in candidates:
            rel = os.path.normpath(c.as_posix())
            if rel.startswith('..'):
                continue
            if self.exists(rel):
                return rel.replace(os.sep, '/')
        return None


def check_text(text: str, citing: str, repo: Repo) -> list[Problem]:
    problems: list[Problem] = []
    is_md = citing.endswith('.md')
    for lineno, line in enumerate(text.splitlines(), 1):
        for bad in FORBIDDEN:
            if bad in line:
                problems.append(Problem(citing, lineno, f'points outside the repository: {bad!r}'))
        clean = _URL.sub(' ', line)
        for m in _NOTE_STEM.finditer(clean):
            problems.append(Problem(citing, lineno, f'{m.group(1)!r} names a design page without '
                                                    'its path: cite docs/design/<page>.md'))
        if is_md:  # a link's label names its target for people; the target is what counts
            clean = _LINK_LABEL.sub(lambda m: '[' + ' ' * (len(m.group(0)) - 3) + '](', clean)
        for m in _MD_PATH.finditer(clean):
            token, fragment = m.group(1), m.group(2)
            if Path(token).name in GENERATED:
                continue
            target = repo.resolve(token, citing)
            if target is None:
                problems.append(Problem(citing, lineno, f'{token} is not in the repository'))
                continue
            problems += _check_target(citing, lineno, target, fragment,
                                      clean[m.end():], repo)
        if is_md:
            for m in _MD_LINK.finditer(clean):
                link = m.group(1)
                path, _, fragment = link.partition('#')
                if not path or path.startswith('mailto:') or path.endswith('.md'):
                    continue  # same-page anchors, mail, and .md links (checked above)
                if repo.resolve(path, citing) is None:
                    problems.append(Problem(citing, lineno, f'link target {link} is not in the '
                                                            'repository'))
            for m in re.finditer(r'\]\((#[\w-]+)\)', clean):
                problems += _check_target(citing, lineno, citing, m.group(1), '', repo)
    return problems


def _check_target(citing, lineno, target, fragment, after, repo) -> list[Problem]:
    if not target.endswith('.md'):
        return []
    out = []
    if fragment and fragment[1:] not in anchors(repo.text(target)):
        out.append(Problem(citing, lineno, f'{target}{fragment}: no such heading'))
    if target.startswith('docs/design/') and not fragment:
        sec = _SECTION.match(after)
        if sec and sec.group(1) not in section_numbers(repo.text(target)):
            out.append(Problem(citing, lineno, f'{target} has no section {sec.group(1)}'))
    return out


def tracked_files(root: Path) -> set[str]:
    """Tracked and new (not ignored) files; without git, a walk that skips build outputs."""
    try:
        out = subprocess.run(['git', 'ls-files', '-z', '--cached', '--others',
                              '--exclude-standard'], cwd=root, capture_output=True,
                             check=True).stdout.decode()
        return {f for f in out.split('\0') if f and (root / f).is_file()}
    except (OSError, subprocess.CalledProcessError):
        files = set()
        for d, subdirs, names in os.walk(root):
            subdirs[:] = [s for s in subdirs if s not in _IGNORED_DIRS]
            files |= {os.path.relpath(os.path.join(d, n), root) for n in names}
        return files


def repo_problems() -> list[Problem]:
    files = tracked_files(REPO)
    repo = Repo(REPO, files)
    problems = []
    for rel in sorted(files):
        suffix = Path(rel).suffix
        if suffix not in TEXT_SUFFIXES | BINARY_WITH_TEXT:
            continue
        try:
            if suffix in BINARY_WITH_TEXT:
                problems += check_text((REPO / rel).read_bytes().decode('latin-1'), rel, repo)
                continue
            text = (REPO / rel).read_text(encoding='utf-8')
        except FileNotFoundError:
            continue  # an untracked file removed since the listing: not part of the repository
        except UnicodeDecodeError:
            # A text suffix must hold text: fail loudly instead of skipping the file.
            problems.append(Problem(rel, 0, 'not UTF-8 text, so it cannot be checked'))
            continue
        problems += check_text(text, rel, repo)
    return problems


@pytest.fixture(scope='module')
def problems() -> list[Problem]:
    return repo_problems()


def test_every_reference_resolves_inside_the_repository(problems):
    mine = [p for p in problems if not p.path.startswith(GENERATED_FILES)]
    assert not mine, 'references to files outside the repository:\n' + '\n'.join(map(str, mine))


def test_lab_references_resolve_inside_the_repository(problems):
    lab = [p for p in problems if p.path.startswith(GENERATED_FILES)]
    assert not lab, 'references to files outside the repository:\n' + '\n'.join(map(str, lab))


def test_design_index_lists_every_page():
    index = (REPO / 'docs/design/README.md').read_text(encoding='utf-8')
    pages = sorted(p.name for p in (REPO / 'docs/design').glob('*.md') if p.name != 'README.md')
    assert pages, 'docs/design/ has no pages'
    missing = [p for p in pages if f']({p})' not in index]
    assert not missing, f'docs/design/README.md does not link {missing}'


# ------------------------------------------------------------------ the checker itself

def _j(*parts: str) -> str:
    """Joins parts, so the synthetic references below do not appear literally in this file."""
    return ''.join(parts)


PAGE = '# Title\n\n## 1. Common rules\n\n### 4.8 Reference values\n\n## Frames and signs\n'
FAKE = Repo(Path('/nonexistent'), {'docs/design/models-rft.md', 'docs/design/architecture.md',
                                   _j('src/pkg/PROTOCOL', '.md'), 'src/pkg/pkg/mod.py',
                                   'README.md', 'docs/fig.png'},
            read=lambda rel: PAGE)
CITING_MD = _j('docs/x/a', '.md')


@pytest.mark.parametrize('text', [
    _j('see ..', '/shared', '/design/models-rft', '.md'),
    _j('notes in /work/', 'shared', '/design/'),
    _j('see docs/design/nonexistent', '.md'),
    _j('see models-rft', '.md 2.3'),                            # bare name, not next to us
    _j('docs/design/models-rft', '.md#2-li-2013'),              # no such heading
    _j('docs/design/architecture', '.md#frames'),
    _j('docs/design/models-rft', '.md 9.9'),                    # no such section
    _j('docs/design/models-rft', '.md section 7'),
    _j('docs/architecture', '.md section 3'),                   # a path that never existed
    _j('serialises them exactly (ros2-from', '-pip 5.3)'),       # a page without its path
])
def test_checker_flags_references_outside_the_repository(text):
    assert check_text(text, 'src/pkg/pkg/mod.py', FAKE)


@pytest.mark.parametrize('text', [
    _j('see docs/design/models-rft', '.md 4.8 and 2'),           # '2' is not checked (first only)
    _j('docs/design/models-rft', '.md, section 1'),
    _j('docs/design/architecture', '.md#frames-and-signs'),
    _j('specified in PROTOCOL', '.md next to setup.py'),         # in an ancestor folder
    _j('https://github.com/o/r/blob/main/NOTES', '.md'),         # URLs are not repo files
    _j("writes out / 'table", ".md'"),                           # generated output
    'a plain sentence with no reference',
    'the architecture of the limit-surfaces code',               # words, not citations
])
def test_checker_accepts_references_inside_the_repository(text):
    assert check_text(text, 'src/pkg/pkg/mod.py', FAKE) == []


def test_checker_reads_markdown_links_and_anchors():
    good = _j('[page](../design/models-rft', '.md#48-reference-values) ![f](../fig.png)')
    assert check_text(good, CITING_MD, FAKE) == []
    assert check_text('![f](../missing.png)', CITING_MD, FAKE)
    assert check_text('[self](#nowhere)', 'docs/design/architecture.md', FAKE)
    assert check_text('[self](#frames-and-signs)', 'docs/design/architecture.md', FAKE) == []


def test_slugs_follow_github():
    assert slugify('4.8 Reference values') == '48-reference-values'
    assert slugify('Ellipsoid (LG04)') == 'ellipsoid-lg04'
    assert slugify("The paper's median rule") == 'the-papers-median-rule'
    assert slugify('The `ros2 run` stand-in') == 'the-ros2-run-stand-in'
    assert anchors('# A\n## A\n```\n# not a heading\n```\n') == {'a', 'a-1'}
