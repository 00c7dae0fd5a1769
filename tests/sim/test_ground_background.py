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
from minirquad_sim.gait_pose import GaitPoses
from minirquad_sim.ground import LiveGround
from minirquad_sim.ground_worker import BackgroundGround
from minirquad_sim.robot import SimRobot
from minirquad_sim.winch import WinchSled
from rftgls_core.types import AnchorState

SH = TABLE_II['SH']
SETTLED = AnchorState(SH.h, SH.theta_b, *SH.final)
# The anchor after a slip: 3 mm higher and pitched 3 deg (other cells of the 1 mm / 1 deg grid).
SLIPPED = AnchorState(SH.h + 0.003, SH.theta_b - math.radians(3.0), *SH.final)
# Another anchor with SH's final legs: DH's (Table II: 13 mm deeper, 2.6 deg more pitch).
DH = TABLE_II['DH']
DEEPER = AnchorState(DH.h, DH.theta_b, *DH.final)


@pytest.fixture(scope='module')
def inline():
    """The reference: the same ground solved in this process (its cache changes no answer)."""
    return LiveGround(medium_scale=0.5)


@pytest.fixture
def grounds(inline):
    """(inline, a fresh BackgroundGround). Fresh per test: a background ground answers a new
    pose with the last answer it gave, so a ground shared between tests made each depend on
    the poses the tests before it asked (pytest-xdist's worksteal may run them in any order)."""
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


def test_a_newly_loaded_anchor_gets_its_own_answer_not_a_stand_in(grounds):
    """A stand-in is for a slip (the same anchor, loaded step after step); the caller says
    when the rope starts to load an anchor, and that cell is solved here (the loop waits
    once) even when it is another burrow with the same legs."""
    inline, background = grounds
    background.predict(SETTLED, 0.0)
    stand_ins, solves = background.stand_ins, background.inline_solves
    answer = background.predict(DEEPER, 0.0, stand_in=False)
    assert answer == inline.predict(DEEPER, 0.0)
    assert answer.capacity_N != inline.predict(SETTLED, 0.0).capacity_N
    assert (background.stand_ins, background.inline_solves) == (stand_ins, solves + 1)


def test_a_prefetched_pose_is_solved_in_the_worker(grounds):
    inline, background = grounds
    pose = AnchorState(SH.h - 0.004, SH.theta_b + math.radians(2.0), *SH.final)
    background.prefetch(pose, 0.0)
    assert background.ground.cached(pose, 0.0) is None     # not solved in this process
    deadline = time.monotonic() + 60.0
    while background.ground.answer_key(pose, 0.0) not in background._answers \
            and time.monotonic() < deadline:
        time.sleep(0.02)
        background.prefetch(pose, 0.0)                     # collects the worker's answer
    stand_ins, solves = background.stand_ins, background.inline_solves
    assert background.predict(pose, 0.0) == inline.predict(pose, 0.0)
    assert (background.stand_ins, background.inline_solves) == (stand_ins, solves)


def test_a_settled_burrow_is_loaded_with_its_own_capacity():
    """The demo launcher test's scripted body under CI load: the rope, taken up just taut at
    standing, loaded the poses a streamed burrow stroke passed (legs near -35/-17 deg at
    standing height hold about 0.4 N), then went slack as the body settled; the tug then
    loaded the settled anchor on the stand-in of such a pose, and the anchor "slipped"
    1.2-1.7 deg at 0.3-0.4 N where its own capacity is about 3 N. The stroke and the tug run
    in real time (the worker's solves come in during them). The 400 g sled slides at 1.96 N,
    which the settled anchor holds."""
    poses = GaitPoses.for_sled(0.4)
    assert poses is not None
    ground = BackgroundGround(LiveGround())
    try:
        # 5 cm of slack to take up (the default rope is taut at the start)
        robot = SimRobot(ground=ground, winch=WinchSled(sled_mass=0.4, rope_length=0.55),
                         gait_poses=poses)
        dt = 0.01
        robot.set_winch(0.02)                              # the take-up, at standing
        while robot.winch.tension < 0.3:
            robot.step(dt)
            assert robot.time < 10.0 and not robot.slipping
        robot.set_winch(0.0)
        final = (math.radians(-40.0), math.radians(-20.0))
        loaded = 0
        for i in range(1, 51):                             # the stroke, streamed at 50 Hz
            legs = (final[0] * i / 50, final[1] * i / 50)
            robot.set_legs((legs[0], legs[0], legs[1], legs[1]))
            for _ in range(2):
                robot.step(dt)
                loaded += robot.winch.tension > 0.0
                time.sleep(dt)
        for _ in range(100):
            robot.step(dt)
        pitch = robot.theta_b
        assert pitch == pytest.approx(poses.pose(final, final)[1])   # settled as the map says
        assert loaded and robot.winch.tension == 0.0       # the stroke loaded, then slack
        robot.set_winch(0.05)                              # the tug: 1.5 s, at least as slow
        for _ in range(150):
            robot.step(dt)
            assert not robot.slipping, (robot.time, robot.winch.tension)
            time.sleep(dt)
        assert robot.winch.sled_moving and robot.winch.tension == pytest.approx(0.5 * 0.4 * 9.81)
        assert robot.theta_b == pitch
    finally:
        ground.close()


def test_an_invalid_state_is_refused_without_a_solve(grounds):
    _, background = grounds
    bad = AnchorState(math.nan, SH.theta_b, *SH.final)
    assert background.predict(bad, 0.0).status.value == 'invalid_input'
