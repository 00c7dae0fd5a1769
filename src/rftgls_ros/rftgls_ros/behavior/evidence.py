"""Is the capacity estimate good enough to keep tugging? (docs/design/tug-safety.md)

A tug runs only on live evidence: a capacity estimate from capacity_node that is fresh, has a
value and a lower bound, and whose status is ``ok`` (every input measured, or modelled with a
band the lower bound covers) or ``assumed`` with every assumed input named in the
accept-list. ``judge`` turns what behavior_node last received into a ``Verdict``:

- usable: the winch may reel in on this estimate; its lower bound is the number to decide on
  (an estimate without a finite lower bound is not evidence: ``lower_bound_missing``).
- reason: a stable code (tests and reports use it, not the wording).
- transient: the evidence is only *missing, late or inconsistent* (no estimate yet, older than
  the timeout, ``stale``, a value-carrying status next to no value, ``assumed`` without
  the names of its assumed inputs, or computed at another height than the one this node now
  sends: capacity_node has not caught up with it yet). The winch stops at
  once, and the attempt is aborted if the evidence is not back within the grace time. Every
  other failure is an explicit "no value" from capacity_node and aborts at once.

Times in s on one clock (behavior_node's monotonic clock; an estimate's time is that of its
underlying sample, by header stamp, so its age includes every delay before it arrived).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

# Statuses of rftgls_core.types.Status, by name so this module needs no core import.
OK = 'ok'
ASSUMED = 'assumed'
STALE = 'stale'

# Reason codes (stable; the cycle report's `reason` column carries them).
USABLE = 'ok'
NO_ESTIMATE = 'estimate_missing'
TIMEOUT = 'estimate_timeout'
NO_VALUE = 'no_value'
NO_LOWER_BOUND = 'lower_bound_missing'
ASSUMED_NOT_ACCEPTED = 'assumed_not_accepted'
ASSUMED_UNKNOWN = 'assumed_inputs_unknown'
OTHER_HEIGHT = 'estimate_other_height'
# The reasons of evidence that is only missing, late or inconsistent (Verdict.transient).
TRANSIENT_REASONS = frozenset({NO_ESTIMATE, TIMEOUT, NO_VALUE, ASSUMED_UNKNOWN, OTHER_HEIGHT,
                               'status_stale'})

# The height sent and the height an estimate states it used compare equal when they are the
# same number: it crosses DDS as a float64, unchanged. 1 um leaves room for a copy that was
# re-serialised on its way, and is far below any new height this node sends (a new burrow or
# a replay of it moves h by 0.1 mm and more; its band is millimetres).
HEIGHT_MATCH_M = 1e-6


def status_reason(status: str) -> str:
    """Reason code for a non-value status word: 'status_<word>' (e.g. status_unsupported)."""
    word = ''.join(c if c.isalnum() else '_' for c in (status or 'empty').lower())
    return f'status_{word}'


@dataclass(frozen=True)
class Verdict:
    usable: bool
    reason: str
    transient: bool
    detail: str


def judge(t: float, capacity: float | None, status: str, t_capacity: float,
          timeout_s: float, assumed_inputs: frozenset[str] | None = None,
          accept_assumed: frozenset[str] = frozenset(),
          capacity_lower: float | None = math.inf, height_used: float = math.nan,
          height_sent: float | None = None) -> Verdict:
    """Verdict on the last estimate received at ``t_capacity`` (s), judged at ``t`` (s).

    capacity: N along the tether (None or NaN = no value); status: capacity_node's status
    word; assumed_inputs: the names capacity_node gave for an ``assumed`` status (None =
    not received); accept_assumed: assumed inputs this robot tolerates (default none);
    capacity_lower: the estimate's lower bound, N, the number a decision uses (None or NaN:
    none; the default inf leaves it out, for callers that judge the status alone);
    height_sent: the height of p (m) the caller now sends capacity_node, and height_used the
    one the estimate states it was computed at (NaN: not stated). An estimate at another
    height (or none stated) answers a question no longer asked; None leaves the check out
    (the caller sends no height, or capacity_node measures it).
    """
    if not math.isfinite(t_capacity):
        return Verdict(False, NO_ESTIMATE, True, 'no capacity estimate received yet')
    if status not in (OK, ASSUMED, STALE):
        # unsupported, degenerate, out_of_range, invalid_input, extrapolated (deprecated: a
        # clamped value is not evidence), or a word this node does not know: capacity_node
        # said there is no value, however old the saying (on a loaded host it may also be late).
        return Verdict(False, status_reason(status), False,
                       f'capacity_node status {status!r}: no usable value')
    age = t - t_capacity
    if age > timeout_s:
        return Verdict(False, TIMEOUT, True, f'last capacity estimate {1e3 * age:.0f} ms old '
                                             f'(timeout {1e3 * timeout_s:.0f} ms)')
    if status == STALE:
        return Verdict(False, status_reason(status), True,
                       'capacity_node reports stale inputs')
    if capacity is None or not math.isfinite(capacity) or capacity < 0.0:
        # Where status and value travel on two topics (teleop), a value-carrying status next
        # to a NaN is most often the other estimate's status read out of order. In one
        # message it is a broken estimate. The winch stops either way.
        return Verdict(False, NO_VALUE, True,
                       f'capacity_node status {status!r} without a finite capacity')
    if capacity_lower != math.inf and (capacity_lower is None or not math.isfinite(capacity_lower)
                           or capacity_lower < 0.0):
        # A decision uses the lower bound, never the point estimate: capacity_node publishes
        # one whenever an input is assumed (behavior_node's height always is) or a level is set.
        return Verdict(False, NO_LOWER_BOUND, False,
                       f'capacity_node status {status!r} without a lower bound (set '
                       'lower_bound_level, or send the height with its provenance)')
    if status == ASSUMED:
        if assumed_inputs is None:
            return Verdict(False, ASSUMED_UNKNOWN, True,
                           'status assumed, names of the assumed inputs not received')
        extra = sorted(set(assumed_inputs) - set(accept_assumed))
        if extra:
            return Verdict(False, ASSUMED_NOT_ACCEPTED, False,
                           f'assumed inputs {", ".join(extra)} not in accept_assumed_inputs '
                           f'({", ".join(sorted(accept_assumed)) or "empty"})')
    # Last: an explicit refusal above says more than a height not yet caught up with.
    if height_sent is not None and not abs(height_used - height_sent) <= HEIGHT_MATCH_M:
        # Most often the first estimates after this node changed its height (a burrow's
        # replay replaced the plan's h): the lower bound at the new height is still on its way.
        return Verdict(False, OTHER_HEIGHT, True,
                       f'estimate computed at h {1e3 * height_used:.2f} mm, this node sends '
                       f'{1e3 * height_sent:.2f} mm')
    return Verdict(True, USABLE, False, f'{status}, {1e3 * age:.0f} ms old')
