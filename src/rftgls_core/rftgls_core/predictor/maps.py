"""Map predictors: a precomputed capacity map as a Predictor, and a map with live checks.

MapPredictor answers from a robot map (maps/query.py, CapacityMap.query: about 20 us),
DescribedMapPredictor from a map over an anchor description's own state variables
(maps/described.py), fed from the AnchorState as the live DescriptionPredictor is.
FallbackPredictor puts a live predictor behind a map where the map cannot be trusted on its
own. build_predictor (spec.py) checks a map once, against what it must answer for (robot,
medium, pull, description); these classes only answer.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..description import AnchorDescription, robot_state_map, state_values
from ..maps.described import METHOD, DescribedMap, check_identity
from ..maps.query import CapacityMap
from ..surfaces.base import CapacityResult
from ..types import AnchorState, Pull, Status
from .protocol import Predictor, predictor_name


class MapPredictor:
    """A robot map (four state axes h, theta_b, theta_l1, theta_l2) as a Predictor.

    integrity: 'shipped' / 'verified' (the loader checked the content hash) or 'unverified'
    (a map with no hash, whose integrity nobody can check: say so loudly).
    """

    def __init__(self, cmap: CapacityMap, path: str | Path):
        self.map = cmap
        self.path = Path(path)
        self.integrity = cmap.data.integrity
        self.name = f'map:{self.path.name}'

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        return self.map.query(state, phi, pull)


class DescribedMapPredictor:
    """A described map (`rftgls map build --anchor`) behind the Predictor protocol, with
    sagittal (vx, vz, wy) twists: the description's state variables are fed from the
    AnchorState by description.robot_state_map (by name or state_map), the answer is
    DescribedMap.query's. A 6D slip twist with an out-of-plane part (> TWIST_PLANE_TOL of the
    unit scaled twist) cannot be carried: `invalid_input` `not_symmetric`, as
    DescriptionPredictor answers there. The description must be the map's own (ValueError,
    one line, otherwise; DescriptionError when the AnchorState cannot feed it)."""

    TWIST_PLANE_TOL = 1e-6

    def __init__(self, cmap: DescribedMap, description: AnchorDescription, state_map=None,
                 path: str | Path | None = None):
        check_identity(cmap, description)
        self.map = cmap
        self.description = description
        self.state_map = robot_state_map(description, state_map)
        self.method = METHOD
        self.path = Path(path if path is not None else cmap.source)
        self.integrity = 'verified'   # load_described_map checked its content hash
        self.name = f'map:{self.path.name}:{description.name}'

    @property
    def medium_name(self) -> str:
        return self.map.medium_name

    @property
    def pulls(self) -> tuple[str, ...]:
        return self.map.grid.pulls

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        robot = state_values(state)
        values = {n: robot[q] for n, q in self.state_map.items()}
        pull = pull.value if isinstance(pull, Pull) else str(pull)
        r = self.map.query(values, phi, pull, self.description.sha256)
        if not r.ok or r.slip_twist_scaled is None or r.slip_twist is None:
            return CapacityResult(phi=float(phi), status=r.status, method=METHOD,
                                  reason=r.reason, detail=r.detail)
        ts, tr = np.asarray(r.slip_twist_scaled), np.asarray(r.slip_twist)
        off = float(np.max(np.abs(ts[[1, 3, 5]])))
        if off > self.TWIST_PLANE_TOL:
            return CapacityResult(phi=float(phi), status=Status.INVALID_INPUT, method=METHOD,
                                  reason='not_symmetric',
                                  detail=f'the map\'s slip twist leaves the pull plane (out-of-'
                                         f'plane part {off:.3g}); a sagittal answer cannot '
                                         'carry it')
        s3, r3 = ts[[0, 2, 4]], tr[[0, 2, 4]]
        s3, r3 = s3 / np.linalg.norm(s3), r3 / np.linalg.norm(r3)
        return CapacityResult(phi=float(phi), status=r.status, method=METHOD,
                              capacity_N=r.capacity_N,
                              slip_twist=(float(r3[0]), float(r3[1]), float(r3[2])),
                              slip_twist_scaled=(float(s3[0]), float(s3[1]), float(s3[2])),
                              unchecked_capacity_N=r.capacity_N, detail=r.detail,
                              flags=r.flags)


class FallbackPredictor:
    """A map, with a live predictor answering where the map cannot be trusted on its own:

    * `out_of_range` (outside its grid), when `fallback` is set: the live answer, reason
      `live_fallback`;
    * an answer of the edge-margin rule (flag `edge_margin`, a cell next to the support edge
      answered from an interpolated support margin), when `edge` is set: the live answer,
      reason `live_edge_check`. The interpolated margin can say "holds" where the anchor
      holds nothing (maps/README.md: one state in 1,800 random MiniRQuad states, 0.512 N
      against `unsupported`); the live solver decides there. Its answer replaces the map's
      whether lower or higher (the edge-margin value is a deliberately low bound, the live
      one exact). The same for a cell the support edge crosses without a margin to answer
      from (`unsupported`, flag `edge_unsupported`: some corners hold, some do not): the
      map cannot say on which side of the edge the state lies, the live solver can.

    Every other map answer stands; the live answer's reason keeps the solver's own reason
    first, if any. One solver may serve both (pass the same object)."""

    def __init__(self, primary: Predictor, fallback: Predictor | None = None,
                 edge: Predictor | None = None):
        self.primary = primary
        self.fallback = fallback
        self.edge = edge
        parts = [predictor_name(primary)]
        if fallback is not None:
            parts.append(predictor_name(fallback))
        if edge is not None:
            parts.append(('' if edge is fallback else predictor_name(edge)) + '(edge check)')
        self.name = '+'.join(parts)

    def predict(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        r = self.primary.predict(state, phi, pull)
        if r.status is Status.OUT_OF_RANGE and self.fallback is not None:
            live, why = self.fallback, 'live_fallback'
        elif self.edge is not None and ('edge_margin' in r.flags
                                        or 'edge_unsupported' in r.flags):
            live, why = self.edge, 'live_edge_check'
        else:
            return r
        answer = live.predict(state, phi, pull)
        reason = ';'.join(x for x in (answer.reason, why) if x)
        return dataclasses.replace(answer, reason=reason)
