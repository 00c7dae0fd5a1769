"""Predictors: anything that answers capacity and slip twist for an anchor state, and the one way
to build one.

    predict(state, phi, pull) -> CapacityResult

state: AnchorState (h m, thetaB/thetaL1/thetaL2 rad). phi: tether angle, rad, tension along
(-cos phi, 0, sin phi) in world axes. pull: 'forward' or 'backward' (C-leg orientation). The
answer's slip_twist is the raw (vx, vz, wy) direction of p's slip (m/s, m/s, rad/s; world axes
at the tether point p; unit Euclidean norm: RFT is rate independent, only the direction is
known), slip_twist_scaled the same direction in the scaled metric (surfaces/base.py).

Implementations are named `<what answers>Predictor`:
    live.py   RobotPredictor, DescriptionPredictor: the live solver posing a robot preset or
              an anchor description at every state (fit-then-query, or streaming)
    maps.py   MapPredictor, DescribedMapPredictor: a precomputed map; FallbackPredictor: a
              map with a live predictor answering where the map cannot be trusted alone
    protocol.py  the Predictor protocol itself, predictor_name
    spec.py   PredictorSpec (what to predict with, one small record) and build_predictor,
              the one builder every consumer calls (nodes, lab tools, simulator, CLI)

Consumers (accuracy harness, capacity_node, behavior_node, the simulator's ground, the lab
tools) depend on the Predictor protocol, not on any class.
"""
from __future__ import annotations

from .protocol import Predictor, predictor_name
from .spec import InputNames, PredictorError, PredictorSpec, build_predictor

__all__ = ['InputNames', 'Predictor', 'PredictorError', 'PredictorSpec', 'build_predictor',
           'predictor_name']
