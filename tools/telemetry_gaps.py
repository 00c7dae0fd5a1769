"""Gaps between the simulated MCU's telemetry frames, from its record.

    minirquad_sim --record out/tel.jsonl ...        # or behavior_demo --sim-arg=--record=...
    python tools/telemetry_gaps.py out/tel.jsonl

A real MCU sends a frame every 10 ms (100 Hz) whatever the ground does; a gap longer than a
few periods is the simulator's loop standing still. Prints the gap percentiles (ms, host
wall time between consecutive frames) once the host is linked (not in WATCHDOG mode) and while
the anchored robot is loaded (ANCHORED, tension above 0.3 N: the tug, a slip and the stop,
when the ground solver is asked about new poses), the number of gaps of 50 ms or more, and
how many frames carried the ANCHOR_SLIPPING flag.
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from minirquad_driver.protocol.messages import Flag, Mode
from rftgls_conventions.safe_read import read_text

PCTS = (50, 99, 100)


def gap_stats(v: np.ndarray) -> dict:
    """Frames, gap percentiles (ms) and gaps of 50 ms or more of host-time gaps v (s)."""
    if len(v) == 0:
        return {'frames': 0}
    return {'frames': int(len(v)),
            **{f'p{p}_ms': round(1e3 * float(np.percentile(v, p)), 1) for p in PCTS},
            'gaps_ge_50ms': int(np.sum(v >= 0.05))}


def gaps(path: str) -> dict:
    rows = [json.loads(x) for x in read_text(path, 'report', 'telemetry record').splitlines()
            if x.strip()]
    t = np.array([r['host_s'] for r in rows])
    gap = np.diff(t)
    first = rows[:-1]
    # The anchored robot under load (a tug, a slip, the stop after it): what the ground solver
    # is asked about; frames before the host connected (WATCHDOG mode) are left out of 'all'.
    linked = np.array([r['mode'] != int(Mode.WATCHDOG) for r in first])
    anchored = np.array([r['mode'] == int(Mode.ANCHORED) and r['tension'] > 300   # mN
                         for r in first])
    slip_t = t[np.array([bool(r['flags'] & int(Flag.ANCHOR_SLIPPING)) for r in rows])]

    return {'linked': gap_stats(gap[linked]), 'anchored_loaded': gap_stats(gap[anchored]),
            'slipping_frames': int(len(slip_t))}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog='telemetry_gaps', description=__doc__.split('\n\n')[0])
    p.add_argument('record', help="minirquad_sim --record file (JSON lines)")
    args = p.parse_args(argv)
    print(json.dumps(gaps(args.record), indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
