"""The one way to build a predictor: what build_predictor returns for each kind of
specification, the checks it makes once (a map answers only for its robot, medium, pull and
description), errors that name the caller's inputs in one line, and direct-warm as a method
of the registry like every other."""
from __future__ import annotations

import math

import pytest

from rftgls_core.description import shipped_description
from rftgls_core.predictor import (
    InputNames,
    Predictor,
    PredictorError,
    PredictorSpec,
    build_predictor,
)
from rftgls_core.predictor.live import DescriptionPredictor, RobotPredictor
from rftgls_core.predictor.maps import FallbackPredictor, MapPredictor
from rftgls_core.surfaces.registry import (
    DEFAULT_METHOD,
    LIVE_METHODS,
    streaming_class,
    surface_method,
)
from rftgls_core.surfaces.warm import WarmDirect
from rftgls_core.types import AnchorState, Status

DH = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)      # Table II, MiniRQuad
FLAGS = InputNames(map='--map', robot='--robot', description='--anchor', medium='--medium',
                   live_method='--method', n_twists='--twists')


def test_each_kind_of_specification_builds_its_predictor():
    assert PredictorSpec().live_method == DEFAULT_METHOD == 'twist-mesh'
    live = build_predictor(PredictorSpec(live_method='twist-mesh'))
    assert isinstance(live, RobotPredictor) and live.name == 'live:twist-mesh'
    desc = build_predictor(PredictorSpec(live_method='twist-mesh',
                                         description=str(shipped_description('minirquad'))))
    assert isinstance(desc, DescriptionPredictor) and desc.medium.name == 'm90_sand'
    plain = build_predictor(PredictorSpec(map='minirquad', pull='backward'))
    assert isinstance(plain, MapPredictor) and plain.integrity == 'shipped'
    both = build_predictor(PredictorSpec(map='minirquad', fallback_method='direct',
                                         edge_method='direct'))
    assert isinstance(both, FallbackPredictor) and both.edge is both.fallback   # one solver
    edge = build_predictor(PredictorSpec(map='minirquad', edge_method='direct-warm'))
    assert edge.fallback is None and edge.name == 'map:minirquad_m90_sand.h5+live:direct-warm' \
        '(edge check)'
    for p in (live, desc, plain, both):
        assert isinstance(p, Predictor)
    # inside the grid, away from the support edge, the map predictor answers as the map does
    r = plain.predict(DH, 0.0, 'backward')
    assert r.status is Status.OK and r == plain.map.query(DH, 0.0, 'backward')
    assert both.predict(DH, 0.0, 'backward') == r


@pytest.mark.parametrize('spec, words', [
    (PredictorSpec(map='minirquad', robot='prototype'),
     "is for robot 'minirquad', not for --robot 'prototype'"),
    (PredictorSpec(map='minirquad', medium='glass_beads'),
     "is for medium 'm90_sand', not for --medium 'glass_beads'"),
    (PredictorSpec(map='minirquad', pull='sideways'), "not 'sideways'"),
    (PredictorSpec(map='minirquad', description=str(shipped_description('prototype'))),
     'does not answer for --anchor'),
    (PredictorSpec(map='no_such_map.h5'), 'map file not found: no_such_map.h5'),
    (PredictorSpec(state_map='depth=h'), '--state needs --anchor'),
    (PredictorSpec(live_method='magic'), '--method: unknown method'),
    (PredictorSpec(n_twists=0), '--twists must be a positive count'),
    (PredictorSpec(robot='hexapod'), "--robot: unknown robot 'hexapod'"),
    (PredictorSpec(description='no_such.yaml'), '--anchor: no_such.yaml: cannot read'),
])
def test_a_specification_that_cannot_be_built_is_one_line_naming_the_input(spec, words):
    names = InputNames(**{**FLAGS.__dict__, 'state_map': '--state'})
    with pytest.raises(PredictorError) as err:
        build_predictor(spec, names)
    assert words in str(err.value) and '\n' not in str(err.value), str(err.value)
    assert isinstance(err.value, ValueError)     # the CLI's one-line handler takes it


def test_direct_warm_is_a_registered_streaming_method():
    assert 'direct-warm' in LIVE_METHODS and surface_method('direct-warm') == 'direct'
    assert streaming_class('direct-warm') is WarmDirect and streaming_class('direct') is None
    with pytest.raises(ValueError, match='known methods: direct-warm'):
        surface_method('warm')
    warm = build_predictor(PredictorSpec(live_method='direct-warm'))
    assert isinstance(warm, RobotPredictor) and warm.stats()['steps'] == 0.0   # none solved
    r = warm.predict(DH, math.radians(-20.0), 'backward')
    assert r.status is Status.OK and r.method == 'direct'    # the answers of direct
    assert warm.stats()['steps'] == 1.0 and warm.solver('backward').n_steps_ == 1
    cold = build_predictor(PredictorSpec(live_method='twist-mesh'))
    cold.predict(DH, 0.0, 'backward')
    assert cold.stats() == {}                        # a surface method keeps no stream


def test_twist_counts_one_for_all_or_per_method():
    def twists(method, n):
        return build_predictor(PredictorSpec(live_method=method, n_twists=n)).n_twists
    assert twists('direct', None) == 400 and twists('twist-mesh', None) == 1000
    assert twists('direct-warm', None) == 400         # its surface method's default
    assert twists('direct', 600) == 600 and twists('direct-warm', 600) == 600
    per_method = {'direct': 1000, 'twist-mesh': 1000}
    assert twists('direct', per_method) == 1000 and twists('direct-warm', per_method) == 400
    # a description answers a streaming method with its surface method: that method's count
    d = build_predictor(PredictorSpec(live_method='direct-warm', n_twists=per_method,
                                      description=str(shipped_description('minirquad'))))
    assert d.method == 'direct' and d.n_twists == 1000
