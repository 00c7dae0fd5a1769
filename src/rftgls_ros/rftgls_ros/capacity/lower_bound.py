"""capacity_node's conservative lower bound of the capacity, and what it remembers.

The bound is the smaller of two parts (docs/design/capacity-inputs.md):

* sigma part (level > 0): rftgls_core.uncertainty.capacity_lower_bound, the one-sided
  confidence bound from h and theta_B one sigma to each side and a relative capacity sigma;
* range part: the smallest capacity over the range of every assumed or modelled input
  (range_bound.range_minimum).

Each asks the predictor for several states (about nine with a modelled height); next to the
support edge those are live solves of 10-20 ms each. During a tug the anchor state stands
still while the tether angle phi creeps with the sled (0.01 deg per tension sample), so a
bound taken at the exact phi would be solved afresh at every sample.

phi_step_rad > 0 takes the bound on a grid of pull angles instead: the smaller of the bounds
at the two grid angles bracketing phi, each remembered (the last CACHE of them). The capacity
changes little and smoothly over one step (0.5 deg: about 0.015 N at the MiniRQuad's 600 g
pose, against a measured phi whose own error is degrees), so the smaller end covers phi; the
point estimate (capacity, margin, slip twist) stays at the exact phi. phi_step_rad 0: the
bound at the exact phi, remembered for that one state.

The body pitch theta_B creeps the same way: an IMU's pitch differs in its last digits at
every sample, and an anchor under a steady pre-tension turns by thousandths of a degree per
sample (the simulator's physics body: 0.001 deg per estimate at the MiniRQuad's g-40/-20>-20/-20
pose, where every new pitch cost ~180 ms of live edge checks and every estimate came 200 ms
late). theta_b_step_rad > 0 takes the bound on a grid of pitches too, the smallest over the
corners of the (theta_B, phi) cell around the state. A step of a tenth of theta_b_sigma (the
shipped 0.1 deg against 1 deg) moves the bound's own +-1 sigma band by a tenth of its half
width, and is well inside the IMU's own error.

A new grid cell still costs its nine solves per corner at once, 25-40 ms next to the edge:
longer than the tension period. `prefetch` prepares corners ahead one prediction per call
(capacity_node calls it after each answer), earliest needed first: phi and theta_B each move at
a rate (an average of their change per bound), so a corner ahead on both axes is needed once
both have come within a grid step of it, and no longer once either has passed it by a step
(such corners, behind on one axis before the other gets there, are skipped). Corners up to
LOOKAHEAD_CELLS cells ahead and needed within HORIZON_BOUNDS bounds are prepared that way; then
the cells on either side of the current one (a reversal, or an axis that does not move). Ahead
matters at the end of a tug: as the sled nears, phi steepens more than ten times faster than at
the start (a new 0.5 deg cell every ten to fifteen samples, two new corners each, while the
pitch creeps into a new 0.1 deg row every hundred), more than one prediction per sample can
keep up with; the slow start of the tug, when nothing new is needed for a second at a time,
prepares those cells.

Units SI: h in m, angles in rad, capacities in N. No ROS.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable
from dataclasses import dataclass, replace

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Pull
from rftgls_core.uncertainty import capacity_lower_bound

from .range_bound import range_minimum

Predict = Callable[[AnchorState, float], CapacityResult]
Ranges = tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class BoundSettings:
    """level: one-sided confidence of the sigma part (0: off). h_sigma_m, theta_b_sigma_rad,
    capacity_rel_sigma: its sigmas. h_range_m, phi_limit_rad: where the range part may scan.
    phi_step_rad, theta_b_step_rad: grids of pull angles and body pitches the bound is taken
    on (0: the exact value)."""

    level: float
    h_sigma_m: float
    theta_b_sigma_rad: float
    capacity_rel_sigma: float
    h_range_m: tuple[float, float]
    phi_limit_rad: float
    phi_step_rad: float = 0.0
    theta_b_step_rad: float = 0.0

    @property
    def gridded(self) -> bool:
        return self.phi_step_rad > 0.0 or self.theta_b_step_rad > 0.0


class _Missing(Exception):
    """A prediction a prefetch has not made yet."""

    def __init__(self, state: AnchorState, phi: float):
        super().__init__()
        self.state, self.phi = state, phi


class LowerBound:
    """predict: the estimator's predictor call for its pull, (state, phi) -> result."""

    # bounds remembered on the grid: a cell's corners, its neighbours and the corners ahead
    CACHE = 256
    # how far ahead prefetch prepares: cells per axis, and bounds until a corner is needed
    # (capacity_node bounds once per tension sample: 300 at 100 Hz are 3 s)
    LOOKAHEAD_CELLS = 12
    HORIZON_BOUNDS = 300.0
    # weight of the newest change in each axis's rate (an average over ~20 bounds: an IMU's
    # noise averages out, a tug's steady creep does not)
    RATE_WEIGHT = 0.05

    def __init__(self, predict: Predict, settings: BoundSettings):
        self.predict = predict
        self.settings = settings
        self._known: OrderedDict[tuple, float] = OrderedDict()
        self._last: tuple[AnchorState, float, Ranges] | None = None
        # which way phi and theta_B moved last (-1, 0, +1): prefetch prepares that side first
        self._heading = (0, 0)
        # phi and theta_B change per bound (rad), averaged with RATE_WEIGHT
        self._rate = (0.0, 0.0)
        # predictions made ahead for a grid angle's bound, by that bound's key
        self._ahead: dict[tuple, dict[tuple, CapacityResult]] = {}

    def bound(self, state: AnchorState, phi: float, center: CapacityResult | None,
              ranges: Ranges) -> float | None:
        """The lower bound (N, >= 0) at state and phi, whose own prediction is `center`
        (status ok or assumed, with a capacity; None: not made at exactly this state and
        phi); None when neither part applies."""
        s = self.settings
        if s.level <= 0.0 and not ranges:
            return None
        if not s.gridded:
            return self._at(state, phi, ranges, center)
        if self._last is not None:
            last, last_phi, _ = self._last
            self._heading = (_sign(phi - last_phi, self._heading[0]),
                             _sign(state.theta_b - last.theta_b, self._heading[1]))
            w = self.RATE_WEIGHT
            self._rate = ((1.0 - w) * self._rate[0] + w * (phi - last_phi),
                          (1.0 - w) * self._rate[1] + w * (state.theta_b - last.theta_b))
        self._last = (state, phi, ranges)
        return min(self._at(st, p, ranges, None)
                   for st in self._pitches(state) for p in self._phis(phi))

    def prefetch(self) -> bool:
        """Make one prediction toward the bound of a grid corner not known yet: the corners
        ahead, earliest needed first (module doc), then those of the cells next to the last
        one: the phi row on the side phi last moved to, the theta_B row on the side theta_B
        last moved to, then the other two. False when all are known or there is nothing to
        do."""
        if self._last is None or not self.settings.gridded:
            return False
        state, phi, ranges = self._last
        s = self.settings
        rows: list[list[tuple[AnchorState, float]]] = [self._ahead_of(state, phi), [], [], [], []]
        for k, p in enumerate(_neighbours(phi, s.phi_step_rad)):
            if abs(p) <= s.phi_limit_rad:   # k 0: below, 1: above
                ahead = (k == 1) == (self._heading[0] > 0)
                rows[1 if ahead else 3] += [(st, p) for st in self._pitches(state)]
        for k, t in enumerate(_neighbours(state.theta_b, s.theta_b_step_rad)):
            ahead = (k == 1) == (self._heading[1] > 0)
            rows[2 if ahead else 4] += [(_with_pitch(state, t), p) for p in self._phis(phi)]
        todo = [corner for row in rows for corner in row]
        for st, p in todo:
            key = (st.as_tuple(), p, ranges)
            if key in self._known:
                continue
            try:
                self._at(st, p, ranges, None, only_ahead=True)
            except _Missing as miss:
                memo = self._ahead.setdefault(key, {})
                memo[(miss.state.as_tuple(), miss.phi)] = self.predict(miss.state, miss.phi)
            return True
        return False

    def _ahead_of(self, state: AnchorState, phi: float) -> list[tuple[AnchorState, float]]:
        """The grid corners ahead of (state, phi) along each axis's rate, earliest needed
        first, within LOOKAHEAD_CELLS and HORIZON_BOUNDS (the corners in use now included:
        they are known after any bound)."""
        s = self.settings
        phis = _ahead(phi, s.phi_step_rad, self._rate[0], s.phi_limit_rad,
                      self.LOOKAHEAD_CELLS, self.HORIZON_BOUNDS)
        pitches = _ahead(state.theta_b, s.theta_b_step_rad, self._rate[1], math.inf,
                         self.LOOKAHEAD_CELLS, self.HORIZON_BOUNDS)
        # a corner is needed from when both its values are corners until either stops being
        # one: corners whose two spans do not meet are never needed on this course
        corners = sorted((max(ep, et), k, t, p) for k, ((p, ep, lp), (t, et, lt))
                         in enumerate((a, b) for a in phis for b in pitches)
                         if max(ep, et) < min(lp, lt))
        return [(_with_pitch(state, t), p) for when, _, t, p in corners
                if when <= self.HORIZON_BOUNDS]

    def _phis(self, phi: float) -> list[float]:
        return _bracket(phi, self.settings.phi_step_rad, self.settings.phi_limit_rad)

    def _pitches(self, state: AnchorState) -> list[AnchorState]:
        return [_with_pitch(state, t)
                for t in _bracket(state.theta_b, self.settings.theta_b_step_rad, math.inf)]

    def _near(self, a: tuple, b: tuple) -> bool:
        """a and b (state tuples) the same pose but for a pitch within prefetch's reach
        (LOOKAHEAD_CELLS and the neighbouring row beyond the cell)."""
        step = self.settings.theta_b_step_rad
        if a[0] != b[0] or a[2:] != b[2:]:
            return False
        return a[1] == b[1] if step <= 0.0 else \
            abs(a[1] - b[1]) < (self.LOOKAHEAD_CELLS + 2.5) * step

    def _at(self, state: AnchorState, phi: float, ranges: Ranges,
            center: CapacityResult | None, only_ahead: bool = False) -> float:
        """The bound at exactly this phi. only_ahead: use the predictions made ahead and
        raise _Missing at the first one not made yet."""
        key = (state.as_tuple(), phi, ranges)
        if key in self._known:
            self._known.move_to_end(key)
            return self._known[key]
        # Both parts ask for some of the same states (the state itself, h one sigma away):
        # each is predicted once.
        answers = self._ahead.get(key, {})
        if center is not None:
            answers[(state.as_tuple(), phi)] = center

        def predict(st: AnchorState, ph: float) -> CapacityResult:
            k = (st.as_tuple(), ph)
            if k not in answers:
                if only_ahead:
                    raise _Missing(st, ph)
                answers[k] = self.predict(st, ph)
            return answers[k]

        here = predict(state, phi)
        if not here.status.has_value or here.capacity_N is None:
            lower = 0.0     # somewhere in the bracket the anchor may hold nothing
        else:
            s = self.settings
            bounds = []
            if s.level > 0.0:
                bounds.append(capacity_lower_bound(
                    predict, state, phi, here.capacity_N, s.level, s.h_sigma_m,
                    s.theta_b_sigma_rad, s.capacity_rel_sigma))
            if ranges:
                bounds.append(range_minimum(predict, state, phi, dict(ranges), s.h_range_m,
                                            s.phi_limit_rad))
            lower = min(bounds)
        self._known[key] = lower
        self._ahead.pop(key, None)
        # what was made ahead for states other than the one now in use (and its pitch
        # neighbours on the grid) is dropped
        self._ahead = {k: v for k, v in self._ahead.items() if self._near(k[0], key[0])}
        while len(self._known) > (self.CACHE if self.settings.gridded else 1):
            self._known.popitem(last=False)
        return lower


class AskedBound:
    """The lower bound at states asked about rather than measured ("what if I burrow to this
    pose?": capacity_node's query service, and behavior_node's chooser over its own map): the
    live bound's two parts with ``settings``, h known only within a band and every other input
    taken as given, at the exact pitch and tether angle (the grids serve inputs that creep
    from sample to sample; a question does not creep). One LowerBound per pull asked.
    ``predict``: (state, phi, pull) -> CapacityResult."""

    def __init__(self, predict: Callable[[AnchorState, float, Pull], CapacityResult],
                 settings: BoundSettings):
        self.predict = predict
        self.settings = replace(settings, phi_step_rad=0.0, theta_b_step_rad=0.0)
        self._bounds: dict[Pull, LowerBound] = {}

    def bound(self, state: AnchorState, phi: float, pull: Pull | str, h_band: float,
              center: CapacityResult | None) -> float | None:
        """The lower bound (N) with h within +- h_band (m; 0: exact); ``center``: the
        prediction at the state itself if made (LowerBound.bound). None when neither part
        applies (no sigma part configured, h_band 0)."""
        key = Pull(pull)
        if key not in self._bounds:
            self._bounds[key] = LowerBound(lambda st, ph: self.predict(st, ph, key),
                                           self.settings)
        return self._bounds[key].bound(state, phi, center,
                                       (('height', h_band),) if h_band > 0.0 else ())


def _grid(i: int, step: float) -> float:
    """Grid value i. Always formed as i x step: a bound is remembered by its grid value, and
    the same value reached as a neighbour's value + step would differ in its last bit for
    about half of the grid (a bound prepared under one spelling was then never found under
    the other)."""
    return i * step


def nearest(x: float, step: float) -> float:
    """The grid value nearest x (x itself without a grid, step 0), formed as _grid's."""
    return x if step <= 0.0 else _grid(round(x / step), step)


def _bracket(x: float, step: float, limit: float) -> list[float]:
    """The grid values on either side of x (x itself on a node, or without a grid)."""
    if step <= 0.0:
        return [x]
    i = math.floor(x / step)
    lo = _grid(i, step)
    return [lo] if lo == x else [lo, min(_grid(i + 1, step), limit)]


def _neighbours(x: float, step: float) -> list[float]:
    """The grid values just outside x's bracket, below then above (none without a grid)."""
    if step <= 0.0:
        return []
    i = math.floor(x / step)
    return [_grid(i - 1, step), _grid((i if _grid(i, step) == x else i + 1) + 1, step)]


def _ahead(x: float, step: float, rate: float, limit: float, cells: int,
           horizon: float) -> list[tuple[float, float, float]]:
    """(grid value, bounds until it becomes a corner of x's cell, bounds until it stops being
    one) for the values of x's bracket and up to `cells` grid values beyond it the way x moves
    at `rate` (per bound), while within `horizon` bounds and |value| <= limit. A value is a
    corner while x lies within one step of it."""
    if step <= 0.0:
        return [(x, 0.0, math.inf)]
    if rate == 0.0:
        return [(v, 0.0, math.inf) for v in _bracket(x, step, limit)]
    speed = abs(rate)
    # in use now: the value behind x leaves when x is a step past it, the one ahead when x
    # is a step past that one
    out = [(v, 0.0, (step - abs(v - x) if (v - x) * rate <= 0.0 else step + abs(v - x)) / speed)
           for v in _bracket(x, step, limit)]
    i = math.floor(x / step)
    first, way = (i + (1 if _grid(i, step) == x else 2), 1) if rate > 0.0 else (i - 1, -1)
    for n in range(cells):
        v = _grid(first + way * n, step)
        if abs(v) > limit:
            break
        enter = (abs(v - x) - step) / speed
        if enter > horizon:
            break
        out.append((v, max(enter, 0.0), (abs(v - x) + step) / speed))
    return out


def _sign(change: float, before: int) -> int:
    """-1 or +1 for a change, `before` when nothing changed."""
    return before if change == 0.0 else (1 if change > 0.0 else -1)


def _with_pitch(state: AnchorState, theta_b: float) -> AnchorState:
    return AnchorState(state.h, theta_b, state.theta_l1, state.theta_l2)
