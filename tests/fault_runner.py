"""Run command-line programs in-process on hostile inputs, bounded in time and memory.

Used by the fault campaigns (tests/lab/test_fault_files.py): each case is a program's
`main(argv)` called in this process, so one interpreter start serves hundreds of cases, with

- a memory limit (RLIMIT_AS) on the whole process: a reader that slurped /dev/zero would die
  here, not take the machine with it;
- a watchdog per case: a reader blocked on a FIFO is reported as `hung` and released (the
  FIFOs of the case are opened for writing and closed, which gives the reader end-of-file).

Input (stdin): JSON {"cases": [{"name", "module", "argv", "fifos"}], "timeout_s"}.
Output (stdout, last line): JSON {name: {"code", "err", "out", "seconds"}}; code "hung" when
the watchdog fired. Each case runs after one untimed warm-up of its module (imports).
"""
from __future__ import annotations

import contextlib
import importlib
import io
import json
import os
import resource
import sys
import threading
import time

MEMORY_LIMIT = 6 << 30     # bytes of address space: numba and BLAS reserve some; 6 GiB is ample


def _release(fifos: list[str]) -> None:
    for path in fifos:
        try:
            fd = os.open(path, os.O_WRONLY | os.O_NONBLOCK)
            os.close(fd)
        except OSError:
            pass


def run_case(case: dict, timeout_s: float) -> dict:
    main = importlib.import_module(case['module']).main
    out, err = io.StringIO(), io.StringIO()
    result: dict = {}

    def target() -> None:
        try:
            with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
                result['code'] = main(case['argv'])
        except SystemExit as exc:
            result['code'] = exc.code if isinstance(exc.code, int) else 2
        except BaseException as exc:  # noqa: BLE001 - reported, the campaign judges it
            result['code'] = f'raised {type(exc).__name__}: {exc}'
    t0 = time.perf_counter()
    worker = threading.Thread(target=target, daemon=True)
    worker.start()
    worker.join(timeout_s)
    seconds = time.perf_counter() - t0
    if worker.is_alive():
        _release(case.get('fifos', []))
        worker.join(5.0)
        result['code'] = 'hung'
    return {'code': result.get('code'), 'err': err.getvalue(), 'out': out.getvalue(),
            'seconds': seconds}


def main() -> int:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
    spec = json.load(sys.stdin)
    timeout_s = float(spec.get('timeout_s', 10.0))
    results = {}
    warm: set[str] = set()
    for case in spec['cases']:
        key = case['module'] + ' ' + ' '.join(case['argv'][:2])
        if key not in warm:    # first use of a program: imports, lazy imports (untimed)
            warm.add(key)
            run_case(case, timeout_s)
        results[case['name']] = run_case(case, timeout_s)
        if results[case['name']]['code'] == 'hung':
            break     # a thread may still hold the process; report what we have
    sys.stdout.write('\n' + json.dumps(results) + '\n')
    return 0


if __name__ == '__main__':
    sys.exit(main())
