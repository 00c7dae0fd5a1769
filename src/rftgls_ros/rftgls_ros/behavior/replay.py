"""The burrowed pose from the burrow as it went (rftgls_core.planning.replay), for
behavior_node: the leg angles measured during a planned burrow are replayed through the burrow
simulation, and the pose it ends in replaces the plan's prediction as the height sent to
capacity_node (modelled, with the plan's band).

One replay takes about 1-3 s of CPU. `ProcessReplayer` runs it in a worker process started
from a clean interpreter (forkserver: nothing of the node's DDS threads is inherited), so the
node's step and callbacks go on and its inputs stay fresh; `InlineReplayer` runs it at once,
for the closed-loop tests without ROS. Both answer `result()`: None while nothing is ready.
"""
from __future__ import annotations

import multiprocessing
import multiprocessing.pool
from multiprocessing.pool import AsyncResult

from rftgls_core.planning.burrowed import BurrowedPose
from rftgls_core.planning.predict import PlanInputs
from rftgls_core.planning.replay import BurrowRecord, ReplayedBurrow, replay_burrow


def _warm() -> bool:
    """Imports the simulation in the worker (and its compiled kernels), before the first
    burrow needs them."""
    from rftgls_core.planning import replay  # noqa: F401
    return True


class InlineReplayer:
    """Replays at submit, in this process (tests)."""

    def __init__(self, inputs: PlanInputs):
        self.inputs = inputs
        self._result: ReplayedBurrow | None = None
        self.submitted = 0

    def submit(self, record: BurrowRecord, plan_pose: BurrowedPose) -> None:
        self.submitted += 1
        self._result = replay_burrow(self.inputs, record, plan_pose)

    def result(self) -> ReplayedBurrow | None:
        """The last replay's answer, once; None while none is ready."""
        out, self._result = self._result, None
        return out

    def cancel(self) -> None:
        self._result = None

    def close(self) -> None:
        pass


class ProcessReplayer(InlineReplayer):
    """Replays in one worker process. A replay that is no longer wanted (a new submit, a
    cancel, the node's stop) is not waited for: its worker is terminated (multiprocessing's
    Pool.terminate) and, unless closing, a fresh one started. A stop then takes no replay's
    1-3 s, and a superseded replay stops taking one of the robot computer's cores."""

    def __init__(self, inputs: PlanInputs):
        super().__init__(inputs)
        self._pool = self._start()
        self._running: AsyncResult | None = None

    @staticmethod
    def _start() -> multiprocessing.pool.Pool:
        pool = multiprocessing.get_context('forkserver').Pool(processes=1)
        pool.apply_async(_warm)
        return pool

    def submit(self, record: BurrowRecord, plan_pose: BurrowedPose) -> None:
        self.submitted += 1
        self.cancel()
        self._running = self._pool.apply_async(replay_burrow,
                                               (self.inputs, record, plan_pose))

    def result(self) -> ReplayedBurrow | None:
        f = self._running
        if f is None or not f.ready():
            return None
        self._running = None
        try:
            return f.get()
        except Exception as exc:      # a crashed worker is a replay without a pose, not a crash
            return ReplayedBurrow(None, float('nan'), f'replay_failed: {exc!r}', 0)

    def cancel(self) -> None:
        if self._running is not None and not self._running.ready():
            self._stop()
            self._pool = self._start()
        self._running = None

    def close(self) -> None:
        self._running = None
        self._stop()

    def _stop(self) -> None:
        # Terminated and joined (not abandoned to the interpreter's exit, which would leave
        # the worker and its semaphores behind: resource_tracker warnings).
        self._pool.terminate()
        self._pool.join()
