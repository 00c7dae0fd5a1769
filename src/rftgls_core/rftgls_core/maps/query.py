"""`CapacityMap`: capacity and slip twist at any anchor state from a precomputed map.

Interpolation (5-linear): over the four state axes (h, theta_b, theta_l1, theta_l2) AND the
pull angle phi, i.e. up to 32 corners (16 state corners x 2 stored pull angles). Linear in phi
because capacity and twist vary smoothly with the load direction; a phi equal to a stored angle
uses that angle only. The pull orientation is not interpolated: it selects a sub-map.

Policies (docs/design/architecture.md, docs/design/limit-surfaces.md):
- Out of grid (any state axis or phi beyond interpolate.SNAP of a cell past the end node):
  OUT_OF_RANGE, reason 'out_of_grid', NO value, with the axes named in `detail`. A clamped
  answer would carry the edge's capacity to states where the live solver gives a far lower
  one (or none); outside the grid the map knows nothing (README "Statuses").
- Non-finite state or phi, unknown pull, or a pull orientation the map does not hold:
  INVALID_INPUT, no value.
- Support edge, valued-corner rule (default): a cell whose only valueless corners are
  UNSUPPORTED and whose valued corners carry >= edge_min_weight (EDGE_MIN_WEIGHT, 0.9) of the
  5-D interpolation weight answers the blend of the valued corners, renormalised by their
  weight, status OK with the flag 'edge_valued'. The capacity JUMPS at the support edge (it
  does not fall to 0), so no blend can place the edge; near the valued corners the state
  measured on the holding side (maps/README.md: 300 random states per robot, no answer where
  the live solver says unsupported, worst overestimate that of interior cells).
- Support edge, edge-margin rule (default on schema-2 maps, edge.py): otherwise, when the
  valueless corners are all UNSUPPORTED and every weighted corner has a support margin, the
  margin is interpolated (the multilinear blend of the 16 state corners' first-order Taylor
  predictions m_i + grad_i . (x - x_i)); at >= edge_min_margin (EDGE_MIN_MARGIN, 0.125) the
  query lies on the holding side and the answer is the valued corners' blend, renormalised,
  capped at s_F x margin (a lower bound of the first exit: the origin is at least that far
  from the surface), status OK with the flag 'edge_margin' (maps/README.md: 3 x 300 random
  states per robot, no answer where the live solver has none, overestimate unchanged).
- Support edge, zeros rule (opt-in, `support_edge=True`): a corner that cannot hold the weight
  (UNSUPPORTED) has capacity 0, the value capacity falls to where the origin leaves the limit
  surface. A cell whose only valueless corners are unsupported then answers the blend with
  those corners as 0 N (twists from the valued corners), status OK with the flag
  'support_edge'. Off by default: capacity falls steeply near the edge, wherever in the cell
  the edge lies, so such answers can lie far above the live solver (maps/README.md).
- Conservative cell rule: if any other corner with nonzero weight has no value (degenerate,
  ...), or no weight has a value, the answer has no value. Its status is the most conservative
  status among those corners, in the order UNSUPPORTED > DEGENERATE > INVALID_INPUT > STALE;
  reason 'cell_<status>', and `detail` counts the corners and quotes the node's own reason;
  flag 'edge_unsupported' when some corners hold and the rest are unsupported (edge crossed).
  A query exactly on a valued node or face never looks at zero-weight neighbours.
- Twists: the scaled-metric components are blended, then renormalised. The pre-normalisation
  norm (1 when all corners agree, -> 0 when they oppose) is the twist confidence, always
  reported in `detail` as 'twist_confidence=0.xxx'; below LOW_CONFIDENCE (0.5) the detail says
  the neighbouring nodes disagree (a slip-mode switch inside the cell). A norm below 1e-9
  (twists cancel) gives DEGENERATE 'twist_cancels'.
- Capacity is clamped at >= 0 (it already is: a convex blend of non-negative node values).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..surfaces.base import CapacityResult
from ..types import AnchorState, Pull, Status
from .grid import AXIS_HUMAN, STATE_AXES, MapGrid
from .hdf5 import STATUS_NAMES, MapData, load_map
from .interpolate import corner_offsets, flat_strides, locate, locate_many, weights4

METHOD = 'map'
LOW_CONFIDENCE = 0.5
CANCEL_NORM = 1e-9        # below this the blended twist has no direction
# Valued-corner rule next to the support edge (maps/README.md): a cell whose valueless corners
# are all unsupported answers the blend of its valued corners, renormalised, when they carry
# at least this share of the interpolation weight (measured: 300 random states per robot).
EDGE_MIN_WEIGHT = 0.9
# Edge-margin rule (schema 2 maps, maps/edge.py): inside a cell that straddles the support edge
# the interpolated support margin (scaled metric) must reach this value to answer. Chosen on
# 3 x 300 random MiniRQuad states (seeds 0-2: the largest coverage without a value where the
# live solver has none, with the margins of the edge corners on the dense sphere), checked on
# seeds 3-5 (maps/README.md).
EDGE_MIN_MARGIN = 0.125
# Most conservative first: a cell touching an unsupported node is reported unsupported.
BAD_PRIORITY = (Status.UNSUPPORTED, Status.DEGENERATE, Status.INVALID_INPUT, Status.STALE)
AXIS_NAMES = STATE_AXES + ('phi',)
_CODE = {s: STATUS_NAMES.index(s.value) for s in Status}
_STATUS_OF = [Status(n) for n in STATUS_NAMES]
_RANK = {_CODE[s]: r for r, s in enumerate(BAD_PRIORITY)}
_RANK_OF_CODE = np.array([_RANK.get(c, len(_RANK)) for c in range(len(STATUS_NAMES))])
_UNSUPPORTED = _CODE[Status.UNSUPPORTED]


@dataclass(frozen=True)
class BatchAnswer:
    """Vectorised answers for N queries (one pull orientation).

    capacity_N (N,), NaN without value; slip_twist_scaled / slip_twist (N, 3), NaN without
    value; confidence (N,) pre-normalisation twist norm (NaN without value); status (N,)
    uint8 codes into hdf5.STATUS_NAMES; out_of_grid (N, 5) bool per axis (h, theta_b,
    theta_l1, theta_l2, phi); support_edge (N,) bool, answered by the zeros rule;
    edge_valued (N,) bool, answered by the valued-corner rule; edge_margin (N,) bool,
    answered by the edge-margin rule.
    """

    capacity_N: np.ndarray
    slip_twist_scaled: np.ndarray
    slip_twist: np.ndarray
    confidence: np.ndarray
    status: np.ndarray
    out_of_grid: np.ndarray
    support_edge: np.ndarray
    edge_valued: np.ndarray
    edge_margin: np.ndarray

    def statuses(self) -> list[Status]:
        return [_STATUS_OF[c] for c in self.status]


def _pair(a: tuple[float, ...] | None, b: tuple[float, ...] | None
          ) -> tuple[float, ...] | None:
    """Values at two neighbouring stored angles as one tuple, None if either has none."""
    return None if a is None or b is None else a + b


def _describe_side(name: str, x: float, lo: float, hi: float, side: int) -> str:
    unit, f = AXIS_HUMAN[name]
    edge = lo if side < 0 else hi
    word = 'below' if side < 0 else 'above'
    return f'{name} {x * f:.4g} {unit} {word} grid (edge {edge * f:.4g})'


class CapacityMap:
    """A loaded capacity map; `query` is the onboard hot path (pure Python, ~10 us)."""

    def __init__(self, data: MapData, source: str = '', support_edge: bool = False,
                 edge_min_weight: float = EDGE_MIN_WEIGHT,
                 edge_min_margin: float | None = EDGE_MIN_MARGIN) -> None:
        """support_edge: answer cells next to unsupported nodes by the zeros rule (opt-in: its
        measured error, maps/README.md, is far larger than the interior's).
        edge_min_weight: the valued-corner rule answers a cell whose valueless corners are all
        unsupported when the valued corners carry at least this share of the weight (> 1
        switches the rule off).
        edge_min_margin: the edge-margin rule (schema-2 maps) answers a cell straddling the
        support edge where the interpolated support margin is >= this; None switches it off."""
        self.data = data
        self.source = source
        self.support_edge = bool(support_edge)
        if not (math.isfinite(edge_min_weight) and edge_min_weight > 0.0):
            raise ValueError(f'edge_min_weight must be a positive share, got {edge_min_weight}')
        self.edge_min_weight = float(edge_min_weight)
        if edge_min_margin is not None and not math.isfinite(edge_min_margin):
            raise ValueError(f'edge_min_margin must be finite or None, got {edge_min_margin}')
        self.edge_min_margin = None if edge_min_margin is None else float(edge_min_margin)
        g = data.grid
        self._axes = [list(map(float, getattr(g, n))) for n in AXIS_NAMES]
        n_pull = len(g.pulls)
        per_pull = g.shape[1:]
        self._strides = flat_strides(per_pull)
        n_phi = per_pull[-1]
        # Single-query path: flat offsets (in answers, node * K + k) of the 16 state corners,
        # ordered like weights4.
        self._offs16 = [int(o) for o in corner_offsets(self._strides[:4])[0]]
        self._state_strides = self._strides[:4]
        self._n_phi = n_phi
        self._pull_index = {p: i for i, p in enumerate(g.pulls)}
        prov = data.attrs
        self._s_lc = float(prov['scaling_length_m'])
        self._s_f = float(prov['scaling_force_N'])
        # Per pull: node tuple (cap, tsx, tsz, tsw) or None, plus status/reason codes.
        cap = data.capacity_N.astype(np.float64).reshape(n_pull, -1)
        ts = data.slip_twist_scaled.astype(np.float64).reshape(n_pull, -1, 3)
        status = data.status.reshape(n_pull, -1)
        reason = data.reason.reshape(n_pull, -1)
        valued = np.isin(status, [_CODE[s] for s in Status if s.has_value])
        self._values, self._pairs, self._codes, self._reasons = [], [], [], []
        for p in range(n_pull):
            vals: list[tuple[float, ...] | None] = [None] * cap.shape[1]
            for j in np.flatnonzero(valued[p]).tolist():
                vals[j] = (float(cap[p, j]), float(ts[p, j, 0]), float(ts[p, j, 1]),
                           float(ts[p, j, 2]))
            self._values.append(vals)
            # (value at k) + (value at k + 1) as one 8-tuple, None if either has no value:
            # one lookup and one unpack per corner when phi lies between stored angles.
            self._pairs.append([_pair(vals[j], vals[j + 1]) if (j + 1) % n_phi else None
                                for j in range(len(vals))])
            self._codes.append(status[p].tolist())
            self._reasons.append(reason[p].tolist())
        # Batch path: flat numpy arrays, NaN-free (zeros) where no value + a validity mask.
        self._cap_flat = np.where(valued, cap, 0.0)
        self._ts_flat = np.where(valued[..., None], ts, 0.0)
        self._valued = valued
        self._status_flat = status
        self._offsets, self._bits = corner_offsets(self._strides)
        # Edge-margin rule (schema 2): per state node (flat C order), the support margin (None
        # without a surface) and its gradient along the state axes (NaN -> 0: that corner
        # contributes its plain margin).
        self._margin: list[list[float | None]] | None = None
        self._mgrad: list[list[tuple[float, ...]]] | None = None
        self._margin_flat = self._margin_ok = self._mgrad_flat = None
        self._bits16 = [tuple(int(b) for b in row)
                        for row in corner_offsets(self._strides[:4])[1].tolist()]
        self._n_states = int(np.prod(g.state_shape))
        if (data.support_margin is not None and data.support_margin_grad is not None
                and self.edge_min_margin is not None):
            marg = data.support_margin.astype(np.float64).reshape(n_pull, -1)
            grad = np.nan_to_num(data.support_margin_grad.astype(np.float64).reshape(
                n_pull, -1, 4), nan=0.0)
            self._margin = [[None if math.isnan(x) else x for x in row]
                            for row in marg.tolist()]
            self._mgrad = [[tuple(r) for r in row] for row in grad.tolist()]
            self._margin_ok = np.isfinite(marg)
            self._margin_flat = np.where(self._margin_ok, marg, 0.0)
            self._mgrad_flat = grad

    # -- construction and metadata ---------------------------------------------------------
    @classmethod
    def load(cls, path: str | Path, support_edge: bool = False,
             edge_min_weight: float = EDGE_MIN_WEIGHT,
             edge_min_margin: float | None = EDGE_MIN_MARGIN) -> 'CapacityMap':
        """Read and validate a map file (MapFileError, a ValueError, on any problem)."""
        return cls(load_map(path), source=str(path), support_edge=support_edge,
                   edge_min_weight=edge_min_weight, edge_min_margin=edge_min_margin)

    @property
    def grid(self) -> MapGrid:
        return self.data.grid

    @property
    def axes(self) -> dict[str, np.ndarray]:
        """State axes in SI: {'h': m, 'theta_b', 'theta_l1', 'theta_l2': rad}."""
        return {n: getattr(self.grid, n) for n in STATE_AXES}

    @property
    def phis(self) -> np.ndarray:
        """Stored pull angles, rad."""
        return self.grid.phi

    @property
    def pulls(self) -> tuple[str, ...]:
        return self.grid.pulls

    @property
    def robot_name(self) -> str:
        return str(self.data.attrs['robot'])

    @property
    def medium_name(self) -> str:
        return str(self.data.attrs['medium'])

    @property
    def method(self) -> str:
        """The limit-surface method the map was built with (query results say 'map')."""
        return str(self.data.attrs['method'])

    @property
    def provenance(self) -> dict:
        return self.data.provenance

    @property
    def description_sha256(self) -> str:
        """Identity of the anchor description the map answers for. A robot map (--robot)
        answers for its robot's shipped description, which gives the same numbers as the
        preset (tests/core/test_description.py); its content hash stays what it was."""
        from ..description import description_sha256, shipped_description
        return description_sha256(shipped_description(self.robot_name))

    def check_description(self, description_sha256: str) -> None:
        """Refuse (ValueError, one line) a caller that poses another description than the
        one the map was built for: a map answers only for its own anchor."""
        mine = self.description_sha256
        if description_sha256 != mine:
            raise ValueError(f'{self.source or "map"}: built for the {self.robot_name} '
                             f'description {mine[:12]}, not for description '
                             f'{description_sha256[:12]}')

    # -- single query (hot path) -----------------------------------------------------------
    def _invalid(self, phi, reason: str, detail: str) -> CapacityResult:
        try:
            phi = float(phi)
        except (TypeError, ValueError):
            phi = math.nan
        return CapacityResult(phi=phi, status=Status.INVALID_INPUT, method=METHOD,
                              reason=reason, detail=detail)

    def query(self, state: AnchorState, phi: float, pull: Pull | str) -> CapacityResult:
        """Capacity (N) along d(phi) and slip twist at `state` (SI), pull angle phi (rad)."""
        p = self._pull_index.get(pull.value if isinstance(pull, Pull) else str(pull))
        if p is None:
            return self._invalid(phi, 'pull_not_in_map',
                                 f'pull {pull!r} not in this map (has {", ".join(self.pulls)})')
        try:
            coords = (float(state.h), float(state.theta_b), float(state.theta_l1),
                      float(state.theta_l2), float(phi))
        except (AttributeError, TypeError, ValueError):
            return self._invalid(phi, 'invalid_state', f'not an anchor state: {state!r}')
        if not all(map(math.isfinite, coords)):
            return self._invalid(phi, 'invalid_state',
                                 f'state and phi must be finite, got {coords}')
        base, out = 0, None
        fr = [0.0, 0.0, 0.0, 0.0]
        axes = self._axes
        for a in range(4):
            i, t, side = locate(axes[a], coords[a])
            base += i * self._state_strides[a]
            fr[a] = t
            if side:
                out = (out or []) + [(a, side)]
        k, tp, side = locate(axes[4], coords[4])
        if side:
            out = (out or []) + [(4, side)]
        if out is not None:
            return self._out_of_grid(coords, out)
        dk = 1 if tp != 0.0 else 0   # on a stored angle: read that angle only
        flat = self._values[p]
        b0 = base + k
        ws = weights4(fr[0], fr[1], fr[2], fr[3])
        bad = None
        n_terms = 0
        w_valued = 0.0
        c = x0 = x1 = x2 = 0.0
        up = 1.0
        if dk:
            pairs = self._pairs[p]
            cb = y0 = y1 = y2 = 0.0
            wa = wb = 0.0     # weight of half-valued pairs at the lower / upper stored angle
            for off, w in zip(self._offs16, ws):
                if w == 0.0:
                    continue   # before indexing: zero-weight corners may lie past the axis end
                n_terms += 1
                v = pairs[b0 + off]
                if v is None:
                    j = b0 + off
                    bad = (bad or []) + [i for i in (j, j + 1) if flat[i] is None]
                    # the valued half of the pair still counts for the valued-corner rule
                    h = flat[j]
                    if h is not None:
                        wa += w
                        c += w * h[0]
                        x0 += w * h[1]
                        x1 += w * h[2]
                        x2 += w * h[3]
                    h = flat[j + 1]
                    if h is not None:
                        wb += w
                        cb += w * h[0]
                        y0 += w * h[1]
                        y1 += w * h[2]
                        y2 += w * h[3]
                    continue
                a0, a1, a2, a3, e0, e1, e2, e3 = v
                w_valued += w
                c += w * a0
                x0 += w * a1
                x1 += w * a2
                x2 += w * a3
                cb += w * e0
                y0 += w * e1
                y1 += w * e2
                y2 += w * e3
            up = 1.0 - tp
            c, x0, x1, x2 = (up * c + tp * cb, up * x0 + tp * y0, up * x1 + tp * y1,
                             up * x2 + tp * y2)
            if bad is not None:   # 5-D valued weight: both angles of the half-valued pairs
                w_valued += up * wa + tp * wb
        else:
            for off, w in zip(self._offs16, ws):
                if w == 0.0:
                    continue
                n_terms += 1
                v = flat[b0 + off]
                if v is None:
                    bad = (bad or []) + [b0 + off]
                    continue
                a0, a1, a2, a3 = v
                w_valued += w
                c += w * a0
                x0 += w * a1
                x1 += w * a2
                x2 += w * a3
        n_corners = n_terms * (1 + dk)
        flags: tuple[str, ...] = ()
        edge_m = 0.0
        if bad is not None:
            # Valueless corners that are all unsupported (any other status withholds the value):
            # - valued-corner rule: when the valued corners carry >= edge_min_weight of the
            #   weight, the query lies close to them, on the side that holds (measured, README);
            #   the answer is their blend, renormalised (flag 'edge_valued');
            # - opt-in zeros rule (support_edge): the unsupported corners count as 0 N.
            unsupported = self._codes[p]
            only_unsupported = w_valued > 0.0 and all(unsupported[k] == _UNSUPPORTED
                                                      for k in bad)
            if only_unsupported and w_valued >= self.edge_min_weight - 1e-12:
                inv = 1.0 / w_valued
                c, x0, x1, x2 = c * inv, x0 * inv, x1 * inv, x2 * inv
                flags = ('edge_valued',)
            elif only_unsupported and self.support_edge:
                flags = ('support_edge',)
            else:
                m = (self._edge_margin(p, coords)
                     if only_unsupported and self._margin is not None else None)
                if m is None:
                    return self._bad_cell(p, coords[4], bad, n_corners, ('edge_unsupported',)
                                          if only_unsupported else ())
                # The valued corners' blend, capped by the margin: the first exit along any
                # load direction lies at least the origin's distance from the surface away
                # (s_F m in N, d has no moment part), so the cap is a lower bound where the
                # valued corners' capacity does not continue to the query.
                inv = 1.0 / w_valued
                c, x0, x1, x2 = min(c * inv, self._s_f * m), x0 * inv, x1 * inv, x2 * inv
                edge_m = m
                flags = ('edge_margin',)
        norm = math.sqrt(x0 * x0 + x1 * x1 + x2 * x2)
        if norm < CANCEL_NORM:
            return CapacityResult(phi=coords[4], status=Status.DEGENERATE, method=METHOD,
                                  reason='twist_cancels',
                                  detail='the corner slip twists cancel exactly')
        ts = (x0 / norm, x1 / norm, x2 / norm)
        # Raw direction S^-1 ts: the common force scale cancels in the normalisation.
        r2 = x2 / self._s_lc
        rn = math.sqrt(x0 * x0 + x1 * x1 + r2 * r2)
        raw = (x0 / rn, x1 / rn, r2 / rn)
        detail = f'twist_confidence={norm:.3f}; corners {n_corners}'
        if flags == ('support_edge',):
            detail += (f'; support edge: {len(bad or [])} unsupported corners counted as 0 N '
                       f'(valued weight {w_valued:.3f})')
        elif flags == ('edge_margin',):
            detail += (f'; support edge: interpolated support margin {edge_m:.4f} >= '
                       f'{self.edge_min_margin:g}: blend of the valued corners capped at '
                       f's_F x margin = {self._s_f * edge_m:.3f} N, {len(bad or [])} '
                       'unsupported corners left out')
        elif flags:
            detail += (f'; support edge: blend of the valued corners (weight {w_valued:.3f} >= '
                       f'{self.edge_min_weight:g}), {len(bad or [])} unsupported corners left out')
        if norm < LOW_CONFIDENCE:
            detail += (f'; LOW twist confidence (< {LOW_CONFIDENCE}): neighbouring nodes '
                       'disagree on the slip twist')
        return CapacityResult(phi=coords[4], status=Status.OK, method=METHOD,
                              capacity_N=max(c, 0.0), slip_twist=raw, slip_twist_scaled=ts,
                              unchecked_capacity_N=max(c, 0.0), reason='', detail=detail,
                              flags=flags)

    def _edge_margin(self, p: int, coords: tuple[float, ...]) -> float | None:
        """Edge-margin rule: the support margin at the query, the multilinear blend of the 16
        state corners' first-order Taylor predictions m_i + grad_i . (x - x_i) (maps/edge.py),
        or None when a weighted corner has no margin (no surface) or the result is below
        edge_min_margin (the query may lie past the support edge)."""
        assert self._margin is not None and self._mgrad is not None
        assert self.edge_min_margin is not None
        axes = self._axes
        node0, fr, width = 0, [0.0] * 4, [0.0] * 4
        for a in range(4):
            xs = axes[a]
            i, t, _ = locate(xs, coords[a])
            node0 = node0 * len(xs) + i
            fr[a] = t
            width[a] = xs[i + 1] - xs[i] if i + 1 < len(xs) else 0.0
        # node strides of the state grid (C order)
        n1, n2, n3 = len(axes[1]), len(axes[2]), len(axes[3])
        strides = (n1 * n2 * n3, n2 * n3, n3, 1)
        ws = weights4(fr[0], fr[1], fr[2], fr[3])
        marg, grads = self._margin[p], self._mgrad[p]
        m = 0.0
        for bits, w in zip(self._bits16, ws):
            if w == 0.0:
                continue
            j = (node0 + bits[0] * strides[0] + bits[1] * strides[1] + bits[2] * strides[2]
                 + bits[3] * strides[3])
            mj = marg[j]
            if mj is None:
                return None
            gj = grads[j]
            m += w * (mj + gj[0] * (fr[0] - bits[0]) * width[0]
                      + gj[1] * (fr[1] - bits[1]) * width[1]
                      + gj[2] * (fr[2] - bits[2]) * width[2]
                      + gj[3] * (fr[3] - bits[3]) * width[3])
        return m if m >= self.edge_min_margin else None

    def _out_of_grid(self, coords, out: list[tuple[int, int]]) -> CapacityResult:
        detail = '; '.join(
            _describe_side(AXIS_NAMES[a], coords[a], self._axes[a][0], self._axes[a][-1], s)
            for a, s in out)
        return CapacityResult(phi=coords[4], status=Status.OUT_OF_RANGE, method=METHOD,
                              reason='out_of_grid', detail=detail)

    def _bad_cell(self, p: int, phi: float, bad: list[int], n_terms: int, flags=()):
        codes = self._codes[p]
        worst = min((codes[k] for k in bad), key=lambda c: _RANK.get(c, len(_RANK)))
        status = _STATUS_OF[worst]
        first = next(k for k in bad if codes[k] == worst)
        names = self.data.reason_names
        why = f' ({names[self._reasons[p][first]]})' if names else ''
        return CapacityResult(
            phi=phi, status=status, method=METHOD, reason=f'cell_{status.value}', flags=flags,
            detail=f'{len(bad)} of {n_terms} weighted cell corners have no value; e.g. node '
                   f'{self._node_text(p, first)} is {status.value}{why}')

    def _node_text(self, p: int, k: int) -> str:
        idx = []
        for stride in self._strides:   # pure-Python unravel (numpy's costs ~5 us here)
            i, k = divmod(k, stride)
            idx.append(i)
        parts = []
        for name, xs, i in zip(AXIS_NAMES, self._axes, idx):
            unit, f = AXIS_HUMAN[name]
            parts.append(f'{name}={xs[i] * f:.4g}{unit}')
        return '(' + ', '.join(parts) + f', {self.pulls[p]})'

    # -- batch query -----------------------------------------------------------------------
    def query_batch(self, states, phis, pull: Pull | str) -> BatchAnswer:
        """Vectorised query: states (N, 4) SI (h, theta_b, theta_l1, theta_l2), phis (N,) or
        scalar, rad; one pull orientation. Same policies as `query` (status codes, NaN values).
        """
        key = pull.value if isinstance(pull, Pull) else str(pull)
        if key not in self._pull_index:
            raise ValueError(f'pull {pull!r} not in this map (has {", ".join(self.pulls)})')
        p = self._pull_index[key]
        s = np.atleast_2d(np.asarray(states, dtype=np.float64))
        if s.shape[1] != 4:
            raise ValueError(f'states must be (N, 4), got {s.shape}')
        n = len(s)
        ph = np.broadcast_to(np.asarray(phis, dtype=np.float64), (n,))
        coords = np.column_stack([s, ph])
        finite = np.all(np.isfinite(coords), axis=1)
        coords = np.where(finite[:, None], coords, 0.0)
        base = np.zeros(n, dtype=np.intp)
        frac = np.empty((n, 5))
        out = np.zeros((n, 5), dtype=bool)
        for a, (xs, stride) in enumerate(zip(self._axes, self._strides)):
            i, t, side = locate_many(np.asarray(xs), coords[:, a])
            base += i * stride
            frac[:, a] = t
            out[:, a] = side != 0
        cap = np.zeros(n)
        tw = np.zeros((n, 3))
        worst = np.full(n, len(_RANK), dtype=np.intp)     # rank of the worst bad corner
        worst_code = np.zeros(n, dtype=np.intp)
        w_valued = np.zeros(n)
        other_bad = np.zeros(n, dtype=bool)     # a valueless corner that is not unsupported
        has_margin = self._margin_flat is not None
        marg = np.zeros(n)                      # interpolated support margin (Taylor blend)
        no_margin = np.zeros(n, dtype=bool)     # a weighted corner without one
        widths = np.zeros((n, 4))
        node0 = np.zeros(n, dtype=np.intp)
        for a in range(4):
            xa = np.asarray(self._axes[a])
            ia = np.clip(np.searchsorted(xa, np.clip(coords[:, a], xa[0], xa[-1]),
                                         side='right') - 1, 0, len(xa) - 2)
            widths[:, a] = xa[ia + 1] - xa[ia]
            node0 = node0 * len(xa) + ia
        node_strides = np.asarray(flat_strides(self.grid.state_shape), dtype=np.intp)
        for off, bits in zip(self._offsets, self._bits):
            w = np.prod(np.where(bits == 1, frac, 1.0 - frac), axis=1)
            k = base + off
            use = w > 0.0
            good = self._valued[p, k]
            w_valued += np.where(use & good, w, 0.0)
            cap += np.where(use & good, w * self._cap_flat[p, k], 0.0)
            tw += np.where((use & good)[:, None], w[:, None] * self._ts_flat[p, k], 0.0)
            code = self._status_flat[p, k].astype(np.intp)
            other_bad |= use & ~good & (code != _UNSUPPORTED)
            if has_margin and bits[4] == 0:   # the margin does not depend on phi
                assert self._margin_flat is not None and self._margin_ok is not None
                assert self._mgrad_flat is not None
                wm = np.prod(np.where(bits[:4] == 1, frac[:, :4], 1.0 - frac[:, :4]), axis=1)
                um = wm > 0.0
                j = node0 + bits[:4] @ node_strides
                dx = (frac[:, :4] - bits[:4]) * widths
                pred = self._margin_flat[p, j] + np.einsum('ij,ij->i', self._mgrad_flat[p, j], dx)
                marg += np.where(um, wm * pred, 0.0)
                no_margin |= um & ~self._margin_ok[p, j]
            rank = _RANK_OF_CODE[code]
            hit = use & ~good & (rank < worst)
            worst = np.where(hit, rank, worst)
            worst_code = np.where(hit, code, worst_code)
        # Support edge (as in `query`): when some weight has a value and no corner has another
        # valueless status, the valued-corner rule or (opt-in) the zeros rule answers.
        only_unsup = (worst < len(_RANK)) & ~other_bad & (w_valued > 0.0)
        valued_rule = only_unsup & (w_valued >= self.edge_min_weight - 1e-12)
        edge = only_unsup & ~valued_rule & self.support_edge
        margin_rule = only_unsup & ~valued_rule & ~edge & has_margin & ~no_margin
        if has_margin:
            assert self.edge_min_margin is not None
            margin_rule &= marg >= self.edge_min_margin
        has_bad = (worst < len(_RANK)) & ~edge & ~valued_rule & ~margin_rule
        inv = np.where(valued_rule | margin_rule,
                       1.0 / np.where(w_valued > 0.0, w_valued, 1.0), 1.0)
        cap = cap * inv
        cap = np.where(margin_rule, np.minimum(cap, self._s_f * marg), cap)
        tw = tw * inv[:, None]
        norm = np.linalg.norm(tw, axis=1)
        status = np.where(norm < CANCEL_NORM, _CODE[Status.DEGENERATE], _CODE[Status.OK])
        status = np.where(has_bad, worst_code, status)
        # Out of grid wins over the cell's own status, as in `query` (checked first there).
        status = np.where(out.any(axis=1), _CODE[Status.OUT_OF_RANGE], status)
        status = np.where(finite, status, _CODE[Status.INVALID_INPUT]).astype(np.uint8)
        ok = status == _CODE[Status.OK]
        safe = np.where(norm >= CANCEL_NORM, norm, 1.0)
        ts = tw / safe[:, None]
        raw = ts * np.array([1.0, 1.0, 1.0 / self._s_lc])
        raw /= np.where(ok, np.linalg.norm(raw, axis=1), 1.0)[:, None]
        nan = np.nan
        return BatchAnswer(capacity_N=np.where(ok, np.maximum(cap, 0.0), nan),
                           slip_twist_scaled=np.where(ok[:, None], ts, nan),
                           slip_twist=np.where(ok[:, None], raw, nan),
                           confidence=np.where(ok, norm, nan), status=status,
                           out_of_grid=out & finite[:, None], support_edge=ok & edge,
                           edge_valued=ok & valued_rule, edge_margin=ok & margin_rule)
