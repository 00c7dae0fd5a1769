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
from concurrent.futures import Future, ProcessPoolExecutor

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
    """Replays in one worker process; a new submit supersedes a replay still running."""

    def __init__(self, inputs: PlanInputs):
        super().__init__(inputs)
        ctx = multiprocessing.get_context('forkserver')
        self._pool = ProcessPoolExecutor(max_workers=1, mp_context=ctx)
        self._future: Future | None = None
        self._pool.submit(_warm)

    def submit(self, record: BurrowRecord, plan_pose: BurrowedPose) -> None:
        self.submitted += 1
        self.cancel()
        self._future = self._pool.submit(replay_burrow, self.inputs, record, plan_pose)

    def result(self) -> ReplayedBurrow | None:
        f = self._future
        if f is None or not f.done():
            return None
        self._future = None
        try:
            return f.result()
        except Exception as exc:      # a crashed worker is a replay without a pose, not a crash
            return ReplayedBurrow(None, float('nan'), f'replay_failed: {exc!r}', 0)

    def cancel(self) -> None:
        if self._future is not None:
            self._future.cancel()
            self._future = None

    def close(self) -> None:
        # Joined, not abandoned: an abandoned pool leaves its worker and semaphores to the
        # interpreter's exit (resource_tracker warnings). A replay still running is waited for.
        self.cancel()
        self._pool.shutdown(wait=True, cancel_futures=True)
