"""The one Predictor protocol (re-exported by rftgls_core.predictor) and a label for logs."""
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


def predictor_name(predictor: Predictor) -> str:
    """A short label for logs and diagnostics: the predictor's `name` attribute if it has one
    (every predictor here has: 'live:direct-warm', 'map:minirquad_m90_sand.h5', ...), else
    its class name."""
    return str(getattr(predictor, 'name', type(predictor).__name__))
