"""Compile the stack's numba kernels for this machine before a run needs them.

numba compiles a kernel at its first call and keeps it in its cache (rftgls_core/numba_cache.py:
one folder per version of the sources, shared by every process). On a fresh machine nothing is
cached, and the first calls land in the middle of a run: capacity_node's first live estimate
compiled for 10 s on an idle core (5 s more for the warm path), 25 s in the first tug of a
fresh `make demo`, where behavior_node saw its evidence age past the 60 ms timeout and aborted
the tug; the simulator's physics body and behavior_node's burrow replay compile the whole-robot
simulation at their first step. ``warm_up`` calls each of those paths once, before any node
starts: slow only on a machine's first run, ~1 s (loading from the cache) after that.
capacity_node also warms its own solvers at start-up (``warm_up_solvers``, the same
``warm_up_predictor``); after this it loads them from the cache in ~0.3 s, so the demo's
walk and burrow never wait on a compile inside the node.
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from rftgls_core.multibody.robot import from_preset
from rftgls_core.multibody.simulate import Simulator
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot

from .capacity.node_predictor import predictor_from_params, warm_up_predictor
from .capacity.params import PARAMETERS
from .launch_check import file_sections


def capacity_parameters(params_file: Path | None) -> dict:
    """capacity_node's parameters: its defaults, then the ``ros__parameters`` of the node's
    sections in params_file (a ROS 2 parameter file: ``capacity_node``, ``/**/capacity_node``,
    ``/**``) if given."""
    p = {name: spec.default for name, spec in PARAMETERS.items()}
    if params_file is not None:
        for section in file_sections(Path(params_file), 'capacity_node'):
            p.update(section)
    return p


def warm_up(params_file: Path | None, robot: str = 'minirquad') -> float:
    """Run capacity_node's live predictor (cold and warm) as params_file configures it, and
    settle the whole-robot simulation of the robot preset once. Returns the seconds taken."""
    t0 = time.perf_counter()
    p = capacity_parameters(params_file)
    warm_up_predictor(predictor_from_params(p), p['pull'])
    body = from_preset(get_robot(robot))
    Simulator(body, get_medium('m90_sand')).place(np.zeros(len(body.legs)))
    return time.perf_counter() - t0
