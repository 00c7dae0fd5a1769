"""The interface every RFT stress model implements, so the engine can batch any of them.

A model maps the outward unit normal n of a buried, leading facet and the unit direction v of
its velocity to the resistive stress per unit depth alpha (N/m^3, world axes, z up). The
engine multiplies by depth and area, masks trailing facets, sums forces and moments.

Models are rate independent: alpha depends on the direction of v only (never its magnitude).
"""
from __future__ import annotations

from typing import Protocol

import numpy as np


class PreparedStress(Protocol):
    """A stress model bound to a fixed set of F facet normals (per-facet constants cached)."""

    def stress(self, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """alpha components (ax, ay, az) in N/m^3 for unit velocity directions.

        vx, vy, vz: components of v_hat, arrays of shape (M, F) (M twists x F facets); the
        facet axis is the last one. Pairs that are trailing or at rest may hold any finite
        numbers here: the engine masks them, but the model must never return NaN or inf.
        """
        ...


class StressModel(Protocol):
    name: str

    def prepare(self, normals: np.ndarray) -> PreparedStress:
        """Bind to outward unit normals (F, 3) in world axes."""
        ...

    def describe(self) -> dict:
        """Parameters for provenance (JSON-serialisable)."""
        ...
