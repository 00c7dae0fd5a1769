"""The simulated MCU loop's period while its anchor slips, without a host stack.

    python tools/sim_loop_gaps.py --ground-solver inline   # the loop waits for each solve
    python tools/sim_loop_gaps.py --ground-solver worker   # solves in a worker process

Runs minirquad_sim's MCU (SimMcu on the live ground, true sand x0.5, 800 g sled) in a real-time
loop paced as minirquad_sim's main loop is: burrow DH, then reel in at 50 mm/s for
``--reel-s`` without ever stopping (the worst case: the slip goes on, each step reaching new
poses). Prints the gaps between telemetry frames (host wall time) while reeling, how many
frames carried ANCHOR_SLIPPING, how far the anchor's pitch moved, and how many answers the
ground gave from a neighbouring pose while a fit ran.
"""
from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
from telemetry_gaps import gap_stats  # tools/, beside this script

from minirquad_driver.protocol import messages as m
from minirquad_driver.protocol.codec import encode_frame
from minirquad_sim.ground import LiveGround
from minirquad_sim.ground_worker import BackgroundGround
from minirquad_sim.mcu import SimMcu
from minirquad_sim.robot import SimRobot
from minirquad_sim.winch import WinchSled


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog='sim_loop_gaps', description=__doc__.split('\n\n')[0])
    p.add_argument('--ground-solver', choices=('inline', 'worker'), default='worker')
    p.add_argument('--reel-s', type=float, default=6.0, help='s of reeling in')
    p.add_argument('--medium-scale', type=float, default=0.5)
    p.add_argument('--sled-mass', type=float, default=0.8, help='kg')
    args = p.parse_args(argv)
    live = LiveGround(medium_scale=args.medium_scale)
    live.warm_up()
    ground = live if args.ground_solver == 'inline' else BackgroundGround(live)
    start = time.monotonic()
    tel: list[tuple[float, m.Telemetry]] = []
    mcu = SimMcu(robot_factory=lambda: SimRobot(ground=ground,
                                                winch=WinchSled(sled_mass=args.sled_mass)),
                 now=start, on_telemetry=lambda s, t, x: tel.append((time.monotonic(), x)))
    seq = 0

    def send(msg, now: float) -> None:
        nonlocal seq
        seq += 1
        mcu.receive(encode_frame(msg, seq, 0), now)

    send(m.Burrow(int(m.BurrowMode.DH)), start)
    reel_from = reel_to = None
    last_hb = last_winch = start
    while True:
        now = time.monotonic()
        if now - last_hb > 0.1:
            send(m.Heartbeat(), now)
            last_hb = now
        anchored = tel and tel[-1][1].mode == m.Mode.ANCHORED
        if reel_from is None and anchored:
            reel_from, reel_to = now, now + args.reel_s
        if reel_from is not None and now - last_winch >= 0.02:
            send(m.Winch(0.05 if now < reel_to else 0.0), now)
            last_winch = now
        mcu.tick(now)
        if reel_to is not None and now > reel_to:
            break
        if now - start > 60.0:
            print('sim_loop_gaps: the burrow did not finish in 60 s', file=sys.stderr)
            return 1
        time.sleep(max(0.0, min(mcu.next_due() - time.monotonic(), 0.05)))
    reeling = [(t, x) for t, x in tel if t >= reel_from]
    gaps = np.diff([t for t, _ in reeling])
    slips = [x for _, x in reeling if x.flags & m.Flag.ANCHOR_SLIPPING]
    pitch = [x.pitch for _, x in reeling]
    print(json.dumps({
        'ground_solver': args.ground_solver, **gap_stats(gaps), 'slipping_frames': len(slips),
        'pitch_change_deg': round(float(np.degrees(max(pitch) - min(pitch))), 2),
        'stand_in_answers': getattr(ground, 'stand_ins', 0)}, indent=1))
    return 0


if __name__ == '__main__':
    sys.exit(main())
