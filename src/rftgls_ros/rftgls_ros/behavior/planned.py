"""Planned burrows: the burrow planner's gaits as the chooser's candidates.

``burrow_modes: planned``. At CHOOSE the planner answers every gait of the shipped gait map for
the configured sled (rftgls_core.planning: the burrow simulation over the medium's and the
servos' spread, and the capacity at each predicted pose over the tether angles in use) at the
configured one-sided confidence, and the cheapest gait whose lower bound, times the learned
scale, covers safety_factor x need / tug_ratio (ModeChooser) is chosen. The gait becomes a
burrow the machine runs like a Table II mode (``AnchorMode``): its final pose, its *predicted*
burrowed h and pitch, and a band of H_BAND_SDS of the predicted h's standard deviations. The
gait map is per sled (the sled is tied to p while the robot burrows); with no map for the sled
the planner refuses at start-up.

The planner's lower bound and CHECK's come from different models of the same anchor: the
planner's from the burrow simulation's spread and the live solver, CHECK's from the predictor
capacity_node answers with (its map) over the height band of the burrowed pose. A gait CHECK
cannot confirm (its band leaves the map: ``out_of_range``, or reaches heights that hold less)
would be burrowed and then found short. So the cheapest sufficient gait is judged once more
as CHECK will judge it, at its predicted pose, before it is chosen (``confirm``); what that
finds is kept per gait (``observe``), so a later plan counts on it without asking again.

The probability that a gait holds is read from the same normal model as its lower bound: per
tether angle the capacity is N(C0, sigma) (bound.py), and P(C >= required) = Phi((C0 -
required) / sigma); over the angles the smallest (a tug passes through all of them).

Units: SI inside (m, rad, N, J); degrees only in the gait's name and the event text.
"""
from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from statistics import NormalDist

from rftgls_core.planning.bound import GaitAnswer
from rftgls_core.planning.burrowed import BurrowedPose, burrowed_pose
from rftgls_core.planning.gait_map import GaitMap, for_sled, shipped_paths
from rftgls_core.planning.planner import plan_from_map
from rftgls_core.predictor import Predictor
from rftgls_core.types import AnchorState

from .gait_energy import GaitEnergyModel
from .model import H_BAND_SDS, AnchorMode, Candidate, Decision, EnergyModel, ModeChooser, versus


class PlanUnavailable(ValueError):
    """No gait map answers for this configuration (one line: why)."""


@dataclass(frozen=True)
class PlannedGait:
    """A gait as behavior_node runs it: retract and final (theta_L1, theta_L2), rad; speed,
    rad/s; the planner's answer (predicted pose, lower bound, energy) at the plan's
    confidence; p_hold: the probability that it holds the required pull."""

    name: str
    retract: tuple[float, float]
    final: tuple[float, float]
    speed: float
    answer: GaitAnswer
    p_hold: float
    pose: BurrowedPose     # the modelled burrowed pose and its band (planning.burrowed)

    def report(self, phis: Sequence[float]) -> dict:
        """The chosen gait for the events and the report: the planner's JSON and p_hold."""
        d = self.answer.to_json(tuple(phis))
        d.pop('per_phi', None)
        d['gait'] = self.name
        d['p_hold'] = self.p_hold
        return d


def gait_name(answer: GaitAnswer) -> str:
    """'SH' for a paper mode, else 'g<retract l1>/<l2>><final l1>/<l2>' in whole degrees
    (no comma: the name goes into the report's CSV)."""
    g = answer.gait
    if g.name:
        return g.name
    r = [round(math.degrees(a)) for a in (*g.retract, *g.final)]
    return f'g{r[0]}/{r[1]}>{r[2]}/{r[3]}'


def sled_map(robot: str, sled_kg: float, paths: Iterable[Path] | None = None) -> GaitMap:
    """The shipped gait map built for this sled (kg); PlanUnavailable naming the sleds there
    are maps for when none matches."""
    gmap, kgs = for_sled(sled_kg, shipped_paths(robot) if paths is None else paths)
    if gmap is not None:
        return gmap
    found = [f'{1e3 * kg:.0f} g' for kg in kgs]
    raise PlanUnavailable(
        f"burrow_modes 'planned': no gait map for a {1e3 * sled_kg:.0f} g sled (the gait maps "
        f"are per sled; shipped for {robot}: {', '.join(found) or 'none'}); use 'table_ii' or "
        "build one with `rftgls plan build-map`")


def p_hold(answer: GaitAnswer, required: float, scale: float = 1.0) -> float:
    """P(capacity x scale >= required) under the gait's normal model, the smallest over its
    tether angles (0 without a value)."""
    if not answer.per_phi or not answer.candidate:
        return 0.0
    ps = []
    for c0, sigma, _ in answer.per_phi:
        c0, sigma = c0 * scale, sigma * scale
        if not math.isfinite(c0):
            return 0.0
        if not (sigma > 0.0):
            ps.append(1.0 if c0 >= required else 0.0)
        else:
            ps.append(1.0 - NormalDist(c0, sigma).cdf(required))
    return min(ps)


class GaitChooser(ModeChooser):
    """A ModeChooser whose candidates are the gait map's gaits (module doc). ``modes`` holds
    the gaits chosen so far as AnchorModes (name -> predicted pose and band), so the machine's
    pose check, the height it publishes and capacity queries read them as a Table II mode;
    ``gaits`` the same gaits with their plan."""

    def __init__(self, predictor: Predictor, gait_map: GaitMap, safety_factor: float = 1.0,
                 phis: Sequence[float] = (0.0, math.radians(-20.0)), confidence: float = 0.95,
                 pull: str = 'backward'):
        super().__init__(predictor, safety_factor, phis, pull=pull)
        self.modes = {}     # its own: the gaits chosen (never the Table II table)
        self.gait_map = gait_map
        self.confidence = confidence
        self.gaits: dict[str, PlannedGait] = {}
        # The smallest lower bound (N, unscaled) capacity_node's predictor gave each gait, at
        # its predicted pose (confirm) or burrowed (CHECK).
        self.observed: dict[str, float] = {}
        self.confirmed: set[str] = set()    # gaits judged at their predicted pose already
        missing = [p for p in self.phis if not any(abs(p - q) < 1e-9 for q in gait_map.phis)]
        if missing:
            raise PlanUnavailable(
                f"burrow_modes 'planned': the gait map holds tether angles "
                f"{[round(math.degrees(q), 1) for q in gait_map.phis]} deg, not "
                f"{[round(math.degrees(p), 1) for p in missing]} (phis_rad)")

    def energy_model(self, prior: EnergyModel) -> GaitEnergyModel:
        """An energy model over the gaits (gait_energy.py): each gait's predicted electrical
        energy (J) is its prior, corrected by the burrows measured at it and near it."""
        cands = [a for a in self._answers() if a.candidate and a.energy_elec_J is not None]
        return GaitEnergyModel(prior_sh=1.0, alpha=prior.alpha,
                               ratios={gait_name(a): float(a.energy_elec_J) for a in cands},
                               gaits={gait_name(a): a.gait.as_array()[:4] for a in cands})

    def observe(self, mode: str, lower: float) -> None:
        """Keep a lower bound seen for a burrowed gait at its measured pose (N: the pose
        check's or capacity_node's live one): a later plan counts on the smaller of it and the
        planner's, so a gait found short is not chosen again for a need it does not cover."""
        if math.isfinite(lower):
            self.observed[mode] = min(lower, self.observed.get(mode, math.inf))

    def confirm(self, c: Candidate, answer: GaitAnswer, need: float,
                stronger_than: float | None = None) -> Candidate:
        """The candidate judged as CHECK will judge it (module doc): the lower bound of the
        chooser's predictor over the predicted pose's height band (``evaluate``), folded into
        the planner's (the smaller counts) and kept for later plans. A candidate whose
        questions went unanswered comes back insufficient with its `stale` statuses (missing
        evidence, not a weak gait: nothing kept) and without a lower bound, which is how
        ``choose`` tells it from a gait found short."""
        pose = burrowed_pose(answer, f'burrow simulation of gait {c.mode} (planner)')
        if pose is None:
            return replace(c, sufficient=False, why='the plan has no predicted pose')
        state = AnchorState(pose.h_m, pose.theta_b_rad, *answer.gait.final)
        e = self.evaluate(c.mode, state, need, c.energy_j, pose.h_band_m)
        if e.weakest is None:       # no bound at all: the planner's number is not kept either
            return replace(c, statuses=e.statuses, weakest=None, sufficient=False, why=e.why)
        self.confirmed.add(c.mode)
        if self.scale > 0.0:
            self.observe(c.mode, e.weakest / self.scale)
        caps = tuple(min(a, b) for a, b in zip(c.capacities, e.capacities))
        lower = min(caps)
        required = self.required(need)
        ok = lower >= required and (stronger_than is None or lower > stronger_than)
        why = (f'lower bound {versus(lower, required)} (planner {c.weakest:.2f} N, '
               f'capacity_node at the predicted pose {e.weakest:.2f} N)')
        if lower < required and 'no value' in e.why:
            why += e.why[e.why.index(':'):]
        elif lower >= required and not ok:
            why = f'not stronger than {stronger_than:.2f} N: ' + why
        return replace(c, capacities=caps, weakest=lower, sufficient=ok, why=why)

    def _answers(self) -> list[GaitAnswer]:
        return plan_from_map(self.gait_map, self.phis, 0.0, self.confidence).answers

    def choose(self, need: float, energy: EnergyModel, states=None,
               exclude: Iterable[str] = (), stronger_than: float | None = None,
               pose: str = 'expected') -> Decision:
        """The cheapest gait whose lower bound x scale covers ``required(need)`` (and is
        above ``stronger_than``, N, after a stop), not in ``exclude``. Energies from
        ``energy`` (the predicted energy scaled by the measured ones). ``states`` is unused:
        a gait's pose is its prediction."""
        required = self.required(need)
        plan = plan_from_map(self.gait_map, self.phis, required / self.scale, self.confidence)
        excluded = set(exclude)
        cands: list[tuple[Candidate, GaitAnswer]] = []
        for a in plan.answers:
            if not a.candidate:
                continue
            name = gait_name(a)
            seen = self.observed.get(name, math.inf)
            lower = min(a.lower_bound_N or 0.0, seen) * self.scale
            caps = tuple(min(lo, seen) * self.scale for _, _, lo in a.per_phi)
            e = energy.estimate(name) if name in energy.ratios else float(a.energy_elec_J or 0)
            ok, why = lower >= required, f'lower bound {versus(lower, required)}'
            if ok and name in excluded:
                ok, why = False, 'excluded: ' + why
            elif ok and stronger_than is not None and lower <= stronger_than:
                ok, why = False, f'not stronger than {stronger_than:.2f} N'
            cands.append((Candidate(name, caps, tuple('ok' for _ in caps), lower, e, ok, why,
                                    (a.capacity_N or 0.0) * self.scale), a))
        # The cheapest sufficient gait, confirmed as CHECK will judge it; one that is not
        # stays in the table with the reason, and the next cheapest is tried.
        confirmed: set[int] = set()
        while True:
            ok = [(i, c, a) for i, (c, a) in enumerate(cands) if c.sufficient]
            best = min(ok, key=lambda ica: (ica[1].energy_j, -(ica[1].weakest or 0.0)),
                       default=None)
            if best is None or best[1].mode in self.confirmed:
                break
            i, c, a = best
            cands[i] = (self.confirm(c, a, need, stronger_than), a)
            confirmed.add(id(a))
            if cands[i][0].weakest is None:          # unanswered: wait for the evidence
                return Decision(None, need, self.safety_factor, self.phis, (cands[i][0],),
                                f'{c.mode}: {cands[i][0].why}', 'planned', self.tug_ratio)
        pick = (best[1], best[2]) if best is not None else None
        # Shown in the decision: the Pareto front, the gaits confirmed now and the pick.
        front = {id(a) for a in plan.front}
        shown = tuple(c for c, a in cands if id(a) in front or id(a) in confirmed
                      or (pick and c is pick[0]))
        phis_txt = '/'.join(f'{math.degrees(p):.0f}' for p in self.phis)
        if pick is None:
            best = max((c for c, _ in cands), key=lambda c: c.weakest or 0.0, default=None)
            reason = (f'no planned gait suffices: need {need:.2f} N x {self.safety_factor:.2f}'
                      f' / {self.tug_ratio:.2f} (scale {self.scale:.2f}) at '
                      f'{self.confidence:.0%} over phi {phis_txt} deg'
                      + (f', strongest {best.mode} has a lower bound of {best.weakest:.2f} N'
                         if best else ''))
            return Decision(None, need, self.safety_factor, self.phis, shown, reason, 'planned',
                            self.tug_ratio)
        pick, answer = pick
        pose = burrowed_pose(answer, f'burrow simulation of gait {pick.mode} (planner)')
        if pose is None:     # a candidate has a nominal pose; refuse rather than guess one
            return Decision(None, need, self.safety_factor, self.phis, shown,
                            f'{pick.mode}: the plan has no predicted pose', 'planned',
                            self.tug_ratio)
        gait = PlannedGait(pick.mode, answer.gait.retract, answer.gait.final, answer.gait.speed,
                           answer, p_hold(answer, required, self.scale), pose)
        self.gaits[pick.mode] = gait
        # AnchorMode states its band in standard deviations (H_BAND_SDS of h_sd).
        self.modes[pick.mode] = AnchorMode(pick.mode, gait.retract, gait.final, pose.h_m,
                                           pose.theta_b_rad, 1.0, pose.h_band_m / H_BAND_SDS)
        reason = (f'{pick.mode}: cheapest sufficient planned gait ({pick.energy_j:.2f} J, '
                  f'{energy.source(pick.mode)}'
                  f'); lower bound {pick.weakest:.2f} N >= {self.safety_factor:.2f} x '
                  f'{need:.2f} N / {self.tug_ratio:.2f} at {self.confidence:.0%}, holds with p '
                  f'{gait.p_hold:.3f}; '
                  f'predicted h {1e3 * pose.h_m:.1f} +- {1e3 * pose.h_band_m:.1f} mm, pitch '
                  f'{math.degrees(pose.theta_b_rad):.1f} deg')
        return Decision(pick.mode, need, self.safety_factor, self.phis, shown, reason,
                        'planned', self.tug_ratio)
