"""ROS-free core of capacity_node: timestamped inputs in, a status-carrying estimate out.

Inputs (SI, frames of docs/design/architecture.md#frames-and-signs; the rules, limits and
tolerances of each in docs/design/capacity-inputs.md):
  joints   leg angles, rad (theta_L1 proximal, theta_L2 distal, left/right): raw angles beyond
           +-leg_limit_rad are `invalid_input` before wrapping to [-pi, pi); the legs of one
           axle must agree within `leg_tolerance_rad` (else leg_disagreement), never averaged.
  pitch    theta_B, rad, positive when the axle end of the body is above p.
  tension  T, N along the load cell, positive pulling p toward the sled (below
           -tension_deadband_N: negative_tension).
  height   h of p above the sand, m;  phi  tether angle, rad: tension along (-cos phi, 0,
           sin phi) in world axes. Both fall back to their parameters (ASSUMED) until a sample
           arrives, and may arrive MODELLED or ASSUMED with a band (half-width); the other
           inputs are measurements (inputs.Provenance).
Times: seconds on one clock, when each sample was taken (header stamp, else receipt time); a
sample older than its timeout is stale, one over `clock_tolerance_s` in the future invalid.

Status precedence: stale > invalid_input > the predictor's status. An estimate with a value
is `ok` when every input is measured, or modelled with a stated finite band (which the lower
bound covers; reason `modelled_input:height`, `modelled` names it, /diagnostics `provenance`
says `height:modelled`); `assumed` when one came from a parameter, arrived ASSUMED, or arrived
MODELLED without a band (its range is then the node's assumption). A value (capacity, margin,
slip twist) is present only for ok and assumed. Reasons are `code:input` items joined by ';'
(e.g. `stale_input:tension`, `assumed_input:height`); `detail` is prose.
"""
from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Mapping
from dataclasses import dataclass, field, replace

from rftgls_conventions import LEG_KEYS, axle_angles, tether_direction_xz
from rftgls_core.predictor import Predictor, predictor_name
from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Provenance, Pull, Status
from rftgls_node_base.diagnostics import DiagStatus
from rftgls_node_base.parameters import ConfigError

from .inputs import LEG_LIMIT_RAD, band_problem
from .lower_bound import AskedBound, BoundSettings, LowerBound, nearest

JOINTS = LEG_KEYS  # leg angle keys, rftgls_conventions
# Input names, as used for timeouts and in stale/invalid reasons.
INPUTS = ('joint_states', 'pitch', 'tension', 'height', 'phi')
DEFAULT_TIMEOUTS_S = {'joint_states': 0.25, 'pitch': 0.25, 'tension': 0.25, 'height': 1.0,
                      'phi': 1.0}
# Inputs with a parameter fallback: used (and reported as assumed) until received once. Only
# these may arrive modelled or assumed (the lower bound can scan their range).
ASSUMABLE = ('height', 'phi')


@dataclass(frozen=True)
class Problem:
    """One reason an input is not usable: code (reason vocabulary), input name, prose."""

    code: str
    input: str
    text: str


def reason_of(problems: list[Problem]) -> str:
    """'code:input;code:input' without repeats, in order."""
    seen = dict.fromkeys(f'{p.code}:{p.input}' for p in problems)
    return ';'.join(seen)


@dataclass(frozen=True)
class EstimatorConfig:
    """Tunables of the estimator (units in the names). Validated by `check()`."""

    pull: str = 'backward'
    timeouts_s: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_TIMEOUTS_S))
    leg_tolerance_rad: float = math.radians(5.0)
    height_m: float = 0.03            # assumed h until a height sample arrives
    phi_rad: float = math.radians(-20.0)  # assumed phi until a phi sample arrives
    h_range_m: tuple[float, float] = (-0.05, 0.30)
    pitch_limit_rad: float = math.pi / 2
    leg_limit_rad: float = LEG_LIMIT_RAD   # raw, before wrapping (inputs.py says why)
    phi_limit_rad: float = math.pi / 2
    tension_max_N: float = 200.0
    tension_deadband_N: float = 0.05  # a load cell reads slightly below 0 at zero load
    clock_tolerance_s: float = 0.05   # a stamp this far ahead of our clock is accepted
    # Half-widths of the range an assumed input may really take: the lower bound is the
    # smallest capacity over it (docs/design/capacity-inputs.md).
    assumed_height_range_m: float = 0.01
    assumed_phi_range_rad: float = math.radians(10.0)
    # Conservative lower bound (rftgls_core.uncertainty); level 0 switches the sigma part off.
    lower_bound_level: float = 0.0
    h_sigma_m: float = 0.002
    theta_b_sigma_rad: float = math.radians(1.0)
    capacity_rel_sigma: float = 0.0
    lower_bound_phi_step_rad: float = 0.0   # 0: at the exact phi (lower_bound.py)
    lower_bound_theta_b_step_rad: float = 0.0   # 0: at the exact pitch (lower_bound.py)
    # The point estimate is solved at phi and theta_B rounded to these (0: exact; class doc).
    phi_resolution_rad: float = 0.0
    theta_b_resolution_rad: float = 0.0

    def check(self) -> 'EstimatorConfig':
        """Raise ConfigError on the first bad value; return self."""
        try:
            Pull(self.pull)
        except ValueError:
            raise ConfigError(f"pull must be 'forward' or 'backward', got {self.pull!r}") from None
        for name in INPUTS:
            t = self.timeouts_s.get(name)
            if t is None or not (math.isfinite(t) and t > 0):
                raise ConfigError(f'timeout of input {name!r} must be a positive number of '
                                  f'seconds, got {t!r}')
        lo, hi = self.h_range_m
        positive = {'leg_tolerance_rad': self.leg_tolerance_rad,
                    'pitch_limit_rad': self.pitch_limit_rad, 'leg_limit_rad': self.leg_limit_rad,
                    'phi_limit_rad': self.phi_limit_rad, 'tension_max_N': self.tension_max_N}
        for name, v in positive.items():
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f'{name} must be positive, got {v!r}')
        for name in ('tension_deadband_N', 'clock_tolerance_s', 'assumed_height_range_m',
                     'assumed_phi_range_rad'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f'{name} must be >= 0, got {v!r}')
        if not (self.lower_bound_level == 0.0 or 0.5 <= self.lower_bound_level < 1.0):
            raise ConfigError(f'lower_bound_level must be 0 (off) or in [0.5, 1), got '
                              f'{self.lower_bound_level!r}')
        for name in ('h_sigma_m', 'theta_b_sigma_rad', 'capacity_rel_sigma',
                     'lower_bound_phi_step_rad', 'lower_bound_theta_b_step_rad',
                     'phi_resolution_rad', 'theta_b_resolution_rad'):
            v = getattr(self, name)
            if not (math.isfinite(v) and v >= 0):
                raise ConfigError(f'{name} must be >= 0, got {v!r}')
        if not (math.isfinite(lo) and math.isfinite(hi) and lo < hi):
            raise ConfigError(f'h range must be finite with min < max, got {self.h_range_m!r}')
        if not (math.isfinite(self.height_m) and lo <= self.height_m <= hi):
            raise ConfigError(f'height_m must lie in [{lo}, {hi}] m, got {self.height_m!r}')
        if not (math.isfinite(self.phi_rad) and abs(self.phi_rad) <= self.phi_limit_rad):
            raise ConfigError(f'phi_rad must lie in [-{self.phi_limit_rad:.4g}, '
                              f'{self.phi_limit_rad:.4g}] rad, got {self.phi_rad!r}')
        return self


@dataclass(frozen=True)
class Sample:
    t: float      # s, when the sample was taken (header stamp, else receipt) on one clock
    value: float  # SI
    provenance: Provenance = Provenance.MEASURED
    band: float = math.nan   # half-width of the true value's range, SI; NaN = not stated


@dataclass(frozen=True)
class Estimate:
    """One prediction. capacity_N, margin_N and slip_twist are None unless `has_value`,
    except `unsupported`, which reports capacity_N = 0 and margin_N = -tension_N.

    capacity_N: load capacity along the tether direction d(phi), N.
    capacity_lower_N: a conservative lower bound, N: the one-sided confidence bound
        (config.lower_bound_level) and, with assumed inputs, the smallest capacity over their
        assumed range; None when neither applies or without a value.
    margin_N: capacity_N - tension_N, N (negative: the anchor is predicted to slip).
    slip_twist: the predictor's slip twist (rftgls_core CapacityResult.slip_twist): the
        direction (vx, vz, wy) of p's slip, world axes at p, m/s, m/s, rad/s, unit Euclidean
        norm (RFT is rate independent so only the direction is known); given whenever there
        is a value, `slipping` says whether the tension exceeds capacity.
    state, phi_rad, tension_N: the inputs used (None when missing or not finite).
    assumed: inputs taken from parameters, received as assumed, or received as modelled
        without a band ('height', 'phi').
    modelled: inputs received as modelled with a finite band (computed, not measured).
    stale: inputs that are stale or were never received.
    warnings: non-fatal findings.
    """

    t: float
    status: Status
    reason: str = ''
    detail: str = ''
    capacity_N: float | None = None
    capacity_lower_N: float | None = None
    tension_N: float | None = None
    margin_N: float | None = None
    slip_twist: tuple[float, float, float] | None = None
    slipping: bool = False
    state: AnchorState | None = None
    phi_rad: float | None = None
    leg_spread_rad: tuple[float, float] | None = None
    assumed: tuple[str, ...] = ()
    modelled: tuple[str, ...] = ()
    stale: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    predictor: str = ''
    result: CapacityResult | None = None

    @property
    def has_value(self) -> bool:
        return self.status in (Status.OK, Status.ASSUMED)

    @property
    def word(self) -> str:
        """The status capacity_node publishes (the provenance of each input says whether an
        ``ok`` rests on a modelled one)."""
        return str(self.status)

    def provenance(self) -> dict[str, str]:
        """Every input's provenance word, INPUTS order ('measured', 'modelled', 'assumed')."""
        return {n: str(Provenance.ASSUMED if n in self.assumed else Provenance.MODELLED
                       if n in self.modelled else Provenance.MEASURED) for n in INPUTS}

    @property
    def reason_codes(self) -> tuple[str, ...]:
        """The reason's items ('code:input', or a predictor's reason)."""
        return tuple(r for r in self.reason.split(';') if r)


NAN = float('nan')
# Diagnostic level per status word (diagnostic_msgs/DiagnosticStatus: 0 OK, 1 WARN, 2 ERROR,
# 3 STALE); a status not listed (e.g. the deprecated 'extrapolated') is an ERROR.
OK_LEVEL, WARN_LEVEL, ERROR_LEVEL, STALE_LEVEL = 0, 1, 2, 3
LEVELS = {str(s): level for s, level in (
    (Status.OK, OK_LEVEL), (Status.ASSUMED, WARN_LEVEL), (Status.OUT_OF_RANGE, ERROR_LEVEL),
    (Status.UNSUPPORTED, ERROR_LEVEL), (Status.DEGENERATE, ERROR_LEVEL),
    (Status.INVALID_INPUT, ERROR_LEVEL), (Status.STALE, STALE_LEVEL))}


@dataclass(frozen=True)
class Outputs:
    """What capacity_node publishes for one Estimate (the output policy, without ROS).

    Vectors are in the anchor frame: world-aligned axes at p, (x, z) components, N.
    capacity_xz, margin_xz, lower_xz: the scalar along d(phi) = (-cos phi, sin phi); NaN when
        there is no value, so nobody can read a number as a valid capacity. capacity_y: 0, or
        NaN without a value (the message's y component carries the 'no value' mark too).
    publish_lower: whether ~/capacity_lower is published (a lower bound is configured or an
        input is assumed or modelled).
    slip_twist: the estimate's slip twist (vx, vz, wy) while the anchor slips (tension above
        capacity); zero while it holds (the predicted motion is zero); NaN without a value.
    """

    status: str
    capacity_xz: tuple[float, float]
    capacity_y: float
    margin_xz: tuple[float, float]
    lower_xz: tuple[float, float]
    publish_lower: bool
    slip_twist: tuple[float, float, float]


def _along(value: float | None, d: tuple[float, float]) -> tuple[float, float]:
    v = value if value is not None else NAN
    return (v * d[0], v * d[1])


def _fmt(x: float | None) -> str:
    return 'nan' if x is None else f'{x:.6g}'


class CapacityEstimator:
    """Keeps the latest sample of every input and turns them into an Estimate on demand.

    The last predictions are remembered by (state, phi): a new tension alone does not
    re-query the predictor (capacity does not depend on T; only the margin does), which keeps
    the live predictor usable at sensor rates.

    Resolution (phi_resolution_rad, theta_b_resolution_rad): during a tug the tether angle
    creeps by ~0.01 deg per tension sample and an IMU's pitch differs in its last digits at
    every sample, so each sample is a new state; next to the support edge each costs a live
    solve (3-5 ms at the demo's 600 g anchor, more than half of a 100 Hz tension period).
    The point estimate (capacity, margin, slip twist) is therefore solved at phi and theta_B
    rounded to their resolution: at the shipped 0.05 deg one solve per five samples of a
    creeping phi, and the capacity within ~2 mN of the exact one there (about 0.03 N per
    degree of phi), far inside the degrees of the measured angle's own error. The lower bound
    still brackets the exact values (lower_bound.py), so the number decisions use is not
    rounded; the estimate reports the measured phi and state.
    """

    ANSWERS = 8     # predictions remembered (class doc)

    def __init__(self, predictor: Predictor, config: EstimatorConfig | None = None):
        self.predictor = predictor
        self.config = (config or EstimatorConfig()).check()
        self.pull = Pull(self.config.pull)
        self._joints: dict[str, Sample] = {}
        self._inputs: dict[str, Sample] = {}
        self._malformed: dict[str, Problem] = {}  # input -> why its latest message is unusable
        self._answers: OrderedDict[tuple, CapacityResult] = OrderedDict()
        self._bound = self._new_bound()
        self.asked = self._new_asked()   # the bound at states asked about (query service)
        self.predictions = 0  # predictor calls (cache misses), for diagnostics and tests

    def reconfigure(self, config: EstimatorConfig) -> None:
        """Use `config` from the next estimate on (a run-time parameter change). The pull
        cannot change (the predictor was checked for it): ConfigError."""
        config = config.check()
        if Pull(config.pull) is not self.pull:
            raise ConfigError('pull cannot change at run time')
        self.config = config
        self._answers.clear()
        self._bound = self._new_bound()
        self.asked = self._new_asked()

    def _new_bound(self) -> LowerBound:
        c = self.config
        return LowerBound(lambda st, ph: self.predictor.predict(st, ph, self.pull), BoundSettings(
            c.lower_bound_level, c.h_sigma_m, c.theta_b_sigma_rad, c.capacity_rel_sigma,
            c.h_range_m, c.phi_limit_rad, c.lower_bound_phi_step_rad,
            c.lower_bound_theta_b_step_rad))

    def _new_asked(self) -> AskedBound:
        c = self.config
        return AskedBound(self.predictor.predict, BoundSettings(
            c.lower_bound_level, c.h_sigma_m, c.theta_b_sigma_rad, c.capacity_rel_sigma,
            c.h_range_m, c.phi_limit_rad))

    # -- inputs -----------------------------------------------------------------------------
    def update_joints(self, t: float, angles: Mapping[str, float]) -> None:
        """Leg angles (rad) for any subset of JOINTS; other joints keep their last sample."""
        for key, value in angles.items():
            if key not in JOINTS:
                raise KeyError(f'unknown joint key {key!r}; expected one of {JOINTS}')
            self._joints[key] = Sample(t, float(value))
        self._malformed.pop('joint_states', None)

    def update(self, name: str, t: float, value: float,
               provenance: Provenance = Provenance.MEASURED, band: float = math.nan) -> None:
        """A scalar input: 'pitch' (rad), 'tension' (N), 'height' (m) or 'phi' (rad).

        provenance and band (half-width of the true value's range, the input's unit; NaN = not
        stated): height and phi may be modelled or assumed, every other input is measured
        (ValueError otherwise, as for a band that is negative or infinite).
        """
        if name not in INPUTS or name == 'joint_states':
            raise KeyError(f'unknown scalar input {name!r}')
        provenance = Provenance(provenance)
        if provenance is not Provenance.MEASURED and name not in ASSUMABLE:
            raise ValueError(f'{name} is measured; only {", ".join(ASSUMABLE)} may be '
                             f'{provenance}')
        why = band_problem(band)
        if why is not None:
            raise ValueError(f'{name}: {why}')
        self._inputs[name] = Sample(t, float(value), provenance, float(band))
        self._malformed.pop(name, None)

    def mark_malformed(self, name: str, t: float, why: str, code: str = 'malformed') -> None:
        """Record that the latest message of an input is unusable (-> invalid_input with
        reason `code:name` until a good message of that input arrives). The message still
        counts as a sign of life: its time t refreshes the input's age."""
        if name not in INPUTS:
            raise KeyError(f'unknown input {name!r}')
        self._malformed[name] = Problem(code, name, why)
        if name == 'joint_states':
            for k in JOINTS:
                if k in self._joints:
                    self._joints[k] = replace(self._joints[k], t=t)
        elif name in self._inputs:
            self._inputs[name] = replace(self._inputs[name], t=t)
        else:
            self._inputs[name] = Sample(t, math.nan)

    def current_phi(self) -> float:
        """The tether angle in use, rad: the latest sample, else the assumed phi_rad."""
        return self._value('phi', self.config.phi_rad)

    # -- output -----------------------------------------------------------------------------
    def estimate(self, now: float) -> Estimate:
        cfg = self.config
        stale_problems = self._stale_inputs(now)
        tension = self._value('tension')
        phi = self._value('phi', cfg.phi_rad)
        assumed = self._with_provenance(Provenance.ASSUMED)
        modelled = self._with_provenance(Provenance.MODELLED)
        if stale_problems:
            return Estimate(now, Status.STALE, reason_of(stale_problems),
                            '; '.join(p.text for p in stale_problems),
                            tension_N=tension, phi_rad=phi, assumed=assumed, modelled=modelled,
                            stale=tuple(dict.fromkeys(p.input for p in stale_problems)),
                            predictor=predictor_name(self.predictor))
        legs, spread, problems = self._legs()
        pitch = self._value('pitch')
        h = self._value('height', cfg.height_m)
        problems += self._future_stamps(now)
        problems += list(self._malformed.values())
        problems += self._range_problems(h, pitch, phi, tension)
        state = None
        if legs is not None and _finite(h, pitch):
            state = AnchorState(h, pitch, legs[0], legs[1])
        common = dict(tension_N=tension if _finite(tension) else None,
                      phi_rad=phi if _finite(phi) else None, state=state,
                      leg_spread_rad=spread, assumed=assumed, modelled=modelled,
                      predictor=predictor_name(self.predictor))
        if problems:
            return Estimate(now, Status.INVALID_INPUT, reason_of(problems),
                            '; '.join(p.text for p in problems), **common)
        solved = AnchorState(state.h, nearest(state.theta_b, cfg.theta_b_resolution_rad),
                             state.theta_l1, state.theta_l2)
        solved_phi = nearest(phi, cfg.phi_resolution_rad)
        result = self._predict(solved, solved_phi)
        if result.status is Status.UNSUPPORTED:
            # No quasi-static balance: the anchor holds nothing. Zero is the safe number here,
            # so it is reported (the slip direction is unknown and stays None).
            t_pos = max(tension, 0.0)
            return Estimate(now, Status.UNSUPPORTED, result.reason or 'unsupported',
                            result.detail, capacity_N=0.0, margin_N=-t_pos, slipping=t_pos > 0,
                            result=result, **{**common, 'tension_N': t_pos})
        if result.status not in (Status.OK, Status.ASSUMED) or result.capacity_N is None:
            status = result.status if result.status not in (Status.OK, Status.ASSUMED) \
                else Status.DEGENERATE
            return Estimate(now, status, result.reason or str(status), result.detail,
                            result=result, **common)
        tension = max(tension, 0.0)  # inside the dead band
        margin = result.capacity_N - tension
        exact = solved == state and solved_phi == phi
        lower = self._bound.bound(state, phi, result if exact else None, self._ranges())
        status, reason = result.status, result.reason
        if assumed:
            status = Status.ASSUMED
        if assumed or modelled:
            reason = reason_of([Problem('assumed_input', n, '') for n in assumed]
                               + [Problem('modelled_input', n, '') for n in modelled]) \
                + (f';{result.reason}' if result.reason else '')
        return Estimate(now, status, reason, result.detail,
                        capacity_N=result.capacity_N, capacity_lower_N=lower, margin_N=margin,
                        slip_twist=result.slip_twist, slipping=margin < 0.0, result=result,
                        **{**common, 'tension_N': tension})

    def outputs(self, est: Estimate) -> Outputs:
        """The output policy for `est` (see Outputs)."""
        d = tether_direction_xz(est.phi_rad if est.phi_rad is not None else NAN)
        if est.slip_twist is None:
            twist = (NAN, NAN, NAN)
        elif est.slipping:
            twist = est.slip_twist
        else:  # the anchor holds: predicted motion is zero
            twist = (0.0, 0.0, 0.0)
        return Outputs(est.word, _along(est.capacity_N, d),
                       NAN if est.capacity_N is None else 0.0, _along(est.margin_N, d),
                       _along(est.capacity_lower_N, d),
                       self.config.lower_bound_level > 0.0 or bool(est.assumed)
                       or bool(est.modelled), twist)

    def diagnostic(self, est: Estimate, name: str, extra: Mapping[str, str] = {}) -> DiagStatus:
        """The /diagnostics entry of `est`: level from LEVELS by its word (WARN at least with
        warnings or an input not measured), message 'word: reason [warnings]', and the
        key/values (SI, the unit in the key; `provenance` names every input's provenance).
        `extra`: node-side values appended (timing, parameters)."""
        level = LEVELS.get(est.word, ERROR_LEVEL)
        if (est.warnings or est.assumed or est.modelled) and level == OK_LEVEL:
            level = WARN_LEVEL
        message = est.word
        if est.reason and est.reason != message:
            message += f': {est.reason}'
        if est.warnings:
            message += ' [' + ', '.join(est.warnings) + ']'
        st = est.state
        twist = ('nan' if est.slip_twist is None
                 else ' '.join(f'{x:.4g}' for x in est.slip_twist))
        values = {
            'status': est.word, 'detail': est.detail,
            'capacity_N': _fmt(est.capacity_N), 'capacity_lower_N': _fmt(est.capacity_lower_N),
            'tension_N': _fmt(est.tension_N),
            'margin_N': _fmt(est.margin_N), 'slipping': str(est.slipping).lower(),
            'phi_rad': _fmt(est.phi_rad),
            'h_m': _fmt(st.h if st else None), 'theta_b_rad': _fmt(st.theta_b if st else None),
            'theta_l1_rad': _fmt(st.theta_l1 if st else None),
            'theta_l2_rad': _fmt(st.theta_l2 if st else None),
            'leg_spread_rad': ('nan' if est.leg_spread_rad is None
                               else ' '.join(f'{x:.4g}' for x in est.leg_spread_rad)),
            'slip_twist': twist,
            'assumed_inputs': ','.join(est.assumed), 'modelled_inputs': ','.join(est.modelled),
            'provenance': ','.join(f'{n}:{p}' for n, p in est.provenance().items()),
            'stale_inputs': ','.join(est.stale),
            'reason': est.reason,
            'predictor': est.predictor, 'pull': str(self.pull),
            **extra,
        }
        return DiagStatus(name, level, message, values)

    # -- helpers ----------------------------------------------------------------------------
    def _value(self, name: str, fallback: float | None = None) -> float | None:
        s = self._inputs.get(name)
        return s.value if s is not None else fallback

    def _with_provenance(self, provenance: Provenance) -> tuple[str, ...]:
        """The inputs whose value in use has this provenance (an input never received is
        assumed: its parameter stands in; a modelled one without a band is assumed too: the
        range it may be off by is then the node's assumption, not the model's)."""
        out = []
        for name in ASSUMABLE:
            s = self._inputs.get(name)
            p = Provenance.ASSUMED if s is None else s.provenance
            if p is Provenance.MODELLED and math.isnan(s.band):
                p = Provenance.ASSUMED
            if p is provenance:
                out.append(name)
        return tuple(out)

    def _ranges(self) -> tuple[tuple[str, float], ...]:
        """(input, half-width) of every assumed or modelled input, in ASSUMABLE order: the
        sample's band when stated, else the configured assumed range."""
        cfg = self.config
        own = {'height': cfg.assumed_height_range_m, 'phi': cfg.assumed_phi_range_rad}
        out = []
        for name in ASSUMABLE:
            s = self._inputs.get(name)
            if s is not None and s.provenance is Provenance.MEASURED:
                continue
            band = s.band if s is not None and not math.isnan(s.band) else own[name]
            out.append((name, band))
        return tuple(out)

    def _samples(self):
        """(input name, sample time) of every received sample."""
        for k in JOINTS:
            if k in self._joints:
                yield 'joint_states', self._joints[k].t
        for name, s in self._inputs.items():
            yield name, s.t

    def _stale_inputs(self, now: float) -> list[Problem]:
        out = []
        timeouts = self.config.timeouts_s
        joints_t = [self._joints[k].t if k in self._joints else None for k in JOINTS]
        if any(t is None for t in joints_t):
            out.append(Problem('no_data', 'joint_states', 'joint_states: no data'))
        elif now - min(joints_t) > timeouts['joint_states']:
            out.append(Problem('stale_input', 'joint_states',
                               f'joint_states: {now - min(joints_t):.3f} s old'))
        for name in ('pitch', 'tension', 'height', 'phi'):
            s = self._inputs.get(name)
            if s is None:
                if name not in ASSUMABLE:
                    out.append(Problem('no_data', name, f'{name}: no data'))
            elif now - s.t > timeouts[name]:
                out.append(Problem('stale_input', name, f'{name}: {now - s.t:.3f} s old'))
        return out

    def _future_stamps(self, now: float) -> list[Problem]:
        tol = self.config.clock_tolerance_s
        ahead: dict[str, float] = {}
        for name, t in self._samples():
            if t - now > tol:
                ahead[name] = max(ahead.get(name, 0.0), t - now)
        return [Problem('future_stamp', n, f'{n}: stamped {dt:.3f} s in the future '
                        f'(tolerance {tol:g} s)') for n, dt in ahead.items()]

    def _legs(self):
        """((theta_l1, theta_l2) per-axle angles, (spread1, spread2), problems)."""
        v = {k: self._joints[k].value for k in JOINTS}
        bad = [k for k, x in v.items() if not math.isfinite(x)]
        if bad:
            return None, None, [Problem('not_finite', 'joint_states',
                                        f'joint angle not finite: {", ".join(bad)}')]
        lim = self.config.leg_limit_rad
        problems = [Problem('outside_limits', 'joint_states',
                            f'{k} = {x:.4g} rad outside [-{lim:.4g}, {lim:.4g}] (before '
                            'wrapping)')
                    for k, x in v.items() if abs(x) > lim]
        if problems:   # wrapped, such a value would look like a plausible angle
            return None, None, problems
        tol = self.config.leg_tolerance_rad
        axles = axle_angles(v, tol)
        spreads = dict(zip(('proximal', 'distal'), axles.spread_rad))
        for axle in axles.disagreeing:
            problems.append(Problem(
                'leg_disagreement', 'joint_states',
                f'{axle} legs {math.degrees(spreads[axle]):.1f} deg apart (tolerance '
                f'{math.degrees(tol):.1f} deg)'))
        return (axles.theta_l1, axles.theta_l2), axles.spread_rad, problems

    def _range_problems(self, h, pitch, phi, tension) -> list[Problem]:
        cfg = self.config
        out = []
        checks = [
            ('height', h, cfg.h_range_m[0], cfg.h_range_m[1], 'm'),
            ('pitch', pitch, -cfg.pitch_limit_rad, cfg.pitch_limit_rad, 'rad'),
            ('phi', phi, -cfg.phi_limit_rad, cfg.phi_limit_rad, 'rad'),
            ('tension', tension, -cfg.tension_deadband_N, cfg.tension_max_N, 'N'),
        ]
        for name, x, lo, hi, unit in checks:
            if name in self._malformed:
                continue  # already reported, its value is the last good one or NaN
            if x is None or not math.isfinite(x):
                out.append(Problem('not_finite', name, f'{name} not finite ({x!r})'))
            elif name == 'tension' and x < lo:
                out.append(Problem('negative_tension', name,
                                   f'tension = {x:.4g} N below -{cfg.tension_deadband_N:g} N '
                                   '(load cell axis reversed or a compressive reading)'))
            elif not lo <= x <= hi:
                out.append(Problem('outside_limits', name,
                                   f'{name} = {x:.4g} {unit} outside [{lo:.4g}, {hi:.4g}]'))
        return out

    def prefetch(self) -> bool:
        """One prediction toward the lower bound the next estimates are likely to need (the
        grid angles next to the last one's, lower_bound.py); False when none is due."""
        return self._bound.prefetch()

    def _predict(self, state: AnchorState, phi: float) -> CapacityResult:
        """The predictor's answer, remembered for the last ANSWERS (state, phi): an input
        that flickers between two rounded values costs no new solve."""
        key = (state.as_tuple(), phi)
        if key in self._answers:
            self._answers.move_to_end(key)
            return self._answers[key]
        result = self._answers[key] = self.predictor.predict(state, phi, self.pull)
        self.predictions += 1
        while len(self._answers) > self.ANSWERS:
            self._answers.popitem(last=False)
        return result


def _finite(*xs) -> bool:
    return all(x is not None and math.isfinite(x) for x in xs)

