"""The machine a benchmark run measured: what it is, and its own arithmetic limit in that run.

Figures from a shared 2-core machine mean little without the CPU they came from: the same
code ran 3x slower on one EPYC of this project's machine kind (Zen 3, AVX2) than on another
(Zen 4, AVX-512). So every run records the CPU, what numba and numpy compile for, and the
load, and measures the peak it compares the engine against:

- `peak_gflops_1core` / `_2core`: float64 multiply-adds per second of a probe that does
  nothing else (sixteen dependent multiply-adds per element of a 256-element array in L1,
  vectorised by numba for the same target as the RFT kernels), on one and on two threads.
  On Zen 3 and Zen 4 that is 2 FMA pipes x 4 float64 lanes x 2 flops = 16 flops per cycle:
  the arithmetic limit of any float64 kernel here. A matrix multiply reaches ~90 % of it.

`CPU_TARGETS` are the environments that make this CPU compile and dispatch as another x86-64
class would (docs/design/numerics.md): numba's target CPU *and* its features (the CPU name
alone keeps the host's AVX-512 features), numpy's SIMD dispatch and OpenBLAS's kernels.
"""
from __future__ import annotations

import math
import os
import platform
import time
from datetime import UTC, datetime

import numpy as np

from .timing import Figure

try:
    import numba
except ImportError:  # pragma: no cover - numba is in the lock; the engine falls back to numpy
    numba = None  # type: ignore[assignment]

# Environments of other x86-64 CPU classes (set before the process imports numpy or numba).
CPU_TARGETS = {
    # Zen 3 class: AVX2 + FMA, no AVX-512 (x86-64-v3).
    'x86-64-v3': {'NUMBA_CPU_NAME': 'znver3', 'NUMBA_CPU_FEATURES': '',
                  'NPY_DISABLE_CPU_FEATURES': 'X86_V4 AVX512_ICL AVX512_SPR',
                  'OPENBLAS_CORETYPE': 'Zen'},
    # No AVX, no FMA (x86-64-v2).
    'x86-64-v2': {'NUMBA_CPU_NAME': 'nehalem', 'NUMBA_CPU_FEATURES': '',
                  'NPY_DISABLE_CPU_FEATURES': 'X86_V3 X86_V4 AVX512_ICL AVX512_SPR',
                  'OPENBLAS_CORETYPE': 'Nehalem'},
}
_SIMD_FLAGS = ('avx', 'avx2', 'fma', 'avx512f')
# Elements of the probe's array (2 KB: in L1) and multiply-adds per element per pass.
_PROBE_N = 256
_PROBE_FMAS = 16


def _cpuinfo() -> dict[str, str]:
    """The first processor's fields of /proc/cpuinfo ({} where there is none)."""
    try:
        with open('/proc/cpuinfo', encoding='ascii', errors='replace') as f:
            text = f.read().split('\n\n')[0]
    except OSError:
        return {}
    out = {}
    for line in text.splitlines():
        key, _, value = line.partition(':')
        out[key.strip()] = value.strip()
    return out


def numba_target() -> dict:
    """The CPU numba compiles for and which SIMD features it may use."""
    if numba is None:
        return {'cpu': 'none (numba missing)', 'features': []}
    import llvmlite.binding as ll
    cpu = getattr(numba.config, 'CPU_NAME', None) or ll.get_host_cpu_name()
    feats = getattr(numba.config, 'CPU_FEATURES', None)
    if feats is None:
        feats = ll.get_host_cpu_features().flatten()
    on = {f[1:] for f in feats.split(',') if f.startswith('+')}
    if feats == '':
        # No feature string: LLVM takes the CPU name's own features.
        on = {'znver3': {'avx', 'avx2', 'fma'}, 'znver2': {'avx', 'avx2', 'fma'},
              'haswell': {'avx', 'avx2', 'fma'}, 'nehalem': set()}.get(cpu, {'?'})
    return {'cpu': cpu, 'features': sorted(on & set(_SIMD_FLAGS) | ({'?'} & on))}


def _threads_max() -> int:
    return int(getattr(numba.config, 'NUMBA_NUM_THREADS', 1)) if numba is not None else 1


def numpy_simd() -> list[str]:
    """numpy's SIMD dispatch targets enabled in this process."""
    try:
        from numpy._core._multiarray_umath import __cpu_dispatch__, __cpu_features__
    except ImportError:  # pragma: no cover - other numpy layouts
        return []
    return [f for f in __cpu_dispatch__ if __cpu_features__.get(f)]


def machine_record() -> dict:
    """CPU, cores, SIMD, numba's target, numpy's dispatch, versions and load (JSON-ready)."""
    info = _cpuinfo()
    flags = set(info.get('flags', '').split())
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - non-Linux
        cores = os.cpu_count() or 1
    target = numba_target()
    load = os.getloadavg() if hasattr(os, 'getloadavg') else (math.nan,) * 3
    return {
        'cpu_model': info.get('model name', platform.processor() or platform.machine()),
        'cpu_family_model': f"{info.get('cpu family', '?')}/{info.get('model', '?')}",
        'cpu_simd': [f for f in _SIMD_FLAGS if f in flags],
        'virtualised': 'hypervisor' in flags,
        'cores': cores,
        'numba_target': f"{target['cpu']} ({'+'.join(target['features']) or 'no AVX'})",
        'numba_threads': _threads_max(),
        'numpy_simd': numpy_simd(),
        'openblas_coretype': os.environ.get('OPENBLAS_CORETYPE', 'auto'),
        'python': platform.python_version(),
        'numpy': np.__version__,
        'numba': numba.__version__ if numba is not None else 'missing',
        'loadavg_1min_start': round(load[0], 2),
        'date_utc': datetime.now(UTC).isoformat(timespec='minutes'),
    }


def describe(record: dict) -> str:
    """One line: 'AMD EPYC (25/17), 2 cores, KVM guest, AVX2+FMA+AVX-512F; numba znver4 ...'."""
    simd = '+'.join(f.upper() for f in record['cpu_simd']) or 'no AVX'
    return (f"{record['cpu_model']} (family/model {record['cpu_family_model']}), "
            f"{record['cores']} cores{', virtualised' if record['virtualised'] else ''}, "
            f"{simd}; numba {record['numba']} for {record['numba_target']}, "
            f"numpy {record['numpy']} SIMD {'+'.join(record['numpy_simd']) or 'baseline'}, "
            f"OpenBLAS {record['openblas_coretype']}; load {record['loadavg_1min_start']} "
            f"at start, {record['date_utc']}")


def _horner(x, y, c, passes):
    """y = a 16-step Horner polynomial of x, `passes` times (the probe's work). Four elements
    per iteration, each its own chain: one chain per vector leaves the FMA pipes waiting on
    its latency within the scheduler's window (44 instead of 58 GFLOP/s with AVX2 here)."""
    c0, c1, c2 = c[0], c[1], c[2]
    q = x.shape[0] // 4
    for _ in range(passes):
        for i in range(q):
            a, b, d, e = x[i], x[i + q], x[i + 2 * q], x[i + 3 * q]
            pa, pb, pd, pe = a * c0 + c1, b * c0 + c1, d * c0 + c1, e * c0 + c1
            for _k in range(_PROBE_FMAS - 1):
                pa = pa * a + c2
                pb = pb * b + c2
                pd = pd * d + c2
                pe = pe * e + c2
            y[i], y[i + q], y[i + 2 * q], y[i + 3 * q] = pa, pb, pd, pe


if numba is not None:
    _horner = numba.njit(cache=True, fastmath={'contract'}, nogil=True)(_horner)

    @numba.njit(cache=True, fastmath={'contract'}, parallel=True)
    def _horner_threads(x, y, c, passes):
        for t in numba.prange(x.shape[0]):
            _horner(x[t], y[t], c, passes)


def peak_gflops(threads: int, call_s: float = 0.002, repeats: int = 60) -> float:
    """Best float64 GFLOP/s of the FMA probe on `threads` threads (each its own array).

    Calls of ~2 ms, best of 60, like the kernels' own short calls: on a loaded machine a
    call that long still often runs undisturbed, so the best call measures the core and not
    the load (0.15 s calls measured half the peak at load 6)."""
    if numba is None:
        return math.nan
    probe = _horner_threads
    x = np.full((threads, _PROBE_N), 0.5)
    y = np.empty_like(x)
    c = np.array([0.1, -0.2, 0.3])
    before = numba.get_num_threads()
    numba.set_num_threads(threads)
    try:
        probe(x, y, c, 1)
        best = math.inf
        for _ in range(5):
            # per-thread work calibrated on one thread (a parallel call under load can wait
            # a whole time slice for its second thread)
            t0 = time.perf_counter()
            _horner(x[0], y[0], c, 100)
            best = min(best, time.perf_counter() - t0)
        passes = max(10, int(100 * call_s / max(best, 1e-9)))
        best = math.inf
        for _ in range(repeats):
            t0 = time.perf_counter()
            probe(x, y, c, passes)
            best = min(best, time.perf_counter() - t0)
    finally:
        numba.set_num_threads(before)
    return 2.0 * _PROBE_FMAS * _PROBE_N * threads * passes / best / 1e9


def peak_figures() -> list[Figure]:
    """The run's own arithmetic limit: the FMA probe on one and on two threads."""
    what = (f'float64 FMA probe ({_PROBE_FMAS} dependent multiply-adds per element, '
            f'{_PROBE_N} elements in L1, four chains per iteration), numba, best of 60 '
            'calls of ~2 ms')
    one = peak_gflops(1)
    two = peak_gflops(2) if _threads_max() >= 2 else math.nan
    return [Figure('peak_gflops_1core', one, 'GFLOP/s', note=f'{what}, one thread'),
            Figure('peak_gflops_2core', two, 'GFLOP/s', note=f'{what}, two threads'),
            Figure('peak_2core_speedup', two / one, 'x', note='two threads / one thread of '
                   'the probe: what two threads can give on this machine now')]
