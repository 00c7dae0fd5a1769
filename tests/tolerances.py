"""Tolerances for comparing two floating-point code paths, each with its argument
(docs/design/numerics.md). A comparison of one code path with itself (a node against the core
function it calls, a file against the arrays it was written from, threads against serial)
needs none: the numbers are the same by construction. A comparison with its own special
argument writes it next to the assertion instead.
"""
from __future__ import annotations

import numpy as np

EPS = float(np.finfo(float).eps)            # 2.2e-16

# The solvers' own tolerance: Newton on the twist sphere stops when the off-ray residual is
# at most 1e-12 of the distance along the ray (surfaces/newton.py, `rtol`), and the closure
# search and polish keep that tolerance.
SOLVER_RTOL = 1e-12
# How much a converged capacity can move per unit of relative perturbation of the problem
# (1 / sigma_min of the tangent Jacobian in the scaled metric, times the ray's slope): a root
# where it is larger is a fold, which the solvers answer through the closure instead. The
# largest seen on the tested states is ~70 (preset against description, 7e-11 relative).
CONDITION_MAX = 1e3

# Two solves of one limit-surface problem whose inputs agree to rounding (a robot posed by
# its preset and by its URDF description, a body placed from an STL and from a description,
# the live solver against a map node built by the same solver on another CPU): each answer is
# within SOLVER_RTOL of the root, relative, amplified by at most CONDITION_MAX, so the two
# capacities agree to 2 * 1e3 * 1e-12 ~ 1e-9 relative, and unit slip twists (scaled metric) to
# 1e-9 absolute.
TWO_SOLVES_RTOL = CONDITION_MAX * SOLVER_RTOL
TWO_SOLVES_TWIST_ATOL = CONDITION_MAX * SOLVER_RTOL

# Two evaluations of the same map interpolation (one query against the batched query): each
# weight is a product of 5 linear factors and the answer a sum over 32 cell corners, so the
# two differ by at most 32 * 5 * 4 eps ~ 1.4e-13 of the largest corner value; the corners of
# one cell stay within 100x of the answer except near zero, which the absolute term covers.
INTERPOLATION_RTOL = 1e-9
INTERPOLATION_ATOL = 1e-12
