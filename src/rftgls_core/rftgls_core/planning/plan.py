"""The plan: which gaits are worth running, and the cheapest that holds the need.

Candidates are the gaits with a value (bound.GaitAnswer.candidate). The Pareto front is the
set of candidates no other candidate beats on both counts: a lower bound at least as high for
no more electrical energy (one strictly better). The chosen gait is the cheapest candidate
whose lower bound covers the need (ties: the higher lower bound); it is on the front by
construction (a gait that beat it on both counts would cover the need for less energy). The
paper's modes (DH, DL, SH) are listed with their own answers and where they lie: on the front,
dominated, or no candidate.

No gait covering the need is an answer too: status `unsupported`, reason `need_not_covered`,
with the strongest lower bound found; the command exits 1 (docs/cli.md), and no gait is
offered as if it held.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..types import Status
from .bound import GaitAnswer


@dataclass
class Plan:
    status: str
    reason: str
    need_N: float
    level: float
    phis: tuple[float, ...]
    chosen: GaitAnswer | None
    front: list[GaitAnswer]
    modes: dict[str, GaitAnswer]
    answers: list[GaitAnswer]
    source: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.chosen is not None

    def mode_place(self, a: GaitAnswer) -> str:
        if not a.candidate:
            return 'no_candidate'
        if any(a is f for f in self.front):
            return 'on_front'
        return 'dominated'

    def to_json(self) -> dict:
        import math
        phis = self.phis
        modes = {}
        for name, a in self.modes.items():
            d = a.to_json(phis)
            d['place'] = self.mode_place(a)
            modes[name] = d
        rejected = [a.to_json(phis) for a in self.answers if not a.candidate]
        return {'status': self.status, 'reason': self.reason, 'need_N': self.need_N,
                'confidence': self.level, 'phi_deg': [math.degrees(p) for p in phis],
                'chosen': None if self.chosen is None else self.chosen.to_json(phis),
                'front': [a.to_json(phis) for a in self.front], 'modes': modes,
                'candidates': sum(a.candidate for a in self.answers),
                'not_candidates': rejected, 'source': self.source}


def dominates(a: GaitAnswer, b: GaitAnswer) -> bool:
    """a is at least as strong for no more energy, and strictly better in one."""
    assert a.lower_bound_N is not None and b.lower_bound_N is not None
    assert a.energy_elec_J is not None and b.energy_elec_J is not None
    return (a.lower_bound_N >= b.lower_bound_N and a.energy_elec_J <= b.energy_elec_J
            and (a.lower_bound_N > b.lower_bound_N or a.energy_elec_J < b.energy_elec_J))


def pareto_front(answers: list[GaitAnswer]) -> list[GaitAnswer]:
    """The non-dominated candidates, cheapest first."""
    cands = [a for a in answers if a.candidate]
    front = [a for a in cands if not any(dominates(b, a) for b in cands if b is not a)]
    return sorted(front, key=lambda a: (a.energy_elec_J, -(a.lower_bound_N or 0.0)))


def make_plan(answers: list[GaitAnswer], need_N: float, level: float,
              phis: tuple[float, ...]) -> Plan:
    """The plan for a need (N) from every gait's answer (module doc)."""
    front = pareto_front(answers)
    covering = [a for a in front if (a.lower_bound_N or 0.0) >= need_N]
    modes = {a.gait.name: a for a in answers if a.gait.name}
    if covering:
        chosen = min(covering, key=lambda a: (a.energy_elec_J, -(a.lower_bound_N or 0.0)))
        return Plan(Status.ASSUMED.value, 'assumed inputs: the pose is modelled (the burrow '
                    'simulation), the medium and servo spreads are as stated in the inputs',
                    need_N, level, phis, chosen, front, modes, answers)
    best = max((a.lower_bound_N or 0.0 for a in front), default=None)
    n = sum(a.candidate for a in answers)
    why = (f'no gait of {len(answers)} has a lower bound at {level:.0%} confidence covering '
           f'{need_N:.3g} N: ' + (f'the strongest candidate holds {best:.3g} N'
                                  if best is not None else 'no gait is a candidate')
           + f' ({n} candidates; the others overturned, stopped or lost their capacity)')
    return Plan(Status.UNSUPPORTED.value, f'need_not_covered: {why}', need_N, level, phis,
                None, front, modes, answers)
