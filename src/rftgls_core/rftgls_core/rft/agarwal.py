"""Agarwal, Goldman and Kamrin 3D-RFT (PNAS 2023), frame-free form.

Stress per unit depth on a leading facet (docs/design/models-rft.md):

    alpha_gen = f1 n_d + f2 v - f3 z,   f_j = sum_k c_jk T_k(x1, x2, x3)
    x1 = -v.z (sin gamma),  x2 = -n_d.z (cos beta),  x3 = n_d.v
    alpha = xi_n [alpha_n + min(1, mu_surf |alpha_n| / |alpha_t|) alpha_t]

n_d is the downward-facing normal of the facet's plane; the basis T_k is the 20-term cubic of
4.4 with c3,16 = -0.02730 (the value that resists extraction; 4.4 explains the choice).
Exactly vertical facets (|n_z| <= 1e-9) take n_d = -n like the public codes (4.2 / 7).

Speed: x2 is a per-facet constant, so each f_j collapses to a cubic in (x1, x3) with ten
per-facet coefficients computed once in `prepare`; a pair then costs a few multiply-adds.
"""
from __future__ import annotations

import math

import numpy as np

# Basis exponents (a, b, c) of T_k = x1^a x2^b x3^c, k = 1..20 (docs/design/models-rft.md).
_EXPONENTS = np.array([
    (0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (2, 0, 0), (0, 2, 0), (0, 0, 2), (1, 1, 0),
    (0, 1, 1), (1, 0, 1), (3, 0, 0), (0, 3, 0), (0, 0, 3), (1, 2, 0), (2, 1, 0), (0, 1, 2),
    (0, 2, 1), (2, 0, 1), (1, 0, 2), (1, 1, 1)])

# Rows: f1, f2, f3; columns: k = 1..20 (KKKobefeng/Hanneszz set, c3,16 = -0.02730).
COEFFICIENTS = np.array([
    [0.00212, -0.02320, -0.20890, -0.43083, -0.00259, 0.48872, -0.00415, 0.07204, -0.02750,
     -0.08772, 0.01992, -0.45961, 0.40799, -0.10107, -0.06576, 0.05664, -0.09269, 0.01892,
     0.01033, 0.15120],
    [-0.06796, -0.10941, 0.04725, -0.06914, -0.05835, -0.65880, -0.11985, -0.25739, -0.26834,
     0.02692, -0.00736, 0.63758, 0.08997, 0.21069, 0.04748, 0.20406, 0.18589, 0.04934,
     0.13527, -0.33207],
    [-0.02634, -0.03436, 0.45256, 0.00835, 0.02553, -1.31290, -0.05532, 0.06790, -0.16404,
     0.02287, 0.02927, 0.95406, -0.00131, -0.11028, 0.01487, -0.02730, 0.10911, -0.04097,
     0.07881, -0.27519],
])

# The ten monomials x1^a x3^c (a + c <= 3) the cubic collapses to once x2 is fixed.
_MONOMIALS = [(a, c) for a in range(4) for c in range(4) if a + c <= 3]
_VERTICAL_TOL = 1e-9
# The same collapse as index arrays, for `_PreparedAgarwal`: the power of x2 of each basis
# term, and in rounds r = 0..3 the r-th term (in basis order) of every monomial that has one,
# so that each coefficient is summed over its terms in basis order, as a loop over k would.
_X2_POWER = _EXPONENTS[:, 1]
_COEFFICIENTS_T = np.ascontiguousarray(COEFFICIENTS.T)[:, :, None]   # (20, 3, 1)
_TERMS = [[k for k, (a, _, c) in enumerate(_EXPONENTS) if (a, c) == mono] for mono in _MONOMIALS]
_ROUNDS = [(np.array([m for m, ks in enumerate(_TERMS) if len(ks) > r]),
            np.array([ks[r] for ks in _TERMS if len(ks) > r]))
           for r in range(max(len(ks) for ks in _TERMS))]


def downward_normal(normals: np.ndarray) -> np.ndarray:
    """n_d: the facet-plane normal that points down; vertical facets take -n (public codes)."""
    flip = normals[..., 2] >= -_VERTICAL_TOL
    return np.where(flip[..., None], -normals, normals)


def generic_coefficients(x1, x2, x3) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(f1, f2, f3) at the invariants, straight from the 20-term table (reference form)."""
    x1, x2, x3 = np.broadcast_arrays(np.asarray(x1, float), np.asarray(x2, float),
                                     np.asarray(x3, float))
    basis = np.stack([x1 ** a * x2 ** b * x3 ** c for a, b, c in _EXPONENTS], axis=-1)
    f = basis @ COEFFICIENTS.T
    return f[..., 0], f[..., 1], f[..., 2]


def generic_stress(normals: np.ndarray, v_hat: np.ndarray) -> np.ndarray:
    """alpha_gen (..., 3) for xi_n = 1 and no friction cap; the unoptimised reference form."""
    nd = downward_normal(np.asarray(normals, float))
    v = np.asarray(v_hat, float)
    f1, f2, f3 = generic_coefficients(-v[..., 2], -nd[..., 2], np.sum(nd * v, axis=-1))
    out = f1[..., None] * nd + f2[..., None] * v
    out[..., 2] -= f3
    return out


class _PreparedAgarwal:
    def __init__(self, model: 'AgarwalRFT', normals: np.ndarray):
        n = np.asarray(normals, dtype=float).reshape(-1, 3)
        self._n = n
        self._nd = downward_normal(n)
        x2 = -self._nd[:, 2]
        # poly[j, m, f]: coefficient of monomial m of f_j for facet f, the sum over the basis
        # terms T_k = x1^a x2^b x3^c with (a, c) = m of c_jk x2^b, in basis order. Per pose
        # this runs twice (full and mirrored half body), so it is vectorised: the powers
        # once, the 20 products in one call, the sums in four rounds (bitwise the loop over
        # k it replaces, which cost ~100 us of the ~350 us of a MiniRQuad pose). Every
        # constant is per facet, so preparing a subset gives that subset's rows bitwise.
        powers = np.empty((4, len(n)))
        powers[0], powers[1], powers[2], powers[3] = 1.0, x2, x2 ** 2, x2 ** 3
        terms = _COEFFICIENTS_T * powers[_X2_POWER][:, None, :]     # (20, 3, F)
        poly = np.zeros((len(_MONOMIALS), 3, len(n)))
        for ms, ks in _ROUNDS:
            poly[ms] += terms[ks]
        self._poly = poly.transpose(1, 0, 2)                          # (3, 10, F) view
        self._xi = model.xi_n
        self._mu = model.mu_surf

    def fused_arrays(self) -> dict:
        """Per-facet constants in the layout of the fused kernels (rft/kernels.py)."""
        return {'n': np.ascontiguousarray(self._n), 'nd': np.ascontiguousarray(self._nd),
                'poly': np.ascontiguousarray(self._poly.transpose(2, 0, 1).reshape(-1, 30)),
                'xi': self._xi, 'mu': self._mu}

    def stress(self, vx, vy, vz):
        nd = self._nd
        ndx, ndy, ndz = nd[:, 0], nd[:, 1], nd[:, 2]
        x1 = -vz
        x3 = ndx * vx + ndy * vy + ndz * vz
        # Monomials x1^a x3^c in _MONOMIALS order, built by products (no power calls).
        x1s, x3s = x1 * x1, x3 * x3
        monos = {(0, 0): None, (0, 1): x3, (0, 2): x3s, (0, 3): x3s * x3,
                 (1, 0): x1, (1, 1): x1 * x3, (1, 2): x1 * x3s,
                 (2, 0): x1s, (2, 1): x1s * x3, (3, 0): x1s * x1}
        f = []
        for j in range(3):
            acc = np.broadcast_to(self._poly[j, 0], x1.shape).copy()
            for m, mono in enumerate(_MONOMIALS[1:], start=1):
                acc += self._poly[j, m] * monos[mono]
            f.append(acc)
        f1, f2, f3 = f
        ax = f1 * ndx + f2 * vx
        ay = f1 * ndy + f2 * vy
        az = f1 * ndz + f2 * vz - f3
        if math.isfinite(self._mu):
            ax, ay, az = self._friction_cap(ax, ay, az)
        return self._xi * ax, self._xi * ay, self._xi * az

    def _friction_cap(self, ax, ay, az):
        """Limit the tangential stress to mu_surf times the normal stress (4.6)."""
        n = self._n
        an = ax * n[:, 0] + ay * n[:, 1] + az * n[:, 2]
        tx, ty, tz = ax - an * n[:, 0], ay - an * n[:, 1], az - an * n[:, 2]
        t_norm = np.sqrt(tx * tx + ty * ty + tz * tz)
        limit = self._mu * np.abs(an)
        scale = np.where(t_norm > limit, limit / np.where(t_norm > 0.0, t_norm, 1.0), 1.0)
        return (an * n[:, 0] + scale * tx, an * n[:, 1] + scale * ty, an * n[:, 2] + scale * tz)


class AgarwalRFT:
    """Agarwal 3D-RFT stress model (default model of the stack).

    xi_n: media stress scale, N/m^3. mu_surf: intruder-surface friction (inf: no cap).
    """

    name = 'agarwal'

    def __init__(self, xi_n: float, mu_surf: float = 0.4):
        if not (math.isfinite(xi_n) and xi_n > 0.0):
            raise ValueError(f'xi_n must be a positive number of N/m^3, got {xi_n}')
        if not (mu_surf >= 0.0):
            raise ValueError(f'mu_surf must be >= 0, got {mu_surf}')
        self.xi_n = float(xi_n)
        self.mu_surf = float(mu_surf)

    def prepare(self, normals: np.ndarray) -> _PreparedAgarwal:
        return _PreparedAgarwal(self, normals)

    def describe(self) -> dict:
        return {'model': self.name, 'xi_n': self.xi_n,
                'mu_surf': self.mu_surf if math.isfinite(self.mu_surf) else 'inf',
                'c3_16': float(COEFFICIENTS[2, 15])}
