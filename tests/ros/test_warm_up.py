"""behavior_demo's warm-up (rftgls_ros/warm_up.py) runs what would otherwise compile mid-run:
capacity_node's live predictor, cold and then warm, as the shipped parameter file builds it, and
one settling of the whole-robot simulation. The compiling itself is seen in a fresh `make demo`
(rftgls_ros/warm_up.py says how long); here, that each path is called."""
from __future__ import annotations

from pathlib import Path

import yaml

from rftgls_core.multibody.simulate import Simulator
from rftgls_ros import warm_up as wu

REPO = Path(__file__).resolve().parents[2]
PARAMS = REPO / 'ros2_ws' / 'params' / 'capacity_node.yaml'


class _Live:
    def __init__(self):
        self.calls = []

    def predict(self, state, phi, pull):
        self.calls.append((state, phi, pull))


class _Combined:
    def __init__(self):
        self.primary, self.edge, self.fallback = object(), _Live(), None


def test_the_shipped_parameters_are_the_nodes(tmp_path):
    p = wu.capacity_parameters(PARAMS)
    assert set(p) == set(wu.PARAMETERS)
    shipped = yaml.safe_load(PARAMS.read_text())['/**/capacity_node']['ros__parameters']
    assert all(p[k] == v for k, v in shipped.items())
    assert wu.capacity_parameters(None) == {n: s.default for n, s in wu.PARAMETERS.items()}
    # another node's section is not capacity_node's
    other = tmp_path / 'other.yaml'
    other.write_text('behavior_node:\n  ros__parameters:\n    pull: forward\n')
    assert wu.capacity_parameters(other)['pull'] == wu.PARAMETERS['pull'].default


def test_warm_up_runs_the_live_predictor_cold_and_warm_and_settles_the_robot(monkeypatch):
    combined = _Combined()
    built = []
    monkeypatch.setattr(wu, 'predictor_from_params', lambda p: built.append(p) or combined)
    placed = []
    monkeypatch.setattr(Simulator, 'place', lambda self, q, *a: placed.append(list(q)))
    took = wu.warm_up(PARAMS)
    assert took >= 0.0
    assert built and built[0]['lower_bound_theta_b_step_rad'] == \
        wu.capacity_parameters(PARAMS)['lower_bound_theta_b_step_rad']
    # two different states: the solver's first answer runs cold, the next one warm
    states = [c[0] for c in combined.edge.calls]
    assert len(states) == 2 and states[0] != states[1]
    assert {c[2] for c in combined.edge.calls} == {built[0]['pull']}
    assert placed == [[0.0, 0.0, 0.0, 0.0]]
