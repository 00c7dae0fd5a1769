"""The walk-burrow-tug action of behavior_node: ``~/walk_burrow_tug``
(rftgls_interfaces/WalkBurrowTug; goal: sled mass and cycles; feedback: state, margin, lower
bound; result: every cycle's outcome).

The rclpy side of the action, next to the ROS-free behaviour (``behavior/``). The server talks
to the node through a small surface (``RunHost``): start a run, stop it now, the run's
machine, capacity_node's last estimate. One goal at a time: a goal is rejected while
a run is going (the parameters' run of ``autostart`` included).

Cancel stops the winch in the cancel request's own callback: the machine is cancelled and
stepped at once, so WINCH 0 is published before the request is answered, not at the next
step. The goal then ends CANCELED with the cycles so far (the interrupted one ``CANCELLED``).

The goal's execute callback is a coroutine: it starts the run and awaits a future that the
feedback timer completes when the run is over, so the goal is EXECUTING for the whole run and
the single-threaded node keeps stepping. (A pending coroutine costs the executor one extra
turn per wake-up, not a busy loop: docs/design/jazzy-robot.md, "The walk-burrow-tug action".)
"""
from __future__ import annotations

import math
from typing import Protocol

from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.action.server import ServerGoalHandle
from rclpy.task import Future

from rftgls_interfaces.action import WalkBurrowTug
from rftgls_interfaces.msg import CycleOutcome

from .behavior import BehaviorMachine, State
from .behavior.report import CycleRecord
from .behavior.tug_series import TugSample

# The cycle report's outcome words (machine.py) -> CycleOutcome's constants.
OUTCOMES = {'ok': CycleOutcome.OK, 'refused': CycleOutcome.REFUSED,
            'stopped': CycleOutcome.STOPPED, 'aborted': CycleOutcome.ABORTED,
            'cancelled': CycleOutcome.CANCELLED}
FEEDBACK_PERIOD_S = 0.1   # s: feedback at 10 Hz (the machine steps at 50 Hz)


class RunHost(Protocol):
    """What the action needs of behavior_node."""

    machine: BehaviorMachine

    @property
    def running(self) -> bool:
        """A run is going (not finished, not idle)."""

    def start_run(self, sled_mass_kg: float, cycles: int) -> None:
        """Start a new run; ValueError (one line) on values it cannot run with."""

    def stop_run(self, why: str) -> None:
        """Stop the run now: the winch stop is published before this returns."""

    def latest_estimate(self) -> TugSample | None:
        """capacity_node's last estimate as received (None before the first)."""


def cycle_outcome(r: CycleRecord) -> CycleOutcome:
    """One cycle report row as the action's CycleOutcome (0: an outcome word not known)."""
    return CycleOutcome(cycle=int(r.cycle), outcome=OUTCOMES.get(r.outcome, 0), mode=r.mode,
                        reason=r.reason, sled_distance_m=float(r.sled_distance_m),
                        energy_j=float(r.energy_j), need_n=float(r.need_n),
                        tension_median_n=float(r.tension_median_n),
                        min_margin_n=float(r.min_margin_n))


def run_succeeded(machine: BehaviorMachine) -> bool:
    """The run did what the goal asked: `cycles` cycles ran their course and the sled arrived
    in each (aborted attempts that were retried do not count against it)."""
    counted = [r for r in machine.records if r.outcome != 'aborted']
    return (machine.state == State.FINISHED and len(counted) >= machine.cfg.cycles
            and all(r.outcome == 'ok' for r in counted))


def feedback(machine: BehaviorMachine, estimate: TugSample | None) -> WalkBurrowTug.Feedback:
    """The run's state and the tug's margin by capacity_node's last estimate."""
    nan = math.nan
    fb = WalkBurrowTug.Feedback(state=str(machine.state),
                                cycle=machine.cycle.index if machine.cycle else 0,
                                tension_n=nan, capacity_n=nan, capacity_lower_n=nan,
                                margin_n=nan, capacity_status='')
    if estimate is not None:
        fb.tension_n, fb.capacity_n = estimate.tension_n, estimate.capacity_n
        fb.capacity_lower_n = estimate.capacity_lower_n
        fb.margin_n = estimate.capacity_n - estimate.tension_n
        fb.capacity_status = estimate.status
    return fb


class TugActionServer:
    """``~/walk_burrow_tug`` on `node` for `host` (behavior_node is both)."""

    def __init__(self, node, host: RunHost):
        self._node, self._host = node, host
        self._goal: ServerGoalHandle | None = None
        self._run_over: Future | None = None
        self._server = ActionServer(node, WalkBurrowTug, '~/walk_burrow_tug',
                                    execute_callback=self._execute,
                                    goal_callback=self._on_goal,
                                    cancel_callback=self._on_cancel)
        node.create_timer(FEEDBACK_PERIOD_S, self.update)

    def _on_goal(self, request: WalkBurrowTug.Goal) -> GoalResponse:
        if self._goal is not None or self._host.running:
            self._node.get_logger().warning(
                f'walk_burrow_tug goal ({request.sled_mass_kg:g} kg, {request.cycles} cycles) '
                f'rejected: a run is going (state {self._host.machine.state})')
            return GoalResponse.REJECT
        return GoalResponse.ACCEPT

    async def _execute(self, goal: ServerGoalHandle) -> WalkBurrowTug.Result:
        req = goal.request
        if goal.is_cancel_requested or self._goal is not None or self._host.running:
            why = ('cancelled before it started' if goal.is_cancel_requested
                   else 'another run is going')
            if goal.is_cancel_requested:
                goal.canceled()
            else:
                goal.abort()
            return WalkBurrowTug.Result(final_state='', reason=why)
        try:
            self._host.start_run(req.sled_mass_kg, req.cycles)
        except ValueError as exc:
            self._node.get_logger().error(f'walk_burrow_tug goal refused: {exc}')
            goal.abort()
            return WalkBurrowTug.Result(final_state='', reason=f'goal refused: {exc}')
        self._node.get_logger().info(f'walk_burrow_tug: {1e3 * req.sled_mass_kg:.0f} g sled, '
                                     f'{req.cycles} cycles')
        self._goal, self._run_over = goal, Future()
        self._publish_feedback()
        await self._run_over
        self._goal = self._run_over = None
        m = self._host.machine
        if goal.is_cancel_requested:
            goal.canceled()
        elif run_succeeded(m):
            goal.succeed()
        else:
            goal.abort()
        return WalkBurrowTug.Result(cycles=[cycle_outcome(r) for r in m.records],
                                    final_state=str(m.state), reason=m.reason)

    def _on_cancel(self, goal: ServerGoalHandle) -> CancelResponse:
        if goal == self._goal:
            self._host.stop_run('walk_burrow_tug cancelled by its client')
        # A goal not started yet ends in its execute callback without running.
        return CancelResponse.ACCEPT

    def update(self) -> None:
        """Feedback, and the end of the goal once its run is over (timer, FEEDBACK_PERIOD_S)."""
        if self._goal is None or self._run_over is None:
            return
        self._publish_feedback()
        if self._host.machine.done and not self._run_over.done():
            self._run_over.set_result(True)

    def _publish_feedback(self) -> None:
        if self._goal is not None:
            self._goal.publish_feedback(feedback(self._host.machine,
                                                 self._host.latest_estimate()))

    def destroy(self) -> None:
        self._server.destroy()
