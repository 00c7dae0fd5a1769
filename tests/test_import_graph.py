"""No import cycle inside any package (issue 14, item 6), checked statically.

Every `import` and `from ... import` in a package's modules counts, at module level or inside a
function (a lazy import that closes a loop is still a loop a reader has to untangle); imports
under `if TYPE_CHECKING:` do not (they never run). Edges go from a module to the modules of
the same package it names; strongly connected components of more than one module are cycles.
"""
from __future__ import annotations

import ast
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / 'src'
PACKAGES = ('rftgls_core', 'rftgls_ros', 'minirquad_driver')


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
    assert len(mods) > 5
    assert cycles(import_edges(mods)) == []
