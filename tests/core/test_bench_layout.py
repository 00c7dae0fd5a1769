"""Benchmark modules: the timing helpers are a leaf, and no section imports the runner back."""
import ast
import math
from pathlib import Path

import rftgls_core
from rftgls_core.timing import Figure, format_value

PKG = Path(rftgls_core.__file__).resolve().parent


def imported_modules(path: Path) -> set[str]:
    """Absolute or relative ('.x', '..x') module names a file imports."""
    names = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            names.add('.' * node.level + (node.module or ''))
    return names


def test_timing_is_a_leaf_module():
    mods = imported_modules(PKG / 'timing.py')
    assert mods and not any(m.startswith('.') or m.startswith('rftgls_core') for m in mods)


def test_map_bench_does_not_import_the_runner():
    mods = imported_modules(PKG / 'maps' / 'bench.py')
    assert '..timing' in mods
    assert not {'..bench', 'rftgls_core.bench', '..'} & mods


def test_format_value():
    assert format_value(Figure('x', 0.01234, 'ms')) == '0.0123'
    assert format_value(Figure('x', 1.5e8, 'pairs/s')) == '1.500e+08'
    assert format_value(Figure('x', math.nan, 'ms')) == 'nan'
