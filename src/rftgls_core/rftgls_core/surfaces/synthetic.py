"""Analytic limit surfaces with exact capacities and twists (tests and benchmarks, no RFT).

Convex case (docs/design/limit-surfaces.md): the dissipation D(t) = ||A t||_p gives
W(t) = grad D(t) = A g(A t), g(u) = sign(u) |u|^(p-1) / ||u||_p^(p-1), so every wrench lies on
the dual-norm ball ||(W - c)/A||_q = 1 (1/p + 1/q = 1), shifted by the offset c (gravity).
Along d(phi) the exact capacity is the root of ||(s d - c)/A||_q = 1 (brentq) and the exact
twist is t ∝ A^-1 grad||y||_q at y = (s d - c)/A. These formulas are independent of every
surface representation, so they are the references of the tests.

Variants:
- dented: the convex wrenches scaled radially about the origin by f(twist) < 1 near one
  twist. Radial scaling keeps directions, so capacity = f(t*) * convex capacity exactly, and
  the twist paired with that point is the convex twist t*.
- folded: the convex wrenches rotated in the (Fx, Fz) plane by an angle that bumps with the
  polar angle; the image overhangs, so some rays cross it three times.
- pinched: the support function of hull(convex ball, tip point): a whole open cone of twists
  maps to the tip (many twists -> one wrench, like a thin plate sliding in its own plane).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.optimize import brentq, minimize

from ..types import pull_direction
from .base import GLSProblem
from .scaling import Scaling


@dataclass(frozen=True)
class PNormGLS:
    """Convex analytic GLS. A: axis sizes (N, N, N m); p: primal norm; offset: centre c (raw)."""

    A: tuple[float, float, float] = (3.0, 5.0, 0.05)
    p: float = 1.6
    offset: tuple[float, float, float] = (0.3, 1.0, 0.01)

    @property
    def q(self) -> float:
        return self.p / (self.p - 1.0)

    def wrench(self, twists: np.ndarray) -> np.ndarray:
        t = np.atleast_2d(np.asarray(twists, dtype=float))
        a = np.asarray(self.A)
        u = a * t
        nrm = np.sum(np.abs(u) ** self.p, axis=1) ** (1.0 / self.p)
        g = np.sign(u) * np.abs(u) ** (self.p - 1.0) / nrm[:, None] ** (self.p - 1.0)
        return a * g + np.asarray(self.offset)

    def support(self, twists: np.ndarray) -> np.ndarray:
        """h(t) = max_W t.W = ||A t||_p + t.c (for unit-free twist directions)."""
        t = np.atleast_2d(np.asarray(twists, dtype=float))
        u = np.asarray(self.A) * t
        return np.sum(np.abs(u) ** self.p, axis=1) ** (1.0 / self.p) + t @ np.asarray(self.offset)

    def gauge(self, w: np.ndarray) -> np.ndarray:
        y = (np.atleast_2d(w) - np.asarray(self.offset)) / np.asarray(self.A)
        return np.sum(np.abs(y) ** self.q, axis=1) ** (1.0 / self.q)

    def origin_inside(self) -> bool:
        return bool(self.gauge(np.zeros(3))[0] < 1.0)

    def exact_capacity(self, phi: float) -> float:
        """First (only) exit along d(phi), N; 0.0 when the origin is outside."""
        d = np.asarray(pull_direction(phi))
        f = lambda s: float(self.gauge(s * d)[0]) - 1.0  # noqa: E731
        if f(0.0) >= 0.0:
            return 0.0
        hi = 1.0
        while f(hi) < 0.0:
            hi *= 2.0
        return brentq(f, 0.0, hi, xtol=1e-15, rtol=1e-15, maxiter=500)

    def exact_twist_raw(self, phi: float) -> np.ndarray:
        """Twist (raw, unit Euclidean) paired with the exit point: A^-1 grad ||y||_q."""
        w = self.exact_capacity(phi) * np.asarray(pull_direction(phi))
        y = (w - np.asarray(self.offset)) / np.asarray(self.A)
        grad = np.sign(y) * np.abs(y) ** (self.q - 1.0)
        t = grad / np.asarray(self.A)
        return t / np.linalg.norm(t)


def _unit(x: np.ndarray) -> np.ndarray:
    return x / np.linalg.norm(x, axis=-1, keepdims=True)


@dataclass(frozen=True)
class SyntheticCase:
    """A GLSProblem plus its exact answers. exact_capacity(phi) in N (0 if unsupported)."""

    name: str
    problem: GLSProblem
    exact_capacity: Callable[[float], float]
    exact_twist_raw: Callable[[float], np.ndarray]
    notes: str = ''
    extra: dict = field(default_factory=dict)

    def exact_twist_scaled(self, phi: float) -> np.ndarray:
        return self.problem.scaling.twist_to_scaled(self.exact_twist_raw(phi))


DEFAULT_SCALING = Scaling(force_N=5.0, length_m=0.01)   # My half-range 0.05 N m -> 1


def convex_case(p: float = 1.6, A=(3.0, 5.0, 0.05), offset=(0.3, 1.0, 0.01),
                scaling: Scaling = DEFAULT_SCALING) -> SyntheticCase:
    g = PNormGLS(tuple(A), p, tuple(offset))
    return SyntheticCase('convex', GLSProblem(g.wrench, scaling), g.exact_capacity,
                         g.exact_twist_raw, notes='dual q-norm ball, brentq reference',
                         extra={'gls': g})


def dented_case(depth: float = 0.35, phi0: float = 0.3, width_rad: float = 0.35,
                scaling: Scaling = DEFAULT_SCALING) -> SyntheticCase:
    """The convex map dented radially about the origin: W(t) = f(t) W_convex(t).

    f(t) = 1 - depth exp(-angle(ts, ts0)^2 / (2 width^2)) in the scaled twist metric, centred
    on the exact twist ts0 of the convex case at phi0 (tug region). Scaling each wrench along
    its own direction keeps the surface star-shaped about the origin and keeps the pairing of
    directions, so along d(phi) the exit point is f(t*) s*(phi) d with t*, s* the exact convex
    twist and capacity: an analytic reference, and the paired twist is still t*.
    """
    g = PNormGLS()
    ts0 = scaling.twist_to_scaled(g.exact_twist_raw(phi0))

    def factor(t: np.ndarray) -> np.ndarray:
        cosang = np.clip(scaling.twist_to_scaled(np.atleast_2d(t)) @ ts0, -1.0, 1.0)
        return 1.0 - depth * np.exp(-0.5 * (np.arccos(cosang) / width_rad) ** 2)

    def wrench(t):
        return g.wrench(t) * factor(t)[:, None]

    def cap(phi):
        return g.exact_capacity(phi) * float(factor(g.exact_twist_raw(phi))[0])

    return SyntheticCase('dented', GLSProblem(wrench, scaling), cap, g.exact_twist_raw,
                         notes='radial dent: capacity = dent factor x exact convex capacity',
                         extra={'gls': g, 'factor': factor})


def folded_case(psi0: float = np.pi - 0.3, amp: float = 1.0, width: float = 0.3,
                scaling: Scaling = DEFAULT_SCALING) -> SyntheticCase:
    """Overhanging surface: polar angle psi -> psi + amp exp(-((psi-psi0)/width)^2) in (Fx, Fz).

    amp / width > 1.17 makes psi' non-monotone, so the image folds over itself near psi0, and
    the radius changes across the bump so the overlapping sheets sit at different distances.
    With the defaults, rays with phi in about [-0.63, -0.3] cross the surface three times.
    """
    g = PNormGLS()

    def wrench(t):
        w = g.wrench(t)
        psi = np.arctan2(w[:, 1], w[:, 0])
        dpsi = np.angle(np.exp(1j * (psi - psi0)))
        bump = np.exp(-(dpsi / width) ** 2)
        r = np.hypot(w[:, 0], w[:, 1]) * (1.0 + 0.3 * (dpsi / width) * bump)
        psi2 = psi + amp * bump
        return np.column_stack([r * np.cos(psi2), r * np.sin(psi2), w[:, 2]])

    nan = lambda phi: float('nan')  # noqa: E731  (no closed form needed: only statuses tested)
    return SyntheticCase('folded', GLSProblem(wrench, scaling), nan,
                         lambda phi: np.full(3, np.nan), notes='fold: statuses only')


def pinched_case(tip=(-4.0, 2.0, 0.0), scaling: Scaling = DEFAULT_SCALING) -> SyntheticCase:
    """Hull of the convex ball and a tip point: an open cone of twists maps to the tip.

    The exact capacity is min over twists with t.d > 0 of h(t) / (t.d), h the support function
    of the hull = max(ball support, t.tip): a dense sample then a Nelder-Mead polish.
    """
    g = PNormGLS()
    tip = np.asarray(tip, dtype=float)

    def wrench(t):
        t = np.atleast_2d(np.asarray(t, dtype=float))
        w = g.wrench(t)
        at_tip = t @ tip > g.support(t)
        w[at_tip] = tip
        return w

    def support(t):
        return np.maximum(g.support(t), np.atleast_2d(t) @ tip)

    from .sampling import fibonacci_sphere
    dense = fibonacci_sphere(100_000)

    def cap(phi):
        d = np.asarray(pull_direction(phi))
        td = dense @ d
        m = td > 1e-9
        vals = support(dense[m]) / td[m]
        t0 = dense[m][np.argmin(vals)]

        def obj(x):
            t = np.array([np.cos(x[1]) * np.cos(x[0]), np.cos(x[1]) * np.sin(x[0]), np.sin(x[1])])
            den = t @ d
            return float(support(t)[0] / den) if den > 1e-12 else 1e9

        x0 = [np.arctan2(t0[1], t0[0]), np.arcsin(np.clip(t0[2], -1, 1))]
        res = minimize(obj, x0, method='Nelder-Mead',
                       options={'xatol': 1e-12, 'fatol': 1e-14, 'maxiter': 4000})
        return float(min(res.fun, vals.min()))

    return SyntheticCase('pinched', GLSProblem(wrench, scaling), cap,
                         lambda phi: np.full(3, np.nan),
                         notes='support-function reference (dense + Nelder-Mead)',
                         extra={'gls': g, 'tip': tip})
