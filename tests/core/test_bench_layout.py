"""Benchmark modules: the timing helpers are a leaf, no section imports the registry back, the
registry names only sections that exist, and derived figures follow from their inputs."""
import ast
import math
from pathlib import Path

import pytest

import rftgls_core
from rftgls_core.benchmarks import registry
from rftgls_core.benchmarks.report import BEGIN, END, table, write_markdown
from rftgls_core.benchmarks.timing import Figure, format_value

PKG = Path(rftgls_core.__file__).resolve().parent / 'benchmarks'


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


def test_sections_do_not_import_the_registry():
    for name, target in registry.SECTIONS.items():
        module = target.partition(':')[0]
        assert module.startswith('.'), f'{name}: sections live in rftgls_core/benchmarks'
        mods = imported_modules(PKG / f'{module[1:]}.py')
        assert not {'.registry', 'rftgls_core.benchmarks.registry', '.report'} & mods, name
        assert callable(registry.section(name))


def test_format_value():
    assert format_value(Figure('x', 0.01234, 'ms')) == '0.0123'
    assert format_value(Figure('x', 1.5e8, 'pairs/s')) == '1.500e+08'
    assert format_value(Figure('x', math.nan, 'ms')) == 'nan'


def test_share_of_peak_and_numpy_ratio_come_from_the_same_run():
    figures = [Figure('peak_gflops_1core', 50.0, 'GFLOP/s'),
               Figure('peak_gflops_2core', 90.0, 'GFLOP/s'),
               Figure('k_numpy', 4e6, 'pairs/s'),
               Figure('k', 2e8, 'pairs/s', flops=125.0, numpy_ref='k_numpy'),
               Figure('k2', 3.6e8, 'pairs/s', flops=125.0, threads=2)]
    got = {f.name: f.value for f in registry.derived(figures)}
    assert got['k_share_of_peak'] == pytest.approx(2e8 * 125 / 50e9)      # 0.5
    assert got['k2_share_of_peak'] == pytest.approx(3.6e8 * 125 / 90e9)   # two-thread peak
    assert got['k_vs_numpy'] == pytest.approx(50.0)
    assert 'k_numpy_share_of_peak' not in got and 'k2_vs_numpy' not in got
    # Without a measured peak the share is unknown, not a number from elsewhere.
    alone = {f.name: f.value for f in registry.derived(figures[3:4])}
    assert math.isnan(alone['k_share_of_peak']) and math.isnan(alone['k_vs_numpy'])


def test_markdown_table_is_written_between_the_markers_only(tmp_path):
    run = registry.Run({'cpu_model': 'CPU X', 'cpu_family_model': '25/1', 'cores': 2,
                        'virtualised': True, 'cpu_simd': ['avx2', 'fma'],
                        'numba': '0', 'numba_target': 'znver3 (avx2+fma)', 'numpy': '2',
                        'numpy_simd': ['X86_V3'], 'openblas_coretype': 'Zen',
                        'loadavg_1min_start': 0.5, 'loadavg_1min_end': 0.7,
                        'date_utc': '2026-01-01T00:00+00:00', 'cpu_target': 'x86-64-v3'},
                       registry.derived([Figure('peak_gflops_1core', 50.0, 'GFLOP/s'),
                                         Figure('k', 2e8, 'pairs/s', flops=125.0)]))
    doc = tmp_path / 'perf_doc'
    doc.write_text(f'# Title\n\nprose before\n\n{BEGIN}\nold table\n{END}\n\nprose after\n')
    write_markdown(doc, run, 'rftgls bench --cpu x86-64-v3')
    text = doc.read_text()
    assert text.startswith('# Title\n\nprose before\n\n') and text.endswith('\n\nprose after\n')
    assert 'old table' not in text and text.count(BEGIN) == 1
    assert 'CPU X' in text and '`rftgls bench --cpu x86-64-v3`' in text
    assert '| `k` | 2.000e+08 | pairs/s | 0.50 |' in text   # the share in its own column
    assert '`k_share_of_peak`' not in text
    assert table(run, 'c') in text.replace('rftgls bench --cpu x86-64-v3', 'c')
    other = tmp_path / 'notes'
    other.write_text('hand-written, no markers\n')
    with pytest.raises(ValueError, match='markers'):
        write_markdown(other, run, 'c')
    assert other.read_text() == 'hand-written, no markers\n'


def _makefile_env(name: str) -> dict[str, str]:
    """The environment assignments of a `NAME := A=x B="y z" ...` line of the Makefile."""
    import re
    import shlex
    text = (Path(rftgls_core.__file__).resolve().parents[3] / 'Makefile').read_text()
    body = re.search(rf'^{name} := ((?:.*\\\n)*.*)$', text, re.M).group(1).replace('\\\n', ' ')
    return dict(item.split('=', 1) for item in shlex.split(body))


def test_make_test_cpus_and_bench_use_the_same_cpu_targets():
    from rftgls_core.benchmarks.machine import CPU_TARGETS
    assert _makefile_env('CPU_V3') == CPU_TARGETS['x86-64-v3']
    assert _makefile_env('CPU_V2') == CPU_TARGETS['x86-64-v2']


def test_the_x86_64_v3_target_compiles_without_avx512():
    # numba keeps the host's features when only NUMBA_CPU_NAME is set (a Zen 4 then still gets
    # AVX-512 code): the target must name the features too. Compiled in a fresh process with
    # the target's environment, a vectorised loop uses 256-bit registers and no 512-bit ones.
    import os
    import subprocess
    import sys

    from rftgls_core.benchmarks.machine import CPU_TARGETS
    code = ('import re, numpy as np, numba\n'
            'f = numba.njit(lambda x: (x * 2.0 + 1.0).sum())\n'
            'f(np.ones(64))\n'
            'asm = list(f.inspect_asm().values())[0]\n'
            'print(len(re.findall("zmm", asm)), len(re.findall("ymm", asm)))\n')
    env = {**os.environ, **CPU_TARGETS['x86-64-v3'], 'NUMBA_CACHE_DIR': '/nonexistent'}
    out = subprocess.run([sys.executable, '-c', code], env=env, capture_output=True, text=True,
                         timeout=120, check=True).stdout.split()
    zmm, ymm = int(out[0]), int(out[1])
    assert zmm == 0 and ymm > 0
