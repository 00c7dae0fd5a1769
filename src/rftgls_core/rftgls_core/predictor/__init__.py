"""The one predictor protocol: anything that answers capacity and slip twist for a state.

    predict(state, phi, pull) -> CapacityResult

Implemented by the live solver (`predictor.live.RobotPredictor`: pose, RFT, limit surface,
query) and by a loaded state-space map (`maps.CapacityMap`: interpolation). Consumers
(accuracy harness, capacity_node, behavior_node, the simulator's ground, the lab tools) depend
on this protocol, not on either class.

state: AnchorState (h m, thetaB/thetaL1/thetaL2 rad). phi: tether angle, rad, tension along
(-cos phi, 0, sin phi) in world axes. pull: 'forward' or 'backward' (C-leg orientation).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    from ..surfaces.base import CapacityResult
    from ..types import AnchorState, Pull


@runtime_checkable
class Predictor(Protocol):
    """Capacity along d(phi) and slip twist at the first exit, with a status (never raises on
    bad state values: they come back as `invalid_input`, `out_of_range` or `unsupported`)."""

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        ...
