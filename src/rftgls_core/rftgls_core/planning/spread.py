"""The uncertain inputs of a burrow prediction and the simulations that carry them.

A predicted burrowed pose is uncertain because its inputs are: the medium's (xi_n, mu_surf)
(the calibrated covariance of a `rftgls calibrate` medium file, else assumed sigmas:
rft.media.medium_covariance) and the servo's stall torque (the XL330's datasheet gives a
typical value, no tolerance; STALL_REL_SIGMA is assumed). The planner propagates them by
**one-sigma runs** (a deterministic bound, not sampling; docs/design/burrow-planner.md says
why): the nominal run, then for each principal axis of the medium covariance and for the
stall torque a run at +1 sigma and one at -1 sigma. Each run is the whole burrow simulation
followed by the capacity at the pose that run ends in, with that run's medium: a stronger
sand both burrows the legs differently and holds them harder, and the two effects are
carried together.

The stall-torque pair is simulated only when it can change the run: a servo changes nothing
while every torque it gave stays under the weaker servo's torque-speed line at the speed it
turned and no leg stalled (`servo_line_binds`); then both runs are the nominal one, exactly.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..multibody.servo import ServoSpec
from ..rft.media import Medium

# The XL330-M077-T's stall torque from servo to servo (and with temperature): the e-manual
# gives 0.215 N m at 5 V and no spread; 10 % at one sigma is assumed.
STALL_REL_SIGMA = 0.10


@dataclass(frozen=True)
class Spread:
    """cov: (xi_n, mu_surf) covariance, (N/m^3)^2 etc.; cov_source: 'calibrated' or 'assumed';
    stall_rel_sigma: relative one-sigma of the servo stall torque (assumed)."""

    cov: tuple[tuple[float, float], tuple[float, float]]
    cov_source: str
    stall_rel_sigma: float = STALL_REL_SIGMA

    def __post_init__(self) -> None:
        c = np.asarray(self.cov, dtype=float)
        if c.shape != (2, 2) or not np.all(np.isfinite(c)):
            raise ValueError('the medium covariance must be a finite 2 x 2 matrix')
        if not np.allclose(c, c.T, rtol=1e-9, atol=0.0) or np.linalg.eigvalsh(c).min() < \
                -1e-12 * max(1.0, abs(c).max()):
            raise ValueError('the medium covariance must be symmetric positive semi-definite')
        if not (math.isfinite(self.stall_rel_sigma) and 0.0 <= self.stall_rel_sigma < 1.0):
            raise ValueError(f'stall torque sigma must be in [0, 1), got {self.stall_rel_sigma}')

    @classmethod
    def of(cls, cov, cov_source: str, stall_rel_sigma: float = STALL_REL_SIGMA) -> Spread:
        """A Spread from a 2 x 2 array-like covariance."""
        c = np.asarray(cov, dtype=float)
        if c.shape != (2, 2):
            raise ValueError('the medium covariance must be a finite 2 x 2 matrix')
        return cls(((float(c[0, 0]), float(c[0, 1])), (float(c[1, 0]), float(c[1, 1]))),
                   cov_source, stall_rel_sigma)

    def medium_axes(self) -> list[np.ndarray]:
        """One-sigma steps along the covariance's principal axes (xi_n, mu_surf), largest
        first; axes with zero variance are left out."""
        w, v = np.linalg.eigh(np.asarray(self.cov, dtype=float))
        out = []
        for k in np.argsort(w)[::-1]:
            if w[k] > 0.0:
                step = math.sqrt(w[k]) * v[:, k]
                out.append(step if step[0] >= 0.0 else -step)
        return out

    def describe(self) -> dict:
        return {'medium_covariance': [list(map(float, r)) for r in self.cov],
                'medium_covariance_source': self.cov_source,
                'stall_torque_rel_sigma': self.stall_rel_sigma,
                'stall_torque_rel_sigma_source': 'assumed (no tolerance published)',
                'propagation': 'one-sigma runs along each input (nominal, then +/- pairs)'}


@dataclass(frozen=True)
class Run:
    """One simulation of the spread: label, the medium and servo it runs with, and which
    input pair it belongs to (-1 for the nominal run)."""

    label: str
    medium: Medium
    servo: ServoSpec
    pair: int = -1
    servo_pair: bool = False


def runs(spread: Spread, medium: Medium, servo: ServoSpec) -> list[Run]:
    """The nominal run, then a (+, -) run per medium axis and for the stall torque."""
    from dataclasses import replace
    out = [Run('nominal', medium, servo)]
    pair = 0
    for k, step in enumerate(spread.medium_axes()):
        for sign, tag in ((1.0, '+'), (-1.0, '-')):
            xi = medium.xi_n + sign * step[0]
            mu = medium.mu_surf + sign * step[1]
            if not (xi > 0.0 and mu >= 0.0):
                raise ValueError(f'the medium at one sigma along axis {k} is not a medium '
                                 f'(xi_n {xi:.4g} N/m^3, mu_surf {mu:.4g}): the covariance is '
                                 'too wide for a linear bound')
            m = replace(medium, name=f'{medium.name} medium axis {k} {tag}1 sigma', xi_n=xi,
                        mu_surf=mu, zeta=medium.zeta * xi / medium.xi_n)
            out.append(Run(f'medium axis {k} {tag}1 sigma', m, servo, pair))
        pair += 1
    if spread.stall_rel_sigma > 0.0:
        for sign, tag in ((1.0, '+'), (-1.0, '-')):
            out.append(Run(f'stall torque {tag}1 sigma', medium,
                           servo.scaled(1.0 + sign * spread.stall_rel_sigma), pair, True))
    return out


def servo_line_binds(samples, servo: ServoSpec) -> bool:
    """True when a servo `servo` (the weaker one of the spread) could have changed the run:
    a leg stalled, or a torque the servos gave while driving their leg exceeds that servo's
    torque-speed line at the speed the leg turned."""
    for s in samples:
        if np.any(s.stalled):
            return True
        for tau, w in zip(s.torques, s.rates):
            if tau * w > 0.0 and abs(tau) > servo.torque_limit(w):
                return True
    return False
