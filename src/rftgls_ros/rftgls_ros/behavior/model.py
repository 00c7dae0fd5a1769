"""Anchor modes, required force, energy per mode, the mode chooser and the tether geometry.

Units: SI (m, rad, N, J, s). Angles of legs and body follow docs/design/architecture.md: leg angles
from -z_B about the axle, body pitch thetaB positive nose up, h = height of the winch point p
above the sand. Pull angle phi: 0 = horizontal tether, negative = tether going down from p to
the sled (the paper's -20 deg when the sled is close).
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from typing import Protocol, runtime_checkable

from rftgls_conventions import G
from rftgls_core.multibody.gaits import TABLE_II_BURROWS
from rftgls_core.predictor import Predictor
from rftgls_core.robots.measured_burrows import MEASURED_BURROWS, MEASURED_ENERGY_RATIOS
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Pull, Status

from ..capacity.estimator import EstimatorConfig
from ..capacity.lower_bound import AskedBound, BoundSettings
from ..capacity.range_bound import scan_points


@dataclass(frozen=True)
class AnchorMode:
    """One burrowing mode of the paper's Table II.

    retract, final: (thetaL1, thetaL2) in rad; h: mean final height of p, m; theta_b: mean
    final body pitch, rad; energy_ratio: burrow energy relative to SH (paper Fig. 10(a));
    h_sd: standard deviation of the final height over the paper's six trials, m.
    """

    name: str
    retract: tuple[float, float]
    final: tuple[float, float]
    h: float
    theta_b: float
    energy_ratio: float
    h_sd: float

    @property
    def h_band(self) -> float:
        """Half-width of the range a burrowed height is taken to lie in, m: H_BAND_SDS of the
        paper's standard deviations (MiniRQuad does not measure h)."""
        return H_BAND_SDS * self.h_sd

    def expected_state(self) -> AnchorState:
        """The anchor state the paper measured after this burrow (Table II means)."""
        return AnchorState(self.h, self.theta_b, self.final[0], self.final[1])


def _rad(a: float, b: float) -> tuple[float, float]:
    return (math.radians(a), math.radians(b))


def _mode(name: str) -> AnchorMode:
    """A paper mode: its leg angles (multibody.gaits.TABLE_II_BURROWS, deg), its measured
    final pose, mean and SD of six trials (Table II), and its measured energy relative to SH
    (Fig. 10(a)), both from robots.measured_burrows."""
    retract, final = TABLE_II_BURROWS[name]
    b = MEASURED_BURROWS['minirquad'][name]
    return AnchorMode(name, _rad(*retract), _rad(*final), b.h_m, b.theta_b_rad,
                      MEASURED_ENERGY_RATIOS['minirquad'][name], b.h_sd_m)


ANCHOR_MODES: dict[str, AnchorMode] = {m: _mode(m) for m in ('DH', 'DL', 'SH')}
# A burrowed height is taken to lie within this many of Table II's standard deviations of its
# mean (about 95 % of burrows if their spread is normal; six trials say little more).
H_BAND_SDS = 2.0


# --------------------------------------------------------------------------- required force
@dataclass
class ForceNeed:
    """Tension (N) the winch needs to drag the sled: mu * m * g until tugs have been measured,
    then a running blend with the median tension measured while the sled was sliding.

    sled_mass kg, mu the sled-on-sand Coulomb friction (0.5 assumed, as `rftgls demo` and the
    simulator), alpha the weight of a new measurement (0..1).
    """

    sled_mass: float
    mu: float = 0.5
    alpha: float = 0.5
    measured: float | None = None
    history: list[float] = field(default_factory=list)

    @property
    def nominal(self) -> float:
        return self.mu * self.sled_mass * G

    @property
    def value(self) -> float:
        return self.measured if self.measured is not None else self.nominal

    def update(self, tensions: Sequence[float]) -> float | None:
        """Blend in the median of tension samples (N) taken while the sled slid."""
        xs = sorted(t for t in tensions if math.isfinite(t))
        if len(xs) < 5:
            return None
        med = xs[len(xs) // 2]
        self.history.append(med)
        self.measured = med if self.measured is None else \
            (1.0 - self.alpha) * self.measured + self.alpha * med
        return med

    def raise_floor(self, tension: float) -> None:
        """The sled did not move at ``tension`` (N): it needs more than that."""
        self.measured = max(self.value, tension)


# --------------------------------------------------------------------------- energy
@dataclass
class EnergyModel:
    """Burrow energy above idle (J) per mode.

    Before any measurement the estimates are the paper's ratios times ``prior_sh`` (J). Each
    measured burrow updates its mode (running blend, weight ``alpha``); modes not measured yet
    are scaled by the mean measured/ratio of the measured ones, so the ranking follows the
    paper until the robot knows better.
    """

    prior_sh: float = 1.0
    alpha: float = 0.5
    ratios: dict[str, float] = field(
        default_factory=lambda: {n: m.energy_ratio for n, m in ANCHOR_MODES.items()})
    measured: dict[str, float] = field(default_factory=dict)

    def scale(self) -> float:
        if not self.measured:
            return self.prior_sh
        return sum(v / self.ratios[k] for k, v in self.measured.items()) / len(self.measured)

    def estimate(self, mode: str) -> float:
        if mode in self.measured:
            return self.measured[mode]
        return self.ratios[mode] * self.scale()

    def update(self, mode: str, energy_j: float) -> None:
        if not math.isfinite(energy_j) or energy_j <= 0.0:
            return
        old = self.measured.get(mode)
        self.measured[mode] = energy_j if old is None else \
            (1.0 - self.alpha) * old + self.alpha * energy_j

    def source(self, mode: str) -> str:
        return 'measured' if mode in self.measured else (
            'paper ratio x measured scale' if self.measured else 'paper ratio')


# --------------------------------------------------------------------------- predictions
Prediction = tuple[float | None, Status]
# Where a height band is scanned (m) and the largest tether angle (rad): capacity_node's
# defaults (its configured ones are not known in this process).
_NODE_DEFAULTS = EstimatorConfig()
H_LIMITS_M = _NODE_DEFAULTS.h_range_m
PHI_LIMIT_RAD = _NODE_DEFAULTS.phi_limit_rad


@runtime_checkable
class BoundSource(Protocol):
    """Where the chooser's lower bounds come from: capacity_node's query service
    (capacity_query.ServicePredictor) or a predictor in this process (LocalBound)."""

    def bound(self, state: AnchorState, phi: float, h_band: float,
              pull: Pull | str = '') -> tuple[CapacityResult, float | None]:
        """(the prediction at state, the lower bound N with h within +- h_band m; None
        where no part of the bound applies)."""
        ...


class LocalBound:
    """Lower bounds over a predictor in this process (behavior_node's capacity_source
    local_map, and the tests' predictors), by capacity_node's own code for asked states
    (capacity.lower_bound.AskedBound). ``settings``: the bound's sigma part and limits; the
    default is the range part alone within capacity_node's default h limits, because this
    process does not know the sigmas a capacity_node is configured with."""

    def __init__(self, predictor: Predictor, pull: Pull | str = 'backward',
                 settings: BoundSettings | None = None):
        self.predictor = predictor
        self.pull = Pull(pull)
        self.asked = AskedBound(predictor.predict, settings or BoundSettings(
            0.0, 0.0, 0.0, 0.0, H_LIMITS_M, PHI_LIMIT_RAD))

    def bound(self, state: AnchorState, phi: float, h_band: float,
              pull: Pull | str = '') -> tuple[CapacityResult, float | None]:
        key = Pull(pull or self.pull)
        r = self.predictor.predict(state, phi, key)
        if not r.status.has_value or r.capacity_N is None:
            return r, None
        return r, self.asked.bound(state, phi, key, h_band, r)


@dataclass(frozen=True)
class BandScan:
    """One pull angle over a height band: the lower bound (N, None without an answer), the
    point estimate at the band's centre (N, None without a value), the status (stale: a
    question went unanswered) and, when the bound is 0 for want of a value, where ('' =
    nowhere)."""

    lower: float | None
    point: float | None
    status: Status
    gap: str = ''


def versus(lower: float, required: float) -> str:
    """'L N >= R N' or 'L N < R N' for a lower bound against what is required (N): two
    decimals, more where a bound just short of the need would print equal to it ('2.018 N <
    2.022 N', not '2.02 N < 2.02 N')."""
    ok = lower >= required
    d = 2
    while not ok and d < 6 and f'{lower:.{d}f}' == f'{required:.{d}f}':
        d += 1
    return f'{lower:.{d}f} N {">=" if ok else "<"} {required:.{d}f} N'


@dataclass(frozen=True)
class Candidate:
    """One mode as the chooser saw it: per pull angle the lower bound it decides on (N, the
    smallest capacity over the mode's height band) and the status, the weakest lower bound,
    the weakest point estimate at the pose itself (``point``, N: reported, never decided on),
    the energy estimate (J) and whether it is sufficient (and why not)."""

    mode: str
    capacities: tuple[float | None, ...]
    statuses: tuple[str, ...]
    weakest: float | None
    energy_j: float
    sufficient: bool
    why: str
    point: float | None = None


@dataclass(frozen=True)
class Decision:
    """The chooser's answer: ``mode`` (None = do not tug), the required force, the safety
    factor and the tug ratio used (ModeChooser.tug_ratio: the guard's stop ratio, or lower
    for a tether the reel must bring in at speed), every candidate, and a one-line human
    reason."""

    mode: str | None
    need_n: float
    safety_factor: float
    phis: tuple[float, ...]
    candidates: tuple[Candidate, ...]
    reason: str
    pose: str = 'expected'
    tug_ratio: float = 1.0

    @property
    def required_n(self) -> float:
        """The lower bound a mode needs, N (ModeChooser.required)."""
        return self.safety_factor * self.need_n / self.tug_ratio

    def candidate(self, mode: str) -> Candidate | None:
        """The candidate of ``mode`` (None if it was not assessed)."""
        return next((c for c in self.candidates if c.mode == mode), None)

    def table(self) -> str:
        phis = '/'.join(f'{math.degrees(p):.0f}' for p in self.phis)
        lines = [f'  need {self.need_n:.2f} N x SF {self.safety_factor:.2f} / tug ratio '
                 f'{self.tug_ratio:.2f} = {self.required_n:.2f} N; lower bound over the '
                 f'height band at phi {phis} deg ({self.pose} pose):']
        for c in self.candidates:
            caps = '/'.join(f'{x:.2f}' if x is not None else s
                            for x, s in zip(c.capacities, c.statuses))
            point = f'{c.point:.2f} N' if c.point is not None else 'none'
            lines.append(f'    {c.mode}: {caps} N (point estimate {point}), energy '
                         f'{c.energy_j:.2f} J -> {"ok" if c.sufficient else "no"} ({c.why})')
        return '\n'.join(lines)


class ModeChooser:
    """Cheapest sufficient mode: a mode is sufficient when every pull angle in ``phis`` has a
    valid prediction whose lower end over the mode's height band (``lower_capacity``) is
    >= ``required(need)`` (N): safety_factor x need / tug_ratio. Ties go to the stronger.

    ``stop_ratio`` is the margin guard's (BehaviorConfig.stop_ratio, set by the machine that
    tugs on the decision; 1.0 for a chooser alone): the guard stops the winch when the tension
    reaches stop_ratio x the lower bound, and the sled moves only at its sliding tension, the
    need. A lower bound between need and need / stop_ratio is a tug the guard stops before
    the sled moves, so it does not suffice. ``reel_ratio`` (set by the machine from the
    tether left, reel.tug_ratio; 1.0 alone) is the largest need / lower bound at which the
    reel, slowed inside its slow band, still brings the tether in within the tug timeout: a
    bound that leaves the tug crawling past its timeout does not suffice either.
    ``tug_ratio`` is the smaller of the two.

    ``predictor``: any rftgls_core ``Predictor`` (the map capacity_node loads, or the live
    model), asked for ``pull`` (MiniRQuad's winch is on its back: 'backward'). Its lower
    bounds come from the predictor itself when it is a ``BoundSource`` (capacity_node's query
    service: the bound capacity_node gates the tug on), else from ``LocalBound`` over it.
    Only a measured ``ok`` prediction counts (``assumed``, ``extrapolated`` and every
    no-value status do not). ``scale`` (<= 1) multiplies every prediction once the robot has
    seen its anchor slip below the prediction (the ground is weaker than the model)."""

    def __init__(self, predictor: Predictor, safety_factor: float = 1.0,
                 phis: Sequence[float] = (0.0, math.radians(-20.0)),
                 modes: dict[str, AnchorMode] | None = None, pull: Pull | str = 'backward'):
        self.predictor = predictor
        self.safety_factor = safety_factor
        self.phis = tuple(phis)
        self.modes = modes or ANCHOR_MODES
        self.pull = Pull(pull)
        self.bounds: BoundSource = predictor if isinstance(predictor, BoundSource) \
            else LocalBound(predictor, self.pull)
        self.scale = 1.0
        self.stop_ratio = 1.0
        self.reel_ratio = 1.0

    @property
    def tug_ratio(self) -> float:
        """The tension / lower bound ratio a tug on the decision may run at (class doc)."""
        return min(self.stop_ratio, self.reel_ratio)

    def required(self, need: float) -> float:
        """The lower bound (N) a decision asks for a sled needing ``need`` (N): the tug
        moves it under the margin guard and brings it in within its timeout, with the safety
        factor."""
        return self.safety_factor * need / self.tug_ratio

    def guard_required(self, need: float) -> float:
        """The lower bound (N) below which a running tug stops: the margin guard would stop
        the winch before the sled moved. (A tug that merely crawls is its timeout's.)"""
        return self.safety_factor * need / self.stop_ratio

    def observe(self, mode: str, lower: float) -> None:
        """A lower bound (N, unscaled) for `mode` at its measured pose, seen at CHECK (the
        pose check's or capacity_node's live one). The Table II modes are judged at the
        measured pose each time: nothing kept."""

    def capacity(self, state: AnchorState, phi: float) -> Prediction:
        """(capacity N along d(phi) or None without a value, status) of the predictor."""
        r = self.predictor.predict(state, phi, self.pull)
        return (r.capacity_N if r.status.has_value else None), r.status

    def lower_capacity(self, state: AnchorState, phi: float, h_band: float) -> Prediction:
        """(lower bound N, status) at state: the bound capacity_node computes (``bounds``),
        with the height of p known only to lie within h +- h_band (m; 0 or NaN: the state's h
        alone). 0 when the prediction at the state has no value. Status: stale when the
        question went unanswered (no value: missing evidence, not a weak anchor), else ok."""
        scan = self.band_scan(state, phi, h_band)
        return scan.lower, scan.status

    def band_scan(self, state: AnchorState, phi: float, h_band: float) -> BandScan:
        """``lower_capacity`` with the point estimate at the state itself and, when the
        bound is 0 for want of a value, where ('' = nowhere)."""
        r, lower = self.bounds.bound(state, phi, h_band if h_band > 0.0 else 0.0, self.pull)
        if r.status == Status.STALE:            # unanswered: no value, not a weak anchor
            return BandScan(None, None, r.status, f'{r.status} at h {1e3 * state.h:.0f} mm')
        cap = r.capacity_N
        if r.status != Status.OK or cap is None or not math.isfinite(cap):
            return BandScan(0.0, None, Status.OK, f'at its pose ({r.status} at h '
                                                  f'{1e3 * state.h:.0f} mm)')
        lower = cap if lower is None else min(lower, cap)
        gap = '' if lower > 0.0 or cap == 0.0 else self._no_value_at(state, phi, h_band)
        return BandScan(lower, cap, Status.OK, gap)

    def _no_value_at(self, state: AnchorState, phi: float, h_band: float) -> str:
        """Where a bound of 0 found no value, for the decision's text: the first height of
        the band's scan (range_bound.scan_points, within capacity_node's default h limits)
        whose prediction has none, else one sigma of the pose (the bound's sigma part).
        Asked only for a bound of 0, so the extra questions cost nothing on the way to a
        tug."""
        if h_band > 0.0:
            for h in scan_points(state.h, h_band, *H_LIMITS_M):
                r = self.predictor.predict(replace(state, h=h), phi, self.pull)
                if not r.status.has_value or r.capacity_N is None:
                    return f'somewhere in its height band ({r.status} at h {1e3 * h:.0f} mm)'
        return 'within one sigma of its pose (the bound\'s sigma part)'

    def evaluate(self, mode: str, state: AnchorState, need: float, energy: float,
                 h_band: float | None = None) -> Candidate:
        """The mode at ``state``: per pull angle the lower capacity over the height band
        h_band (m; default the mode's own) around state.h (a decision uses the lower bound,
        not the point estimate), times ``scale``; the point estimate at the state's own h is
        kept for the report."""
        caps, stats, points, gaps = [], [], [], []
        band = h_band if h_band is not None else (
            self.modes[mode].h_band if mode in self.modes else 0.0)
        for phi in self.phis:
            scan = self.band_scan(state, phi, band)
            cap = scan.lower
            ok = scan.status == Status.OK and cap is not None and math.isfinite(cap)
            caps.append(cap * self.scale if ok else None)
            stats.append(str(scan.status))
            points.append(scan.point * self.scale if scan.point is not None else None)
            if scan.gap:
                gaps.append(scan.gap)
        weakest_point = None if any(p is None for p in points) else min(points)
        required = self.required(need)
        if any(c is None for c in caps):
            bad = [s for c, s in zip(caps, stats) if c is None]
            return Candidate(mode, tuple(caps), tuple(stats), None, energy, False,
                             f'no valid prediction: {", ".join(bad)}', weakest_point)
        weakest = min(caps)
        ok = weakest >= required
        why = f'lower bound {versus(weakest, required)}' + (
            f': no value {gaps[0]}' if gaps and not ok else '')
        return Candidate(mode, tuple(caps), tuple(stats), weakest, energy, ok, why,
                         weakest_point)

    def choose(self, need: float, energy: EnergyModel,
               states: dict[str, AnchorState] | None = None,
               exclude: Iterable[str] = (), stronger_than: float | None = None,
               pose: str = 'expected') -> Decision:
        """``states``: the pose to assess per mode (default: Table II means); ``exclude``:
        modes not to consider; ``stronger_than``: only modes whose weakest capacity is above
        this (N), used when re-burrowing after the guard stopped a tug."""
        excluded = set(exclude)
        cands = []
        for name, mode in self.modes.items():
            state = (states or {}).get(name, mode.expected_state())
            c = self.evaluate(name, state, need, energy.estimate(name))
            if name in excluded:
                c = replace(c, sufficient=False, why='excluded: ' + c.why)
            elif stronger_than is not None and c.sufficient and c.weakest <= stronger_than:
                c = replace(c, sufficient=False, why=f'not stronger than {stronger_than:.2f} N')
            cands.append(c)
        ok = [c for c in cands if c.sufficient]
        if not ok:
            best = max((c for c in cands if c.weakest is not None),
                       key=lambda c: c.weakest, default=None)
            reason = (f'no mode suffices: need {need:.2f} N x {self.safety_factor:.2f} / '
                      f'{self.tug_ratio:.2f}'
                      + (f', strongest {best.mode} has a lower bound of {best.weakest:.2f} N'
                         if best else ', no valid prediction'))
            return Decision(None, need, self.safety_factor, self.phis, tuple(cands), reason,
                            pose, self.tug_ratio)
        pick = min(ok, key=lambda c: (c.energy_j, -(c.weakest or 0.0)))
        others = [c.mode for c in ok if c is not pick]
        reason = (f'{pick.mode}: cheapest sufficient mode ({pick.energy_j:.2f} J, '
                  f'{energy.source(pick.mode)}); lower bound {pick.weakest:.2f} N >= '
                  f'{self.safety_factor:.2f} x {need:.2f} N / {self.tug_ratio:.2f}'
                  + (f'; also sufficient: {", ".join(others)}' if others else ''))
        return Decision(pick.mode, need, self.safety_factor, self.phis, tuple(cands), reason,
                        pose, self.tug_ratio)
