"""The live ground solved in a worker process: the simulated MCU loop never waits for it.

A real MCU keeps its loop rate whatever the ground does; the simulator's live ground solves
each new anchor pose with rftgls_core's solver (50-200 ms each), so ``BackgroundGround``
answers a pose not solved yet with the last answer at once and solves it in a worker process
(docs/design/tug-safety.md, "The simulated MCU keeps its period").
"""
from __future__ import annotations

import math
import time

import pytest

from minirquad_sim.burrow import TABLE_II
from minirquad_sim.ground import LiveGround
from minirquad_sim.ground_worker import BackgroundGround
from rftgls_core.types import AnchorState

SH = TABLE_II['SH']
SETTLED = AnchorState(SH.h, SH.theta_b, *SH.final)
# The anchor after a slip: 3 mm higher and pitched 3 deg (other cells of the 1 mm / 1 deg grid).
SLIPPED = AnchorState(SH.h + 0.003, SH.theta_b - math.radians(3.0), *SH.final)


@pytest.fixture(scope='module')
def grounds():
    inline = LiveGround(medium_scale=0.5)
    background = BackgroundGround(LiveGround(medium_scale=0.5))
    yield inline, background
    background.close()
    assert not background._worker.is_alive()


def test_a_new_pose_is_answered_at_once_and_solved_in_the_worker(grounds):
    inline, background = grounds
    settled = background.predict(SETTLED, 0.0)          # nothing to stand in: solved here
    assert settled == inline.predict(SETTLED, 0.0)
    first = background.predict(SLIPPED, 0.0)
    # At once the last answer (the settled pose's), and this process did not solve the new
    # pose: what the MCU loop gets while the worker solves.
    assert first == settled and background.stand_ins == 1
    assert background.ground.cached(SLIPPED, 0.0) is None
    deadline = time.monotonic() + 60.0
    answer = first
    while answer == first and time.monotonic() < deadline:
        time.sleep(0.02)
        answer = background.predict(SLIPPED, 0.0)
    # The worker's answer is the pose's own: the same result the inline ground computes.
    assert answer == inline.predict(SLIPPED, 0.0)
    assert answer.capacity_N != settled.capacity_N
    assert background.ground.cached(SLIPPED, 0.0) is None


def test_an_invalid_state_is_refused_without_a_solve(grounds):
    _, background = grounds
    bad = AnchorState(math.nan, SH.theta_b, *SH.final)
    assert background.predict(bad, 0.0).status.value == 'invalid_input'
