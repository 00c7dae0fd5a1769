"""ROS-free core of capacity_node: timestamped inputs in, a status-carrying estimate out.

Inputs (SI, the conventions of docs/design/architecture.md#frames-and-signs):
  joints   leg angles, rad, from -z_B about the axles: proximal_left/right (theta_L1),
           distal_left/right (theta_L2). The two legs of one axle are averaged (the sagittal
           model shares one angle per axle); a spread beyond `leg_tolerance_rad` is reported.
  pitch    body pitch theta_B, rad, positive when the axle end of the body is above p.
  tension  winch tension T >= 0, N, along the tether.
  height   h, m, height of the winch point p above the sand surface (optional topic; the
           `height_m` fallback is used until the first sample arrives).
  phi      tether angle, rad: tension along (-cos phi, 0, sin phi) in world axes
           (optional topic; `phi_rad` fallback until the first sample arrives).
Times are seconds on one clock (the node uses its clock at message receipt).

Status precedence: stale (any required input older than its timeout or never received)
> invalid_input (NaN / out of range / malformed) > the predictor's status. A value (capacity,
margin, slip twist) is present only when the status is ok or extrapolated.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Mapping

from rftgls_core.surfaces.base import CapacityResult
from rftgls_core.types import AnchorState, Pull, Status
from rftgls_core.uncertainty import capacity_lower_bound

from .predictor import ConfigError, Predictor

JOINTS = ('proximal_left', 'proximal_right', 'distal_left', 'distal_right')
# Input names, as used for timeouts and in stale/invalid reasons.
INPUTS = ('joint_states', 'pitch', 'tension', 'height', 'phi')
DEFAULT_TIMEOUTS_S = {'joint_states': 0.25, 'pitch': 0.25, 'tension': 0.25, 'height': 1.0,
                      'phi': 1.0}


@dataclass(frozen=True)
class EstimatorConfig:
    """Tunables of the estimator (units in the names). Validated by `check()`."""

    pull: str = 'backward'
    timeouts_s: Mapping[str, float] = field(default_factory=lambda: dict(DEFAULT_TIMEOUTS_S))
    leg_tolerance_rad: float = math.radians(5.0)
    height_m: float = 0.03            # fallback h until a height sample arrives
    phi_rad: float = math.radians(-20.0)  # fallback phi until a phi sample arrives
    h_range_m: tuple[float, float] = (-0.05, 0.30)
    pitch_limit_rad: float = math.pi / 2
    leg_limit_rad: float = math.pi
    phi_limit_rad: float = math.pi / 2
    tension_max_N: float = 200.0
    tension_deadband_N: float = 0.05  # a load cell reads slightly below 0 at zero load
    # Conservative lower bound (capacity/lower_bound.py); level 0 switches it off.
    lower_bound_level: float = 0.0
    h_sigma_m: float = 0.002
    theta_b_sigma_rad: float = math.radians(1.0)
    capacity_rel_sigma: float = 0.0

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
        if not (math.isfinite(self.tension_deadband_N) and self.tension_deadband_N >= 0):
            raise ConfigError(f'tension_deadband_N must be >= 0, got {self.tension_deadband_N!r}')
        if not (self.lower_bound_level == 0.0 or 0.5 <= self.lower_bound_level < 1.0):
            raise ConfigError(f'lower_bound_level must be 0 (off) or in [0.5, 1), got '
                              f'{self.lower_bound_level!r}')
        for name in ('h_sigma_m', 'theta_b_sigma_rad', 'capacity_rel_sigma'):
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
    t: float      # s, receipt time on the estimator's clock
    value: float  # SI


@dataclass(frozen=True)
class Estimate:
    """One prediction. capacity_N, margin_N and slip_twist are None unless `has_value`,
    except `unsupported`, which reports capacity_N = 0 and margin_N = -tension_N.

    capacity_N: load capacity along the tether direction d(phi), N.
    capacity_lower_N: its one-sided lower confidence bound (config.lower_bound_level), N;
        None when switched off or without a value.
    margin_N: capacity_N - tension_N, N (negative: the anchor is predicted to slip).
    slip_twist: unit direction (vx, vz, wy) of the predicted slip at p in world axes
        (m/s, m/s, rad/s per unit; RFT is rate independent so only the direction is known);
        given whenever there is a value, `slipping` says whether the tension exceeds capacity.
    state, phi_rad, tension_N: the inputs used (None when missing or not finite).
    warnings: non-fatal findings, e.g. 'leg_disagreement'.
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
    warnings: tuple[str, ...] = ()
    predictor: str = ''
    result: CapacityResult | None = None

    @property
    def has_value(self) -> bool:
        return self.status.has_value


class CapacityEstimator:
    """Keeps the latest sample of every input and turns them into an Estimate on demand.

    The last prediction is cached by (state, phi): a new tension alone does not re-query the
    predictor (capacity does not depend on T; only the margin does), which keeps the live
    predictor usable at sensor rates.
    """

    def __init__(self, predictor: Predictor, config: EstimatorConfig | None = None):
        self.predictor = predictor
        self.config = (config or EstimatorConfig()).check()
        self.pull = Pull(self.config.pull)
        self._joints: dict[str, Sample] = {}
        self._inputs: dict[str, Sample] = {}
        self._malformed: dict[str, tuple[float, str]] = {}  # input -> (t, why)
        self._cache_key: tuple | None = None
        self._cache: CapacityResult | None = None
        self._lower_cache: tuple | None = None
        self.predictions = 0  # predictor calls (cache misses), for diagnostics and tests

    # -- inputs -----------------------------------------------------------------------------
    def update_joints(self, t: float, angles: Mapping[str, float]) -> None:
        """Leg angles (rad) for any subset of JOINTS; other joints keep their last sample."""
        for key, value in angles.items():
            if key not in JOINTS:
                raise KeyError(f'unknown joint key {key!r}; expected one of {JOINTS}')
            self._joints[key] = Sample(t, float(value))
        self._malformed.pop('joint_states', None)

    def update(self, name: str, t: float, value: float) -> None:
        """A scalar input: 'pitch' (rad), 'tension' (N), 'height' (m) or 'phi' (rad)."""
        if name not in INPUTS or name == 'joint_states':
            raise KeyError(f'unknown scalar input {name!r}')
        self._inputs[name] = Sample(t, float(value))
        self._malformed.pop(name, None)

    def mark_malformed(self, name: str, t: float, why: str) -> None:
        """Record that the latest message of an input could not be parsed (-> invalid_input
        until a good message of that input arrives)."""
        self._malformed[name] = (t, why)

    # -- output -----------------------------------------------------------------------------
    def estimate(self, now: float) -> Estimate:
        cfg = self.config
        stale = self._stale_inputs(now)
        tension = self._value('tension')
        phi = self._value('phi', cfg.phi_rad)
        if stale:
            return Estimate(now, Status.STALE, 'stale_input', 'stale or missing: '
                            + ', '.join(stale), tension_N=tension, phi_rad=phi,
                            predictor=self.predictor.name)
        legs, spread, problems = self._legs()
        pitch = self._value('pitch')
        h = self._value('height', cfg.height_m)
        problems += [f'{n}: {why}' for n, (_, why) in self._malformed.items()]
        problems += self._range_problems(h, pitch, phi, tension)
        warnings = ()
        if spread is not None and max(spread) > cfg.leg_tolerance_rad:
            warnings = ('leg_disagreement',)
        state = None
        if legs is not None and _finite(h, pitch):
            state = AnchorState(h, pitch, legs[0], legs[1])
        common = dict(tension_N=tension if _finite(tension) else None,
                      phi_rad=phi if _finite(phi) else None, state=state,
                      leg_spread_rad=spread, warnings=warnings, predictor=self.predictor.name)
        if problems:
            return Estimate(now, Status.INVALID_INPUT, 'invalid_input', '; '.join(problems),
                            **common)
        result = self._predict(state, phi)
        if result.status is Status.UNSUPPORTED:
            # No quasi-static balance: the anchor holds nothing. Zero is the safe number here,
            # so it is reported (the slip direction is unknown and stays None).
            t_pos = max(tension, 0.0)
            return Estimate(now, Status.UNSUPPORTED, result.reason or 'unsupported',
                            result.detail, capacity_N=0.0, margin_N=-t_pos, slipping=t_pos > 0,
                            result=result, **{**common, 'tension_N': t_pos})
        if not result.status.has_value or result.capacity_N is None:
            status = result.status if not result.status.has_value else Status.DEGENERATE
            return Estimate(now, status, result.reason or str(status), result.detail,
                            result=result, **common)
        tension = max(tension, 0.0)  # inside the dead band
        margin = result.capacity_N - tension
        lower = self._lower_bound(state, phi, result.capacity_N)
        return Estimate(now, result.status, result.reason, result.detail,
                        capacity_N=result.capacity_N, capacity_lower_N=lower, margin_N=margin,
                        slip_twist=result.slip_twist, slipping=margin < 0.0, result=result,
                        **{**common, 'tension_N': tension})

    # -- helpers ----------------------------------------------------------------------------
    def _value(self, name: str, fallback: float | None = None) -> float | None:
        s = self._inputs.get(name)
        return s.value if s is not None else fallback

    def _stale_inputs(self, now: float) -> list[str]:
        out = []
        timeouts = self.config.timeouts_s
        joints_t = [self._joints[k].t if k in self._joints else None for k in JOINTS]
        if any(t is None for t in joints_t):
            out.append('joint_states (no data)')
        elif now - min(joints_t) > timeouts['joint_states']:
            out.append(f'joint_states ({now - min(joints_t):.3f} s old)')
        for name in ('pitch', 'tension', 'height', 'phi'):
            s = self._inputs.get(name)
            if s is None:
                if name in ('pitch', 'tension'):  # height and phi fall back to parameters
                    out.append(f'{name} (no data)')
            elif now - s.t > timeouts[name]:
                out.append(f'{name} ({now - s.t:.3f} s old)')
        return out

    def _legs(self):
        """((theta_l1, theta_l2) axle means, (spread1, spread2), problems)."""
        v = {k: self._joints[k].value for k in JOINTS}
        bad = [k for k, x in v.items() if not math.isfinite(x)]
        if bad:
            return None, None, [f'joint angle not finite: {", ".join(bad)}']
        lim = self.config.leg_limit_rad
        problems = [f'{k} = {x:.4g} rad outside [-{lim:.4g}, {lim:.4g}]'
                    for k, x in v.items() if abs(x) > lim]
        l1 = 0.5 * (v['proximal_left'] + v['proximal_right'])
        l2 = 0.5 * (v['distal_left'] + v['distal_right'])
        spread = (abs(v['proximal_left'] - v['proximal_right']),
                  abs(v['distal_left'] - v['distal_right']))
        return (l1, l2), spread, problems

    def _range_problems(self, h, pitch, phi, tension) -> list[str]:
        cfg = self.config
        out = []
        checks = [
            ('height', h, cfg.h_range_m[0], cfg.h_range_m[1], 'm'),
            ('pitch', pitch, -cfg.pitch_limit_rad, cfg.pitch_limit_rad, 'rad'),
            ('phi', phi, -cfg.phi_limit_rad, cfg.phi_limit_rad, 'rad'),
            ('tension', tension, -cfg.tension_deadband_N, cfg.tension_max_N, 'N'),
        ]
        for name, x, lo, hi, unit in checks:
            if x is None or not math.isfinite(x):
                out.append(f'{name} not finite ({x!r})')
            elif not lo <= x <= hi:
                out.append(f'{name} = {x:.4g} {unit} outside [{lo:.4g}, {hi:.4g}]')
        return out

    def _lower_bound(self, state: AnchorState, phi: float, capacity_N: float) -> float | None:
        """Lower confidence bound, cached with the prediction it belongs to."""
        cfg = self.config
        if cfg.lower_bound_level <= 0.0:
            return None
        key = (state.as_tuple(), phi)
        if self._lower_cache is None or self._lower_cache[0] != key:
            lower = capacity_lower_bound(
                lambda st, ph: self.predictor.predict(st, ph, self.pull), state, phi,
                capacity_N, cfg.lower_bound_level, cfg.h_sigma_m, cfg.theta_b_sigma_rad,
                cfg.capacity_rel_sigma)
            self._lower_cache = (key, lower)
        return self._lower_cache[1]

    def _predict(self, state: AnchorState, phi: float) -> CapacityResult:
        key = (state.as_tuple(), phi)
        if key != self._cache_key:
            self._cache = self.predictor.predict(state, phi, self.pull)
            self._cache_key = key
            self.predictions += 1
        return self._cache


def _finite(*xs) -> bool:
    return all(x is not None and math.isfinite(x) for x in xs)


def pitch_from_quaternion(x: float, y: float, z: float, w: float) -> float:
    """theta_B (rad) from a body orientation quaternion in a z-up world (REP-103 base frame:
    x forward from p toward the axles, y left, z up).

    theta_B is the elevation of the body x axis above the horizontal. The body x axis in the
    world is R e_x, whose z component is 2 (x z - w y); so theta_B = asin(2 (x z - w y)).
    For a pure REP-103 pitch beta (rotation about +y, positive turns the nose DOWN) this gives
    theta_B = -beta: the sign flip between REP-103 pitch and the anchor state's theta_B.
    Roll and yaw do not change it. The quaternion is normalised first; raises ValueError if it
    is not finite or has (near) zero norm.
    """
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or n < 1e-6:
        raise ValueError(f'orientation quaternion is not usable (norm {n!r})')
    x, y, z, w = x / n, y / n, z / n, w / n
    return math.asin(max(-1.0, min(1.0, 2.0 * (x * z - w * y))))
