"""The live ground answered by a worker process, so the simulated MCU loop never waits for it.

A real MCU keeps its loop rate whatever the sand does. The live solver (``LiveGround``) takes
50-200 ms for an answer at a pose it has not seen (more on a loaded host), and while an anchor
slips every physics step reaches a new pose: asked inline, the MCU loop stood still for
0.1-0.6 s at a time (docs/design/tug-safety.md, "The simulated MCU keeps its period").
``BackgroundGround`` wraps a warmed-up ``LiveGround``:

- an answer already computed (its grid cell: 1 mm, 1 deg, 1 deg of pull angle) is returned;
- otherwise the cell is sent to a worker process that owns a copy of the ground (forked after
  the warm-up, so its compiled solver and caches come with it) and the caller gets, at once,
  the newest answer this pull got (the cell's own when it was solved, else the worker's latest
  solve): the ground runs behind the pose by one solve. One request is in flight and one
  waits; a newer cell replaces the waiting one, since a slipping anchor passes cells faster
  than they solve. A slipping anchor therefore meets the capacity it digs into one solve late:
  it slips further than with the solve inline, by at most what the winch reels in one solve;
- a stand-in is only for that slip, and only the caller knows one is under way: it passes
  ``stand_in=False`` when the rope starts to load an anchor (the previous step loaded none),
  and such a cell, like one asked before any answer for this pull, is solved inline. The loop
  waits for that one solve rather than let a new anchor hold with another's capacity: the
  newest answer is then whatever the rope loaded last (a pose the burrow stroke passed, the
  previous burrow), however near in time. In the demo launcher's one-cycle test (the
  scripted body) under CI load a settled burrow "slipped" 1.2-1.7 deg in pitch at 0.3-0.4 N
  (its own capacity: about 3 N) on the stand-in of a shallow pose its stroke passed, and the
  cycle stopped;
- ``prefetch`` asks for a cell with no answer back: the simulated robot sends its settled pose
  while the rope is slack, so the solve is done before a tug loads it and the inline solve
  stays a fallback.

A process, not a thread: the solver holds the GIL through its compiled calls (a thread left
gaps of up to 0.8 s in the loop); worker_process.py starts and stops it.
"""
from __future__ import annotations

import math
from collections import OrderedDict

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Pull

from . import worker_process
from .ground import LiveGround


def _serve(ground: LiveGround, conn) -> None:
    """Worker process: answer (cell, state, phi, pull) requests until the pipe closes."""
    while True:
        try:
            cell, state, phi, pull = conn.recv()
            conn.send((cell, ground.predict(state, phi, pull)))
        except (EOFError, OSError):
            return


class BackgroundGround:
    """A ``LiveGround`` whose new answers are solved in a worker process (module doc).
    ``stand_ins`` counts the answers given from an earlier cell while a solve ran,
    ``inline_solves`` the cells solved in this process (a new load, nothing to stand in)."""

    def __init__(self, ground: LiveGround, cache_size: int = 50_000):
        self.ground = ground
        self.method = getattr(ground, 'method', 'live')
        self.cache_size = cache_size
        self._answers: OrderedDict = OrderedDict()
        self._last: dict[str, CapacityResult] = {}
        self._in_flight: tuple | None = None
        self._waiting: tuple | None = None
        self.stand_ins = 0
        self.inline_solves = 0
        self._conn, self._worker = worker_process.start(_serve, ground, 'minirquad_sim ground')

    def describe(self) -> str:
        return self.ground.describe() + ', solved in a worker process'

    def close(self) -> None:
        """End the worker now (a solve in progress is not waited for)."""
        worker_process.stop(self._conn, self._worker)

    def _collect(self) -> None:
        """Take in the worker's answer if it is ready; send the waiting request."""
        while self._in_flight is not None and self._conn.poll():
            cell, answer = self._conn.recv()
            self._answers[cell] = answer
            # The newest solve is the nearest pose the ground knows (the anchor passed it at
            # most one solve ago): a slipping anchor meets the capacity it digs into with one
            # solve's delay, not never.
            self._last[cell[1]] = answer
            if len(self._answers) > self.cache_size:
                self._answers.popitem(last=False)
            self._in_flight = None
            if self._waiting is not None:
                self._send(self._waiting)
                self._waiting = None

    def _send(self, request: tuple) -> None:
        self._conn.send(request)
        self._in_flight = request

    def _request(self, request: tuple) -> None:
        """Solve `request` in the worker: now if it is free, else next (replacing a waiting
        request for another cell)."""
        if self._in_flight is None:
            self._send(request)
        elif self._in_flight[0] != request[0]:
            self._waiting = request

    def _known(self, cell: tuple, state: AnchorState, phi: float, pull: str
               ) -> CapacityResult | None:
        """The cell's answer if the worker (its answers taken in first) or this process
        solved it, else None."""
        self._collect()
        return self._answers.get(cell) or self.ground.cached(state, phi, pull)

    def prefetch(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD
                 ) -> None:
        """Have the worker solve this pose's cell if it is not solved yet; nothing waits,
        nothing is answered (the robot's settled pose, asked while the rope is slack)."""
        if not (state.is_finite() and math.isfinite(phi)):
            return
        pull = Pull(pull).value
        cell = self.ground.answer_key(state, phi, pull)
        if self._known(cell, state, phi, pull) is None:
            self._request((cell, state, phi, pull))

    def predict(self, state: AnchorState, phi: float, pull: Pull | str = Pull.BACKWARD,
                stand_in: bool = True) -> CapacityResult:
        """The cell's answer; while it is solved, the newest answer this pull got if
        stand_in (the same anchor, loaded since the previous step: a slip), else the cell
        solved here (module doc)."""
        if not (state.is_finite() and math.isfinite(phi)):
            return self.ground.predict(state, phi, pull)       # invalid_input, no solve
        pull = Pull(pull).value
        cell = self.ground.answer_key(state, phi, pull)
        hit = self._known(cell, state, phi, pull)
        if hit is None and (not stand_in or pull not in self._last):
            hit = self.ground.predict(state, phi, pull)
            self.inline_solves += 1
        if hit is not None:
            self._last[pull] = hit
            return hit
        self._request((cell, state, phi, pull))
        self.stand_ins += 1
        return self._last[pull]
