"""`plan_burrow`: the whole plan, from a gait map when one answers for the inputs, else from
the live simulation (the same runs, computed now: build_gait_map in memory)."""
from __future__ import annotations

import time
from pathlib import Path

from ..maps.errors import MapFileError
from .bound import answer
from .gait_map import GaitMap, build_gait_map, load, shipped_paths
from .gaits import SHIPPED_GRID, GaitPoint, with_modes
from .plan import Plan, make_plan
from .predict import PlanInputs


def gait_space() -> list[GaitPoint]:
    """The gaits a plan searches: the shipped grid and the paper's modes."""
    return with_modes(SHIPPED_GRID.gaits())


def find_map(inputs: PlanInputs, path: str | Path | None) -> tuple[GaitMap | None, str]:
    """The gait map to answer from and why: the given file (MapFileError when it is unreadable
    or does not answer for these inputs: the user asked for it), or the robot's shipped one
    (None and why when it does not answer: the plan is then simulated live)."""
    if path is not None:
        gmap = load(path)
        why = gmap.answers_for(inputs)
        if why is not None:
            raise MapFileError(f'{path} does not answer for these inputs: {why}')
        return gmap, f'gait map {path}'
    shipped = [] if inputs.anchor else shipped_paths(inputs.robot)
    if not shipped:
        return None, 'no gait map given or shipped for this robot'
    whys = []
    for p in shipped:
        gmap = load(p)
        why = gmap.answers_for(inputs)
        if why is None:
            return gmap, f'shipped gait map {p.name}'
        whys.append(f'{p.name} {why}')
    return None, 'no shipped gait map answers: ' + '; '.join(whys)


def plan_burrow(inputs: PlanInputs, need_N: float, level: float, *,
                map_path: str | Path | None = None, live: bool = False,
                gaits: list[GaitPoint] | None = None, workers: int | None = 1,
                progress: bool = False) -> Plan:
    """The plan for a need (N) at one-sided confidence `level`; `live` skips the maps."""
    t0 = time.perf_counter()
    gmap, why = (None, 'live asked (--live)') if live else find_map(inputs, map_path)
    if gmap is None:
        gmap = build_gait_map(inputs, gaits or gait_space(), workers=workers,
                              progress=progress)
        source = {'kind': 'live', 'why': why}
    else:
        source = {'kind': 'map', 'file': why, 'content_sha256': gmap.attrs['content_sha256']}
    source['inputs_sha256'] = inputs.inputs_sha256()
    plan = plan_from_map(gmap, inputs.phis, need_N, level)
    plan.source = {**source, 'elapsed_s': time.perf_counter() - t0}
    return plan


def plan_from_map(gmap: GaitMap, phis, need_N: float, level: float) -> Plan:
    """The onboard plan: every gait's answer from its stored runs, then the front."""
    answers = [answer(g, r, level) for g, r in zip(gmap.gaits(), gmap.runs(phis))]
    return make_plan(answers, need_N, level, tuple(phis))
