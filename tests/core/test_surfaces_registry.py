"""One registry and one fit template for every limit-surface method.

A method only provides `method`, `min_twists`, `_fit_samples` and a query; the base class's
`fit(problem)` does the rest. The checks below hold for every registered method and for a new
method written in this file, which has none of those checks in its own code.
"""
from __future__ import annotations

import inspect

import numpy as np
import pytest

from rftgls_core.surfaces import GLSProblem, LimitSurface
from rftgls_core.surfaces.base import CapacityResult, FitSamples
from rftgls_core.surfaces.registry import METHOD_NAMES, surface_class
from rftgls_core.surfaces.synthetic import DEFAULT_SCALING, convex_case
from rftgls_core.types import Status


class NearestSampleSurface(LimitSurface):
    """A deliberately crude fifth method: the sampled wrench closest to the load ray."""

    method = 'nearest-sample'
    min_twists = 6

    def _fit_samples(self, problem, samples: FitSamples):
        self._ws = samples.wrenches_scaled
        return self

    def _capacity(self, phi):
        pr = self._fitted_problem()
        d = pr.load_direction_scaled(phi)
        along = self._ws @ d
        off = np.linalg.norm(self._ws - along[:, None] * d, axis=1)
        k = int(np.argmin(np.where(along > 0, off, np.inf)))
        return CapacityResult.make(phi, Status.OK, self.method, along[k] * pr.scaling.force_N)


ALL = [surface_class(m) for m in METHOD_NAMES] + [NearestSampleSurface]


def test_registry_names_match_classes():
    assert set(METHOD_NAMES) == {'twist-mesh', 'direct', 'ellipsoid', 'alpha', 'brute-force'}
    for name in METHOD_NAMES:
        cls = surface_class(name)
        assert issubclass(cls, LimitSurface) and cls.method == name
    with pytest.raises(ValueError, match='known methods'):
        surface_class('no-such-method')


def test_predictor_lists_come_from_the_registry():
    """capacity_node's live methods and the lab tools' methods are the registry's, less the
    reference-only brute force (seconds per state)."""
    from rftgls_core.surfaces.registry import PREDICTOR_METHODS, REFERENCE_ONLY
    assert REFERENCE_ONLY == ('brute-force',)
    assert set(PREDICTOR_METHODS) == set(METHOD_NAMES) - {'brute-force'}
    ros = pytest.importorskip('rftgls_ros.capacity.node_predictor')
    lab = pytest.importorskip('rftgls_ros.lab.predict')
    assert ros.LIVE_METHODS == ('direct-warm', *PREDICTOR_METHODS)
    assert lab.METHODS == (*PREDICTOR_METHODS, 'map')


@pytest.mark.parametrize('cls', ALL, ids=lambda c: c.method)
def test_fit_takes_the_problem_only_and_keeps_hyper_parameters(cls):
    assert list(inspect.signature(cls.fit).parameters) == ['self', 'problem']
    surf = cls(n_twists=300)
    assert surf.fit(convex_case().problem) is surf
    assert surf.n_twists == 300


@pytest.mark.parametrize('cls', ALL, ids=lambda c: c.method)
def test_template_checks_apply_to_every_method(cls):
    convex = convex_case()
    g = convex.extra['gls']
    # Twist count below the class minimum.
    r = cls(n_twists=cls.min_twists - 1).fit(convex.problem).capacity(0.2)
    assert (r.status, r.reason) == (Status.DEGENERATE, 'too_few_twists')
    # Non-finite wrenches.
    nan = GLSProblem(lambda t: np.full_like(t, np.nan), DEFAULT_SCALING)
    r = cls(n_twists=200).fit(nan).capacity(0.2)
    assert (r.status, r.reason) == (Status.INVALID_INPUT, 'non_finite_wrench')
    # A flat sampled surface (My identically zero) has no volume.
    flat = GLSProblem(lambda t: g.wrench(t) * [1.0, 1.0, 0.0], DEFAULT_SCALING)
    r = cls(n_twists=200).fit(flat).capacity(0.2)
    assert (r.status, r.reason) == (Status.DEGENERATE, 'flat_cloud')
    # The surface shifted so that the origin lies outside it: the weight is not held. The
    # shift is 3x the largest semi-axis of the synthetic surface, so no twist reaches back.
    shift = np.array([3.0 * max(g.A), 0.0, 0.0]) * DEFAULT_SCALING.force_N
    outside = GLSProblem(lambda t: g.wrench(t) + shift, DEFAULT_SCALING)
    r = cls(n_twists=200).fit(outside).capacity(0.2)
    assert (r.status, r.reason) == (Status.UNSUPPORTED, 'origin_outside')
    assert r.capacity_N is None and r.slip_twist is None


def test_a_new_method_answers_through_the_template():
    case = convex_case()
    r = NearestSampleSurface(n_twists=4000).fit(case.problem).capacity(0.2)
    assert r.status is Status.OK
    # The exact capacity of the synthetic surface (brentq on its gauge, synthetic.py); the
    # nearest of 4000 samples lies within a few per cent of it.
    assert r.capacity_N == pytest.approx(case.exact_capacity(0.2), rel=0.05)
