"""The physics body stepped in a worker process, so the simulated MCU loop never waits for it.

A real robot's body moves with the wall clock whatever it costs to compute. The whole-robot
physics (physics.PhysicsBody) mostly runs ten times faster than real time, but some steps
need many short substeps (seen in the demo's re-burrows, tied to the sled): single physics
steps of 20 ms took 0.5-3.8 s in the simulator's loop, the MCU sent no telemetry
meanwhile, and the host saw the link go stale again and again
(docs/design/walk-burrow-physics.md, "The simulator"). ``BackgroundPhysics`` keeps the same
interface as PhysicsBody:

- ``advance`` gathers loop time as before; each physics step that falls due is queued for
  the worker with the leg references of its own time, and the call returns at once. The
  worker runs the steps in order, each exactly as the body itself would: the physics gets
  the same inputs, only later. While it runs slowly the body falls behind the wall clock
  (``behind_s``) and catches up when the steps get cheap again. (Gathering the waiting time
  into one long step instead lost the physics: a 0.9 s step toward leg references that had
  run far ahead found no balance.) A physics slower than real time for good (``--body
  physics``' walk: 6 s of computing per 1.6 s) falls further behind without end; the
  simulator says so on stderr at each further second.
- ``pose``, ``q``, ``rates``, ``elec_W``, ``failed`` are the newest step's answer: sensors
  on a body that has moved that far.
- ``place`` (the hand-over from the scripted walk, 0.1-0.25 s) waits for the steps before it
  and for itself: the robot cannot stand on the physics before it is down.

The worker is forked after the body is built (worker_process.py), so the body and its
compiled kernels come with it.
"""
from __future__ import annotations

from collections import deque

import numpy as np

from . import worker_process
from .physics import PhysicsBody


def _answer(body: PhysicsBody) -> tuple:
    return (body.pose, np.array(body.q, dtype=float), np.array(body.rates, dtype=float),
            body.elec_W, body.failed, body.sim.t)


def _serve(body: PhysicsBody, conn) -> None:
    """Worker process: run ('step', ...) and ('place', ...) requests until the pipe closes."""
    while True:
        try:
            kind, *args = conn.recv()
        except (EOFError, OSError):
            return
        if kind == 'place':
            body.place(*args)
        else:
            body.run_step(*args)
        try:
            conn.send(_answer(body))
        except (EOFError, OSError):
            return


class BackgroundPhysics:
    """A PhysicsBody whose steps run in a worker process (module doc). ``behind_s``: the
    most simulated time that was waiting for the worker at once, s."""

    # steps sent to the worker before its answers: the rest wait here, so a worker far
    # behind never fills the pipe (a full pipe would block the loop on send)
    IN_FLIGHT = 16

    def __init__(self, body: PhysicsBody):
        self.robot, self.step, self.medium = body.robot, body.step, body.medium
        self._describe = body.describe()
        (self._pose, self._q, self._rates, self.elec_W, self.failed,
         self.t) = _answer(body)
        self.behind_s = 0.0
        self._pending = 0.0
        self._queue: deque[tuple] = deque()
        self._in_flight: deque[float] = deque()     # the runs sent, s
        self._fresh = False
        self._conn, self._proc = worker_process.start(_serve, body, 'minirquad_sim physics')

    def describe(self) -> str:
        return self._describe + ' (stepped in a worker process)'

    def place(self, q, x_p: float = 0.0) -> None:
        """PhysicsBody.place after every step before it, waiting for it (module doc)."""
        self.wait()
        self._pending = 0.0
        self._conn.send(('place', np.asarray(q, dtype=float), float(x_p)))
        self._take(self._conn.recv())

    def advance(self, dt: float, q_ref, ff, target, tension: float, phi: float,
                phase: str) -> bool:
        """Gather dt; queue a step when `step` has gathered. True when a step's answer
        arrived since the last call."""
        self._pending += dt
        if self._pending >= self.step and not self.failed:
            run, self._pending = self._pending, 0.0
            self._queue.append(('step', run, np.asarray(q_ref, dtype=float),
                                np.asarray(ff, dtype=float), np.asarray(target, dtype=float),
                                float(tension), float(phi), str(phase)))
        self._pump(block=False)
        fresh, self._fresh = self._fresh, False
        return fresh

    def wait(self) -> None:
        """Block until every step queued has answered."""
        while self._queue or self._in_flight:
            self._pump(block=True)

    @property
    def behind_now_s(self) -> float:
        """Simulated time queued or running in the worker, s."""
        return sum(r[1] for r in self._queue) + sum(self._in_flight)

    @property
    def pid(self) -> int | None:
        """The worker's process id."""
        return self._proc.pid

    def close(self) -> None:
        """End the worker now (a step in progress is not waited for)."""
        worker_process.stop(self._conn, self._proc)

    def _pump(self, block: bool) -> None:
        """Send what may go, take what has come (one answer at least when `block`)."""
        while self._queue and len(self._in_flight) < self.IN_FLIGHT:
            request = self._queue.popleft()
            self._conn.send(request)
            self._in_flight.append(request[1])
        self.behind_s = max(self.behind_s, self.behind_now_s)
        while self._in_flight and (block or self._conn.poll()):
            self._take(self._conn.recv())
            self._in_flight.popleft()
            block = False
        if self.failed:
            self._queue.clear()       # a body that cannot go on takes no more steps

    def _take(self, answer: tuple) -> None:
        self._pose, self._q, self._rates, self.elec_W, self.failed, self.t = answer
        self._fresh = True

    @property
    def pose(self) -> tuple[float, float, float]:
        """(x, z) of the tether point p (m) and the pitch theta_b (rad), as of the newest
        step answered."""
        return self._pose

    @property
    def q(self) -> np.ndarray:
        return self._q

    @property
    def rates(self) -> np.ndarray:
        return self._rates
