"""The physics body in a worker process (minirquad_sim/physics_worker.py): the same physics,
answered one step later, and a loop that never waits for a slow step."""
from __future__ import annotations

import os
import signal

import numpy as np
import pytest

from minirquad_sim.physics import PhysicsBody
from minirquad_sim.physics_worker import BackgroundPhysics

STEP = 0.002    # s, the simulator loop's step
STAND = np.zeros(4)
# legs to the g-40/-20 pose at the burrow slew (1 rad/s), in the body's leg order
# (left proximal, left distal, right proximal, right distal)
TARGET = np.radians([-40.0, -20.0, -40.0, -20.0])
RATE = np.sign(TARGET) * 1.0


def _refs(t: float):
    q = np.where(np.abs(RATE * t) < np.abs(TARGET), RATE * t, TARGET)
    ff = np.where(q == TARGET, 0.0, RATE)
    return q, ff


def test_the_worker_steps_the_same_physics_as_the_body_itself():
    """Answered step by step (the caller waits for each), the worker's body reaches the same
    poses, legs and power as the body stepped in this process, to the last bit: the same
    code on the same inputs."""
    inline = PhysicsBody()
    inline.place(STAND, 0.0)
    worker = BackgroundPhysics(_placed())
    try:
        t = 0.0
        for _ in range(round(0.6 / STEP)):
            q, ff = _refs(t)
            ran = inline.advance(STEP, q, ff, TARGET, 0.5, 0.0, 'burrow')
            worker.advance(STEP, q, ff, TARGET, 0.5, 0.0, 'burrow')
            worker.wait()
            if ran:
                assert worker.pose == inline.pose
                np.testing.assert_array_equal(worker.q, inline.q)
                np.testing.assert_array_equal(worker.rates, inline.rates)
                assert worker.elec_W == inline.elec_W and worker.t == inline.sim.t
            t += STEP
        assert not inline.failed and not worker.failed
        # never more than the one step in flight was waiting
        assert worker.t > 0.5 and worker.behind_s <= worker.step + 1e-12
    finally:
        worker.close()


def _placed() -> PhysicsBody:
    body = PhysicsBody()
    body.place(STAND, 0.0)
    return body


def test_the_loop_does_not_wait_and_the_body_catches_up_step_by_step():
    """With the worker stopped (SIGSTOP: a step that takes seconds), every advance still
    returns, with no answer; the due steps wait in order. Let go, the worker answers every
    one, each as the body itself would have: the same physics, to the last bit."""
    worker = BackgroundPhysics(_placed())
    inline = _placed()
    try:
        t0 = worker.t
        os.kill(worker.pid, signal.SIGSTOP)
        try:
            given, answers, calls = 0.0, 0, []
            for _ in range(round(0.8 / STEP)):
                q, ff = _refs(given)
                answers += worker.advance(STEP, q, ff, TARGET, 0.5, 0.0, 'burrow')
                calls.append((q, ff))
                given += STEP
        finally:
            os.kill(worker.pid, signal.SIGCONT)
        assert answers == 0 and worker.t == t0
        # all 40 due steps waited (less than one step may still be gathering)
        assert worker.behind_s == pytest.approx(worker.behind_now_s)
        assert given - worker.step < worker.behind_s <= given + 1e-9
        worker.wait()
        assert not worker.failed and worker.behind_now_s == 0.0
        ran = sum(inline.advance(STEP, q, ff, TARGET, 0.5, 0.0, 'burrow') for q, ff in calls)
        assert ran == round(0.8 / worker.step)
        assert worker.t == inline.sim.t and worker.t - t0 > given - worker.step
        assert worker.pose == inline.pose
        np.testing.assert_array_equal(worker.q, inline.q)
    finally:
        worker.close()


def test_close_ends_the_worker():
    worker = BackgroundPhysics(_placed())
    pid = worker.pid
    assert pid is not None
    os.kill(pid, 0)                    # alive
    worker.close()
    with pytest.raises(ProcessLookupError):
        os.kill(pid, 0)                # gone (and reaped: close joins it)


def test_the_simulator_says_when_the_physics_falls_behind(capsys):
    """Once past a second behind the wall clock, again at each further second, and afresh
    after catching up (minirquad_sim.main.report_lag)."""
    from minirquad_sim.main import BEHIND_REPORT_S, report_lag
    said, lines = 0.0, []
    for t, lag in enumerate((0.2, 0.9, 1.2, 1.5, 2.3, 2.0, 0.0, 0.4, 1.1)):
        said = report_lag(lag, said, float(t))
        lines += [x for x in capsys.readouterr().err.splitlines() if x]
    assert BEHIND_REPORT_S == 1.0
    assert lines == ['minirquad_sim: the physics runs 1.2 s behind the wall clock at t 2.00 s',
                     'minirquad_sim: the physics runs 2.3 s behind the wall clock at t 4.00 s',
                     'minirquad_sim: the physics runs 1.1 s behind the wall clock at t 8.00 s']
