"""capacity_node's ``~/query_capacity`` service (rftgls_interfaces/QueryCapacity), both ends:
behavior_node's "what if I burrow to this pose" question and capacity_node's answer.

``answer_query`` fills the response from capacity_node's own predictor, so the answer gives the
numbers of `rftgls capacity --method map` for the same map, and the behaviour decides on the same
map or model as the estimates it tugs on (it loads no copy of its own). With the capacity it
sends capacity_node's own lower bound at that state, h known only within a band: the bound
the node publishes for a live state, so a mode is chosen and checked on the number its tug
will be gated on (docs/design/capacity-inputs.md, "One bound").

``ServicePredictor`` is the ModeChooser's predictor ``(state, phi) -> (capacity N | None,
Status)`` answered by that service, and its ``bound`` the lower bound. The call blocks the
caller for at most ``timeout_s``: the client lives on a private node spun by a private
executor, so it can be called from a callback of the behaviour node's own executor. It waits
in slices of ``WAIT_SLICE_S`` and gives up within one slice once ``stopping()`` is true
(node_main.stop_requested: a SIGINT): a mode choice asks several questions in one callback,
and the node's stop cannot begin before that callback returns.

Safety: an unanswered question is no value. A missing service, a timeout or a malformed answer
gives ``(None, Status.STALE)``, which the chooser never counts as sufficient (no tug on it);
after a failure the service is not asked again for ``retry_s``, so a dead capacity_node
cannot stall the behaviour's 50 Hz step once per question.
"""
from __future__ import annotations

import math
import time
from collections.abc import Callable

import rclpy
from rclpy.executors import SingleThreadedExecutor

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Pull, Status
from rftgls_interfaces.srv import QueryCapacity

from .capacity_msgs import num_or_nan, twist_msg

CAPACITY_SOURCES = ('service', 'local_map')
# s: how often a waiting question looks at stopping(); a stop ends the wait within this.
WAIT_SLICE_S = 0.05


#: (state, phi, pull, h_band m, prediction at the state or None) -> lower bound N or None
Bound = Callable[[AnchorState, float, str, float, CapacityResult | None], float | None]


def answer_query(predictor, default_pull: str, req, res, bound: Bound | None = None):
    """Fill a QueryCapacity response from predictor.predict and, when given, ``bound``
    (capacity_node: lower_bound.AskedBound.bound); invalid_input on a bad request."""
    res.capacity_n = res.capacity_lower_n = num_or_nan(None)
    res.slip_twist = res.slip_twist_scaled = twist_msg(None)
    res.method = predictor.name
    values = (req.h_m, req.theta_b_rad, req.theta_l1_rad, req.theta_l2_rad, req.phi_rad)
    pull = req.pull.strip() or default_pull
    try:
        Pull(pull)
    except ValueError:
        res.status, res.reason = str(Status.INVALID_INPUT), 'unknown_pull'
        res.detail = f"pull must be 'forward' or 'backward' (or empty), got {req.pull!r}"
        return res
    if not all(math.isfinite(v) for v in values):
        res.status, res.reason = str(Status.INVALID_INPUT), 'not_finite'
        res.detail = f'state and phi must be finite, got {values}'
        return res
    if not (math.isfinite(req.h_band_m) and req.h_band_m >= 0.0):
        res.status, res.reason = str(Status.INVALID_INPUT), 'bad_h_band'
        res.detail = f'h_band_m must be finite and >= 0, got {req.h_band_m!r}'
        return res
    state = AnchorState(*values[:4])
    r = predictor.predict(state, values[4], pull)
    res.status, res.reason, res.detail = str(r.status), r.reason, r.detail
    res.has_value = r.status.has_value
    res.capacity_n = num_or_nan(r.capacity_N)
    if bound is not None and r.status.has_value and r.capacity_N is not None:
        res.capacity_lower_n = num_or_nan(bound(state, values[4], pull, req.h_band_m, r))
    res.slip_twist = twist_msg(r.slip_twist)
    res.slip_twist_scaled = twist_msg(r.slip_twist_scaled)
    res.flags = list(r.flags)
    return res


class ServicePredictor:
    """Capacity of hypothetical states from capacity_node's query service (see module doc)."""

    def __init__(self, node, service: str, pull: str = 'backward', timeout_s: float = 2.0,
                 retry_s: float = 1.0, stopping: Callable[[], bool] = lambda: False):
        self.path = f'service {service}'   # what behavior_node logs as its capacity source
        self.pull = pull
        self.timeout_s = timeout_s
        self.retry_s = retry_s
        self.stopping = stopping
        # Without the process's global ROS arguments: launch_ros passes `-r __node:=<name>`,
        # which would rename this helper node to its owner's name (two nodes of one name, one
        # rosout publisher between them). Its namespace and service name are given explicitly.
        self._node = rclpy.create_node(f'{node.get_name()}_capacity_query',
                                       namespace=node.get_namespace(), context=node.context,
                                       use_global_arguments=False)
        self._client = self._node.create_client(QueryCapacity, service)
        self._executor = SingleThreadedExecutor(context=node.context)
        self._executor.add_node(self._node)
        self._down_until = -math.inf
        self.calls = 0      # answered questions (tests)

    def predict(self, state: AnchorState, phi: float, pull: Pull | str = '') -> CapacityResult:
        """The core Predictor protocol (rftgls_core.predictor) over the query service. No
        answer in time, or an answer this node cannot read, is `stale` with no value."""
        return self.bound(state, phi, 0.0, pull)[0]

    def bound(self, state: AnchorState, phi: float, h_band: float,
              pull: Pull | str = '') -> tuple[CapacityResult, float | None]:
        """(the prediction, capacity_node's lower bound N with h within +- h_band m, or None
        where the node gives none). The prediction is `stale` without a value when the
        question went unanswered (``predict``)."""
        if time.monotonic() < self._down_until:
            return self._no_value(phi, 'capacity_query_backoff'), None
        if self.stopping():                   # no new question once a stop is requested
            return self._no_value(phi, 'stopping'), None
        if not self._wait(self._client.service_is_ready):
            return self._failed(phi, f'service {self._client.srv_name} not available'), None
        req = QueryCapacity.Request(h_m=float(state.h), theta_b_rad=float(state.theta_b),
                                    theta_l1_rad=float(state.theta_l1),
                                    theta_l2_rad=float(state.theta_l2), phi_rad=float(phi),
                                    pull=str(pull or self.pull), h_band_m=float(h_band))
        future = self._client.call_async(req)
        self._wait(future.done)
        res = future.result() if future.done() else None
        if res is None:
            self._client.remove_pending_request(future)
            return self._failed(phi, f'no answer within {self.timeout_s:g} s'), None
        try:
            status = Status(res.status)
        except ValueError:
            return self._failed(phi, f'unknown status {res.status!r}'), None
        self.calls += 1
        cap = res.capacity_n
        has = status.has_value and math.isfinite(cap)

        def twist(t) -> tuple[float, float, float] | None:
            v = (t.linear.x, t.linear.z, t.angular.y)
            return v if has and all(math.isfinite(x) for x in v) else None
        lower = res.capacity_lower_n
        return CapacityResult(phi=phi, status=status, method=res.method,
                              capacity_N=cap if has else None,
                              slip_twist=twist(res.slip_twist),
                              slip_twist_scaled=twist(res.slip_twist_scaled),
                              reason=res.reason, detail=res.detail, flags=tuple(res.flags)), \
            (lower if has and math.isfinite(lower) and lower >= 0.0 else None)

    def __call__(self, state: AnchorState, phi: float) -> tuple[float | None, Status]:
        """(capacity N or None, status): the short form the tests and tools print."""
        r = self.predict(state, phi)
        return (r.capacity_N if r.status.has_value else None), r.status

    def _wait(self, done: Callable[[], bool]) -> bool:
        """Spin the private executor until done(); False after timeout_s, at a stop request
        (within WAIT_SLICE_S) or once the context is shut down."""
        deadline = time.monotonic() + self.timeout_s
        while not done():
            left = deadline - time.monotonic()
            if left <= 0.0 or self.stopping() or not self._node.context.ok():
                return False
            self._executor.spin_once(timeout_sec=min(WAIT_SLICE_S, left))
        return True

    def _no_value(self, phi: float, reason: str) -> CapacityResult:
        return CapacityResult(phi=phi, status=Status.STALE, method='capacity_query',
                              reason=reason)

    def _failed(self, phi: float, why: str) -> CapacityResult:
        """No value; after a failure the service rests for retry_s. A question cut short by a
        stop request is no failure of the service: `stopping`, no rest, nothing logged."""
        if self.stopping():
            return self._no_value(phi, 'stopping')
        self._node.get_logger().warning(f'capacity query failed ({why}): no value for '
                                        f'{self.retry_s:g} s')
        self._down_until = time.monotonic() + self.retry_s
        return self._no_value(phi, 'capacity_query_failed')

    def destroy(self) -> None:
        """Release the query's node and executor (before the context is shut down: the
        executor's SIGINT guard condition dies with the context, and an executor left to the
        garbage collector would then fail to unregister it)."""
        self._executor.remove_node(self._node)
        self._node.destroy_node()
        self._executor.shutdown(timeout_sec=0.0)

