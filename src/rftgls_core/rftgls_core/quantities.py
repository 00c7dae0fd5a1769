"""The physical range of every quantity a person types: one place per quantity.

A value outside its range is a typo, a unit slip (mm for m, rad for deg) or an attack, never
an input: the command lines refuse it in one line (exit 2) before anything is computed, and
no value is wrapped, clipped or normalised first (a 1e308 deg angle wrapped into [-180, 180)
would look like any other angle). The reasoning behind each range is in
docs/design/safe-io.md, "Ranges"; the ranges are wide (a factor of several beyond anything
the robots, the media or the lab produce) because their job is to catch the absurd, not to
second-guess the plausible. A robot's or description's own pose limits (robots.model.StateRange,
the description's `physical:` ranges) apply after these.

Edge units are the ones the options take: degrees, metres (h in mm only where the option says
so), kg, N/m^3.
"""
from __future__ import annotations

import argparse
import math
from dataclasses import dataclass


@dataclass(frozen=True)
class Quantity:
    """A quantity with its physical range [lo, hi] in `unit` (inclusive); allow_inf accepts
    +inf as well (a fully rough surface friction)."""

    name: str
    unit: str
    lo: float
    hi: float
    allow_inf: bool = False

    def violation(self, value: float) -> str | None:
        """Why `value` is not this quantity (one line), or None when it is."""
        try:
            v = float(value)
        except (TypeError, ValueError):
            return f'{self.name} must be a number, got {value!r}'
        if self.allow_inf and v == math.inf:
            return None
        if not math.isfinite(v):
            return f'{self.name} must be finite, got {value!r}'
        if not self.lo <= v <= self.hi:
            unit = f' {self.unit}' if self.unit else ''
            return (f'{self.name} must be in {self.lo:g}..{self.hi:g}{unit}'
                    + (' (or inf)' if self.allow_inf else '') + f', got {v:g}')
        return None

    def check(self, value: float, label: str = '') -> float:
        """value as a float, or ValueError (one line, prefixed with label) outside the range."""
        problem = self.violation(value)
        if problem:
            raise ValueError(f'{label}: {problem}' if label else problem)
        return float(value)

    def arg(self, text: str) -> float:
        """An argparse `type`: the text as a number in range (ArgumentTypeError otherwise)."""
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'not a number: {text!r}') from None
        problem = self.violation(value)
        if problem:
            raise argparse.ArgumentTypeError(problem)
        return value


# ------------------------------------------------------------------------------ geometry
# Any orientation is one value within a turn either way; more is a slip of units or a typo.
ANGLE_DEG = Quantity('angle', 'deg', -360.0, 360.0)
# The tether leaves the winch point above the sand: from straight down to straight up.
TETHER_PHI_DEG = Quantity('tether angle phi', 'deg', -90.0, 90.0)
# A yawed pull turns the tether about z: half a turn either way covers every direction.
TETHER_YAW_DEG = Quantity('tether yaw', 'deg', -180.0, 180.0)
# Positions of bodies, tether points, centres of mass in the world (free surface z = 0): a
# lab tank or a beach is metres across; RFT bodies are centimetres.
POSITION_M = Quantity('position', 'm', -10.0, 10.0)
POSITION_MM = Quantity('position', 'mm', -10_000.0, 10_000.0)
MASS_KG = Quantity('mass', 'kg', 0.0, 100.0)
# |scale| of a URDF mesh: mm -> m is 1e-3; beyond 1e-6..1e3 a body leaves the lab's size range.
MESH_SCALE = Quantity('mesh scale magnitude', '', 1e-6, 1e3)

# ------------------------------------------------------------------------------ motion
# RFT is quasi-static: it holds below a Froude number of ~1, sqrt(g d) ~ 1 m/s for a body
# 0.1 m deep. Rotations: 1 m/s at 1 cm from the axis.
LINEAR_SPEED_M_S = Quantity('linear velocity', 'm/s', -1.0, 1.0)
ANGULAR_SPEED_RAD_S = Quantity('angular velocity', 'rad/s', -100.0, 100.0)
PULL_SPEED_M_S = Quantity('pull speed', 'm/s', 1e-6, 1.0)
SLIP_STEP_M = Quantity('slip step', 'm', 1e-6, 0.05)
SLIP_TRAVEL_M = Quantity('slip travel', 'm', 1e-4, 1.0)
# A servo's leg speed: the XL330 turns at most 40 rad/s (2300 deg/s) unloaded; 100 rad/s is
# ANGULAR_SPEED's bound. Gait clocks run from a fraction of a second (a pronk) to a minute.
LEG_SPEED_DEG_S = Quantity('leg speed', 'deg/s', 0.01, 5730.0)
GAIT_PERIOD_S = Quantity('gait period', 's', 0.01, 60.0)
GAIT_DUTY = Quantity('duty', '', 0.0, 1.0)
# Simulated gaits: the paper's phases last 8 s; ten minutes of steps is hours of computing.
SIM_DURATION_S = Quantity('simulated duration', 's', 1e-3, 600.0)
SIM_STEP_S = Quantity('time step', 's', 1e-5, 1.0)
# Hobby servos stall at 0.1..10 N m; the XL330-M077 at 0.215 N m (5 V).
STALL_TORQUE_NM = Quantity('stall torque', 'N m', 1e-4, 100.0)

# ------------------------------------------------------------------------------ media
# xi_n = rho_c g (894 mu^3 - 386 mu^2 + 89 mu): rho_c 500..3000 kg/m^3 and mu_int 0.1..1.0
# give 2.9e4..1.8e7 N/m^3 on Earth (4.8e3 at lunar gravity); zeta ~ 0.875 xi_n.
XI_N = Quantity('xi_n', 'N/m^3', 1e3, 1e8)
ZETA = Quantity('zeta', 'N/m^3', 1e3, 1e8)
# Friction coefficients of real surfaces are 0.1..1; inf is the explicit fully rough surface.
MU_SURF = Quantity('mu_surf', '', 0.0, 10.0, allow_inf=True)
SLED_FRICTION = Quantity('sled friction', '', 0.0, 2.0)
RELATIVE_SIGMA = Quantity('relative sigma', '', 0.0, 1.0)
FRICTION_SIGMA = Quantity('friction sigma', '', 0.0, 1.0)

# ------------------------------------------------------------------------------ lab
PLATE_AREA_M2 = Quantity('plate area', 'm^2', 1e-6, 1.0)
FORCE_SIGMA_N = Quantity('force sigma', 'N', 1e-6, 100.0)
FRAME_RATE_HZ = Quantity('frame rate', 'Hz', 0.1, 10_000.0)
REPLAY_RATE = Quantity('replay rate', '', 0.0, 1000.0)
WAIT_S = Quantity('wait', 's', 0.0, 60.0)
RUN_TIMEOUT_S = Quantity('timeout', 's', 1.0, 3600.0)
IMAGE_NOISE = Quantity('image noise', 'grey levels', 0.0, 255.0)
IMAGE_BLUR_PX = Quantity('image blur', 'px', 0.0, 20.0)
PERCENT = Quantity('tolerance', '%', 0.0, 100.0)

# ------------------------------------------------------------------------------ planning
# The pull a burrowed anchor must hold: MiniRQuad's sleds need 2-3 N; 1 kN would tow a car.
NEED_FORCE_N = Quantity('needed force', 'N', 0.0, 1000.0)
# A one-sided confidence: below one half a lower bound would sit above the estimate; 1 is an
# infinite bound.
CONFIDENCE = Quantity('confidence', '', 0.5, 0.999999)


def bounded_int(lo: int, hi: int, what: str = 'value'):
    """An argparse `type`: an integer in [lo, hi] (a one-line message otherwise)."""
    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f'not an integer: {text!r}') from None
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f'{what} must be in {lo}..{hi}, got {value}')
        return value
    return parse


SEED = bounded_int(0, 2**32 - 1, 'seed')
WORKERS = bounded_int(1, 256, 'worker count')
