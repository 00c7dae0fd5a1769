"""The live ground's background fit: the simulated MCU loop never waits for a fit.

A real MCU keeps its loop rate whatever the ground does; the simulator's live ground fits each
new anchor pose with rftgls_core's solver (tens of ms each), so with ``background=True`` a pose
not fitted yet is answered from the nearest fitted pose while its own fit runs in another
thread (docs/design/tug-safety.md, "The simulated MCU keeps its period").
"""
from __future__ import annotations

import math
import threading
import time

import pytest

from minirquad_sim.burrow import TABLE_II
from minirquad_sim.ground import LiveGround
from rftgls_core.types import AnchorState

SH = TABLE_II['SH']
SETTLED = AnchorState(SH.h, SH.theta_b, *SH.final)
# The anchor after a slip: 3 mm higher and 3 deg pitched (three grid steps away in h and pitch).
SLIPPED = AnchorState(SH.h + 0.003, SH.theta_b - math.radians(3.0), *SH.final)


def _fit_threads(ground: LiveGround) -> list[str]:
    """Record the thread of every fit the ground's predictors make."""
    seen: list[str] = []
    for p in ground.predictors:
        fit = p.fit

        def recording(*a, _fit=fit, **k):
            seen.append(threading.current_thread().name)
            return _fit(*a, **k)
        p.fit = recording
    return seen


@pytest.fixture(scope='module')
def grounds():
    inline = LiveGround(medium_scale=0.5)
    background = LiveGround(medium_scale=0.5, background=True)
    for g in (inline, background):
        g._fit(g._key(SETTLED), 'backward')
    return inline, background


def test_a_new_pose_is_answered_from_its_neighbour_while_it_fits_elsewhere(grounds):
    inline, background = grounds
    threads = _fit_threads(background)
    first = background.predict(SLIPPED, 0.0)
    # Answered at once, from the settled pose (the only one fitted), not from a fit in this
    # thread: what the MCU loop gets while the fitter works.
    assert threading.current_thread().name not in threads
    assert first.capacity_N == pytest.approx(inline.predict(SETTLED, 0.0).capacity_N)
    assert background.stand_ins >= 1
    deadline = time.monotonic() + 30.0
    while background._key(SLIPPED) not in {k for k, _ in background._fits} \
            and time.monotonic() < deadline:
        time.sleep(0.01)
    assert threads and set(threads) == {'ground-fitter'}, threads
    # Once fitted, the pose's own answer: the same number the inline ground computes.
    own = background.predict(SLIPPED, 0.0)
    ref = inline.predict(SLIPPED, 0.0)
    assert own.status == ref.status and own.capacity_N == ref.capacity_N
    assert own.capacity_N != first.capacity_N      # the stand-in was a different pose's


def test_the_inline_ground_fits_in_the_callers_thread(grounds):
    inline, _ = grounds
    threads = _fit_threads(inline)
    inline.predict(AnchorState(SH.h + 0.001, SH.theta_b, *SH.final), 0.0)
    assert threads and set(threads) == {threading.current_thread().name}
    assert inline.stand_ins == 0
