"""The import graph, checked statically: packages depend on each other only downward, and
no package has an import cycle inside it.

Direction (docs/design/architecture.md, "Layout"): rftgls_conventions at the bottom; the
ROS-free core and the node base on it; the driver, which runs on the robot, on the node base
only (no solver, no map code); the simulator on the driver and the core; the nodes on the core
and the node base, never on the simulator.

Every `import` and `from ... import` in a package's modules counts, at module level or inside a
function (a lazy import that closes a loop is still a loop a reader has to untangle); imports
under `if TYPE_CHECKING:` do not (they never run). Edges go from a module to the modules of
the same package it names; strongly connected components of more than one module are cycles.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest
from repo_layout import PYTHON_PACKAGES, packages

SRC = Path(__file__).resolve().parents[1] / 'src'
# The packages with Python modules (minirquad_description is data only).
PACKAGES = tuple(p for p in PYTHON_PACKAGES if (SRC / p / p).is_dir())
# Which of the repository's packages each Python package may import.
ALLOWED = {
    'rftgls_conventions': set(),
    'rftgls_core': {'rftgls_conventions'},
    'rftgls_node_base': {'rftgls_conventions'},
    'minirquad_driver': {'rftgls_conventions', 'rftgls_node_base', 'rftgls_interfaces'},
    'minirquad_sim': {'rftgls_conventions', 'rftgls_node_base', 'rftgls_core',
                      'minirquad_driver'},
    'rftgls_ros': {'rftgls_conventions', 'rftgls_node_base', 'rftgls_core',
                   'rftgls_interfaces', 'tf2_msgs'},
}
REPO_PACKAGES = set(PYTHON_PACKAGES) | set(packages('ament_cmake'))


def module_names(pkg_dir: Path, pkg: str) -> dict[str, Path]:
    mods = {}
    for f in pkg_dir.rglob('*.py'):
        parts = list(f.relative_to(pkg_dir.parent).with_suffix('').parts)
        if parts[-1] == '__init__':
            parts = parts[:-1]
        mods['.'.join(parts)] = f
    return mods


def _is_type_checking(node: ast.If) -> bool:
    t = node.test
    return (isinstance(t, ast.Name) and t.id == 'TYPE_CHECKING') or (
        isinstance(t, ast.Attribute) and t.attr == 'TYPE_CHECKING')


def _imports(tree: ast.AST):
    stack = [tree]
    while stack:
        node = stack.pop()
        for child in ast.iter_child_nodes(node):
            if isinstance(child, ast.If) and _is_type_checking(child):
                stack.extend(child.orelse)
                continue
            if isinstance(child, (ast.Import, ast.ImportFrom)):
                yield child
            stack.append(child)


def import_edges(mods: dict[str, Path]) -> dict[str, set[str]]:
    edges: dict[str, set[str]] = {m: set() for m in mods}
    for mod, path in mods.items():
        is_pkg = path.name == '__init__.py'
        here = mod.split('.') if is_pkg else mod.split('.')[:-1]
        for node in _imports(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            else:
                if node.level:
                    base = here[:len(here) - node.level + 1]
                    prefix = '.'.join(base + ([node.module] if node.module else []))
                else:
                    prefix = node.module or ''
                targets = [f'{prefix}.{a.name}' if f'{prefix}.{a.name}' in mods else prefix
                           for a in node.names]
            for t in targets:
                while t and t not in mods:  # `import a.b.c` names a.b.c's package chain
                    t = t.rpartition('.')[0]
                if t and t != mod:
                    edges[mod].add(t)
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in edges[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def test_checker_finds_a_cycle_and_ignores_type_checking(tmp_path):
    pkg = tmp_path / 'p'
    pkg.mkdir()
    (pkg / '__init__.py').write_text('')
    (pkg / 'a.py').write_text('from .b import x\n')
    (pkg / 'b.py').write_text('def f():\n    from . import a\n')
    (pkg / 'c.py').write_text('from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n'
                              '    from .a import y\n')
    edges = import_edges(module_names(pkg, 'p'))
    assert cycles(edges) == [['p.a', 'p.b']]
    assert 'p.a' not in edges['p.c']


@pytest.mark.parametrize('pkg', PACKAGES)
def test_no_import_cycle(pkg):
    mods = module_names(SRC / pkg / pkg, pkg)
    assert mods                  # the scan found the package's modules
    assert cycles(import_edges(mods)) == []


def first_party_imports(pkg_dir: Path, repo_packages: set[str]) -> dict[str, set[str]]:
    """Repository package -> files of pkg_dir's package that import it (at any depth)."""
    out: dict[str, set[str]] = {}
    for f in pkg_dir.rglob('*.py'):
        for node in _imports(ast.parse(f.read_text(), str(f))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for n in names:
                top = n.split('.')[0]
                if top in repo_packages:
                    out.setdefault(top, set()).add(f.name)
    return out


def test_every_package_has_a_rule():
    assert set(ALLOWED) == set(PACKAGES)


@pytest.mark.parametrize('pkg', PACKAGES)
def test_packages_import_only_downward(pkg):
    used = first_party_imports(SRC / pkg / pkg, REPO_PACKAGES - {pkg})
    forbidden = {p: sorted(fs) for p, fs in used.items() if p not in ALLOWED[pkg]}
    assert not forbidden, f'{pkg} imports {forbidden}'


def test_the_direction_check_sees_a_forbidden_import(tmp_path):
    pkg = tmp_path / 'minirquad_driver'
    pkg.mkdir()
    (pkg / 'bridge.py').write_text('def f():\n    from rftgls_core.maps import query\n')
    used = first_party_imports(pkg, REPO_PACKAGES)
    assert set(used) == {'rftgls_core'} and 'rftgls_core' not in ALLOWED['minirquad_driver']
