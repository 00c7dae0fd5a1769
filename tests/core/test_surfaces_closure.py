"""Capacity through the closure of a discontinuous twist -> wrench map.

RFT's wrench jumps where a facet switches between trailing and leading; at the switch the
facet may carry any fraction of its leading stress (a set-valued closure, like Coulomb
friction at zero slip). The capacity is the first exit of the load ray from that closure.
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from rftgls_core.cli.demo import ANCHOR_MODES
from rftgls_core.predictor.live import RobotPredictor
from rftgls_core.rft.media import get_medium
from rftgls_core.robots.presets import get_robot
from rftgls_core.surfaces import DirectSurface, GLSProblem, Scaling, TwistMeshSurface
from rftgls_core.surfaces.brute_force import BruteForceSurface
from rftgls_core.types import AnchorState, Pull, Status

JUMP = 1.0


def _jump_wrench(t: np.ndarray) -> np.ndarray:
    """Unit sphere W = t, with its t1 < 0 half pushed out by JUMP along -w1: the face that
    resists t1 < 0 switches on at t1 = 0 (a great circle), like a flat face of a box."""
    t = t / np.linalg.norm(t, axis=1, keepdims=True)
    w = t.copy()
    w[:, 0] -= JUMP * (t[:, 0] < 0.0)
    return w


JUMP_PROBLEM = GLSProblem(_jump_wrench, Scaling(1.0, 1.0))


def _exact(phi: float) -> tuple[float, np.ndarray]:
    """The capacity worked out on paper, and the slip twist.

    The ray s d, d = (-cos phi, sin phi, 0), s > 0. The closure at the switch t1 = 0 is the band
    {(-lambda JUMP, t2, t3): t2^2 + t3^2 = 1, lambda in [0, 1]}. The ray meets it at t3 = 0,
    t2 = sign(phi), so s sin|phi| = 1 and lambda = cot|phi| / JUMP, which lies in [0, 1] when
    |phi| >= arccot(JUMP): there s = 1 / sin|phi| with the slip twist (0, sign(phi), 0) on the
    switching circle. At smaller |phi| the ray leaves through the pushed-out half sphere
    |w + JUMP e1| = 1: s^2 - 2 s JUMP cos(phi) + JUMP^2 - 1 = 0, twist = w + JUMP e1.
    """
    if abs(phi) >= math.atan2(1.0, JUMP):
        return 1.0 / abs(math.sin(phi)), np.array([0.0, math.copysign(1.0, phi), 0.0])
    c = JUMP * math.cos(phi)
    s = c + math.sqrt(c * c - JUMP * JUMP + 1.0)
    w = s * np.array([-math.cos(phi), math.sin(phi), 0.0]) + [JUMP, 0.0, 0.0]
    return s, w / np.linalg.norm(w)


@pytest.mark.parametrize('surface', [DirectSurface(), TwistMeshSurface(1000)],
                         ids=lambda s: s.method)
@pytest.mark.parametrize('phi_deg', [-70.0, -50.0, 50.0, 60.0, 80.0, 20.0, -30.0])
def test_hand_built_jump_is_answered_on_the_closure(surface, phi_deg):
    phi = math.radians(phi_deg)
    cap, twist = _exact(phi)
    r = surface.fit(JUMP_PROBLEM).capacity(phi)
    assert r.status is Status.OK, r.detail
    assert r.capacity_N == pytest.approx(cap, rel=1e-6)
    angle = math.acos(min(1.0, float(np.dot(r.slip_twist_scaled, twist))))
    assert angle < 1e-4
    assert ('on_jump' in r.flags) == (abs(phi) > math.atan2(1.0, JUMP))


def test_brute_force_reference_agrees_on_the_jump():
    phis = np.radians([-70.0, -50.0, 20.0, 60.0])
    res = BruteForceSurface(20_000).fit(JUMP_PROBLEM).capacity_many(phis)
    for phi, r in zip(phis, res):
        assert r.status is Status.OK
        assert r.capacity_N == pytest.approx(_exact(phi)[0], rel=2e-3)


def test_refined_brute_force_is_exact_on_the_jump_and_bounds_its_error():
    # The paper-worked capacities above, to 1e-7: the local re-sampling converges onto the
    # bridged jump, and the error bound it reports covers its actual error.
    phis = np.radians([-70.0, -50.0, 20.0, 60.0])
    surface = BruteForceSurface(20_000).fit(JUMP_PROBLEM)
    res = surface.capacity_many(phis)
    for phi, r, bound in zip(phis, res, surface.errors_N_):
        exact = _exact(phi)[0]
        assert r.status is Status.OK and bound is not None
        assert r.capacity_N == pytest.approx(exact, rel=1e-7)
        assert abs(r.capacity_N - exact) <= bound + 1e-12 * exact


def test_uniform_mesh_underestimates_a_small_capacity_next_to_a_jump():
    # The prototype's worst state of `rftgls chart agreement` (seed 11): a capacity of 4 % of
    # the weight next to a jump ~8 times larger. The bare 10^5-twist mesh says 0.0435 N (its
    # straddling triangles' vertices lie up to one spacing off the switching circle); the
    # local re-sampling, independent of direct's Newton and closure search, converges to
    # direct's 0.0506 N within its own error bound.
    state = AnchorState(0.027857058898804875, 0.34003298354550077, 0.07368837271823292,
                        -0.49621527415977335)
    phi, pull = math.radians(-11.402250958905148), Pull.FORWARD
    robot, medium = get_robot('prototype'), get_medium('glass_beads')
    bare = RobotPredictor(robot, medium, method='brute-force',
                          surface_options={'refine': False}).predict(state, phi, pull)
    predictor = RobotPredictor(robot, medium, method='brute-force')
    surface, _ = predictor.fit(state, pull)
    assert isinstance(surface, BruteForceSurface)
    ref = surface.capacity(phi)
    bound = surface.errors_N_[0]
    d = RobotPredictor(robot, medium, method='direct').predict(state, phi, pull)
    assert bare.capacity_N is not None and bare.capacity_N < 0.046
    assert bound is not None and bound < 1e-4
    assert ref.capacity_N == pytest.approx(d.capacity_N, abs=bound + 1e-5)
    assert ref.capacity_N > bare.capacity_N + 0.006


@pytest.fixture(scope='module')
def prototype_direct():
    return RobotPredictor(get_robot('prototype'), get_medium('glass_beads'), method='direct')


def test_direct_answers_every_state_of_the_fig9_grid(prototype_direct):
    # The paper's Fig. 9 grid: h = 20 mm, thetaB = 0, thetaL1, thetaL2 in -40:20:40 deg, both
    # pulls, phi = 0. Before the closure solver 8 of these 50 were `degenerate` (no_root).
    counts: dict[tuple[str, str], int] = {}
    for pull in Pull:
        for l1 in range(-40, 41, 20):
            for l2 in range(-40, 41, 20):
                r = prototype_direct.predict(AnchorState.from_degrees(0.02, 0, l1, l2), 0.0, pull)
                counts[(r.status.value, r.reason)] = counts.get((r.status.value, r.reason), 0) + 1
                assert r.status in (Status.OK, Status.UNSUPPORTED), (pull, l1, l2, r.detail)
    assert counts.get(('ok', ''), 0) >= 45


def test_direct_answers_the_table2_poses():
    predictor = RobotPredictor(get_robot('minirquad'), get_medium('m90_sand'), method='direct')
    for mode, state in ANCHOR_MODES.items():
        for phi_deg in (0.0, -20.0):
            r = predictor.predict(state, math.radians(phi_deg), Pull.BACKWARD)
            assert r.status is Status.OK and r.capacity_N > 0, (mode, phi_deg, r.detail)


def test_grid_centre_matches_twist_mesh_and_brute_force(prototype_direct):
    # The state of the issue report: direct said `degenerate`, twist-mesh 4.35 N.
    state = AnchorState.from_degrees(0.02, 0, 0, 0)
    d = prototype_direct.predict(state, 0.0, Pull.BACKWARD)
    tm = RobotPredictor(get_robot('prototype'), get_medium('glass_beads')).predict(
        state, 0.0, Pull.BACKWARD)
    bf = RobotPredictor(get_robot('prototype'), get_medium('glass_beads'), method='brute-force',
                        n_twists=40_000).predict(state, 0.0, Pull.BACKWARD)
    assert d.status is tm.status is bf.status is Status.OK
    assert d.capacity_N == pytest.approx(tm.capacity_N, rel=1e-6)
    assert d.capacity_N == pytest.approx(bf.capacity_N, rel=0.01)


def test_twist_mesh_finds_the_thin_fold_its_polish_stepped_over():
    # Found by the refined reference (seed 11 of `rftgls chart agreement`): the 1,000-twist
    # chord (3.49 N) lies next to the exit, but the closure search from it settled on a sheet
    # at 3.65 N (+4.8 % above the reference). The fold check from a 2 % polish move finds it.
    state = AnchorState(0.0153437537105366, 0.019728332646528606, -0.0008246602076111284,
                        -0.5108521821067686)
    phi, pull = math.radians(-27.813277543926485), Pull.BACKWARD
    robot, medium = get_robot('prototype'), get_medium('glass_beads')
    tm = RobotPredictor(robot, medium).predict(state, phi, pull)
    surface, _ = RobotPredictor(robot, medium, method='brute-force').fit(state, pull)
    assert isinstance(surface, BruteForceSurface)
    ref = surface.capacity(phi)
    assert tm.capacity_N is not None and ref.capacity_N is not None
    assert surface.errors_N_[0] is not None and surface.errors_N_[0] < 1e-4
    assert ref.capacity_N == pytest.approx(3.478, abs=2e-3)
    assert tm.capacity_N <= 1.02 * ref.capacity_N


def test_a_bridged_jump_in_front_of_a_converged_root_is_the_exit():
    # Found by the refined reference (seed 12 of `rftgls chart agreement`): Newton converges
    # to a smooth root at 0.0222 N while the ray crosses a bridged jump 0.3 deg away at
    # 0.0125 N (the refined brute force, at 10^5 and 4 10^5 twists; a jittered Delaunay
    # sampling of the twist plane agrees). The local closure check finds it (twist-mesh:
    # local_check, on by default since the shipped maps were rebuilt with it).
    state = AnchorState(0.013086723444173564, 0.1928445993016025, 0.5406865480075519,
                        -0.21615652201508126)
    phi, pull = math.radians(-18.439385650570934), Pull.FORWARD
    robot, medium = get_robot('prototype'), get_medium('glass_beads')
    surface, _ = RobotPredictor(robot, medium, method='brute-force').fit(state, pull)
    assert isinstance(surface, BruteForceSurface)
    ref = surface.capacity(phi)
    assert ref.capacity_N is not None and surface.errors_N_[0] is not None
    assert ref.capacity_N == pytest.approx(0.01247, abs=1e-4)
    floor = 0.05 * robot.mass * 9.81
    tm_off = RobotPredictor(robot, medium, surface_options={'local_check': False}).predict(
        state, phi, pull)
    assert tm_off.capacity_N == pytest.approx(0.02223, abs=1e-4)   # without the check
    for method, options in (('direct', {}), ('twist-mesh', {})):
        r = RobotPredictor(robot, medium, method=method,
                           surface_options=options).predict(state, phi, pull)
        assert r.status is Status.OK and r.capacity_N is not None
        assert r.capacity_N - ref.capacity_N <= 0.02 * max(ref.capacity_N, floor), method
        assert 'on_jump' in r.flags, method


def _reference(robot, medium, state, pull, phi):
    """The refined brute-force reference (surfaces/brute_force.py) and its own error bound."""
    surface, _ = RobotPredictor(robot, medium, method='brute-force').fit(state, pull)
    assert isinstance(surface, BruteForceSurface)
    ref = surface.capacity(phi)
    assert ref.capacity_N is not None and surface.errors_N_[0] is not None
    return ref.capacity_N, surface.errors_N_[0]


# States of `rftgls chart agreement` where the solvers were above the refined reference.
# Reference values: the refined brute force (surfaces/brute_force.py: 10^5 twists, 7
# refinement levels; its wrench at the exit twist lies on the ray), computed in the test.
REFERENCE_CASES = {
    # Seed 12, prototype. Newton fails, the closure search settled on a bridged jump at
    # 0.5383 N (+2.29 %), while a smooth root 0.0017 rad away maps onto the ray at 0.5263 N:
    # closure.jump_exit (finer turned patches) finds it in both solvers.
    'nearer_exit_next_to_a_closure_search_exit': (
        'prototype',
        (0.028814037573832718, -0.10116126625415003, 0.686137081512544, -0.512366879517691),
        -26.612049950788755, Pull.FORWARD, 0.52628, 1e-4, 1e-5),
    # Seed 12, prototype. The polish went to 2.346 N, one round of the thin-fold check to a
    # sheet at 2.162 N (+7.1 %); the exit is 2.018 N (direct agrees), which a second round of
    # the check, from 2.162 N, finds.
    'fold_check_repeated_from_the_sheet_it_found': (
        'prototype',
        (0.029321129702412903, -0.0059799998954231555, 0.36801426966898276,
         -0.5692593847565214),
        -21.10218733949822, Pull.BACKWARD, 2.0180, 1e-3, 1e-4),
    # Seed 14, MiniRQuad. Both solvers stopped at 1.781 N (+24 %): the exit is on a fold sheet
    # ~0.03 rad wide, 9 deg from that root, which the 0.25 rad fold patch (spacing 0.042 rad)
    # missed; the 0.6-scale turned patches see it.
    'narrow_fold_sheet_seen_by_the_smaller_turned_patches': (
        'minirquad',
        (0.04105407926698655, 0.013400783355462229, -0.8272028290640885, 0.3415892270325489),
        -20.231490737407455, Pull.BACKWARD, 1.43228, 1e-4, 1e-6),
    # Seed 15, prototype: twist-mesh polished 1.7 % (6.059 -> 6.165 N) and 1.1 % (a closure
    # exit, 2.571 -> 2.600 N) beyond its chord, under the 2 % that started its fold check,
    # and stopped +4.7 % and +3.2 % above the exits (direct's own seeds found them); the
    # fold check now starts at a 1 % move.
    'fold_check_from_a_1_7_percent_polish_move': (
        'prototype',
        (0.006711511477798594, -0.20203154797099102, 0.3511530423702217, -0.21353805445661406),
        -19.44030564135483, Pull.BACKWARD, 5.880888, 1e-5, 1e-6),
    # A MiniRQuad map node (h = 25 mm, thetaB = 5, thetaL1 = -60, thetaL2 = 10 deg, backward,
    # phi = -30 deg): direct's Newton root 2.874 N lay 3.2 % beyond its 400-twist chord, under
    # the 5 % that started its fold check; the exit is 2.238 N (+28 %). direct now starts the
    # check at 3 % (DIRECT_FOLD_CHECK_RTOL), twist-mesh at 1 %.
    'direct_fold_check_from_a_3_percent_move': (
        'minirquad', (0.025, 0.08726646259971647, -1.0471975511965976, 0.17453292519943295),
        -30.0, Pull.BACKWARD, 2.23772, 1e-4, 1e-5),
    'fold_check_from_a_1_1_percent_closure_exit': (
        'prototype',
        (0.019390959339445756, 0.15341181344014113, 0.38337310936955843, -0.43802136564142724),
        -29.227897926563884, Pull.BACKWARD, 2.518984, 1e-5, 1e-5),
}


@pytest.mark.parametrize('case', sorted(REFERENCE_CASES))
def test_states_that_were_above_the_reference_now_land_on_it(case):
    name, state, phi_deg, pull, expected, tol, err_max = REFERENCE_CASES[case]
    state, phi = AnchorState(*state), math.radians(phi_deg)
    robot = get_robot(name)
    medium = get_medium('glass_beads' if name == 'prototype' else 'm90_sand')
    ref, err = _reference(robot, medium, state, pull, phi)
    assert ref == pytest.approx(expected, abs=tol) and err < err_max
    floor = 0.05 * robot.mass * 9.81
    for method in ('direct', 'twist-mesh'):
        r = RobotPredictor(robot, medium, method=method).predict(state, phi, pull)
        assert r.status is Status.OK and r.capacity_N is not None
        assert abs(r.capacity_N - ref) <= 1e-3 * max(ref, floor), method


def test_twist_mesh_local_checks_do_not_skip_the_fold_check():
    # A node of the shipped prototype map (h = 5 mm, thetaB = -20, thetaL1 = 20, thetaL2 = -40
    # deg, backward, phi = 10 deg): the polish converges on a sheet at 5.614 N, the thin-fold
    # check from there finds the exit at 5.158 N (the refined brute force computed here agrees).
    # Run before it, the local closure check moved the answer to 5.451 N, close enough to the
    # chord that the fold check was skipped (+5.7 %); the checks now run after it.
    state = AnchorState.from_degrees(0.005, -20, 20, -40)
    phi, pull = math.radians(10.0), Pull.BACKWARD
    robot, medium = get_robot('prototype'), get_medium('glass_beads')
    ref, err = _reference(robot, medium, state, pull, phi)
    assert ref == pytest.approx(5.1585, abs=1e-3) and err < 1e-4
    r = RobotPredictor(robot, medium, n_twists=1000).predict(state, phi, pull)   # the maps' setting
    assert r.capacity_N is not None
    assert abs(r.capacity_N - ref) <= 1e-3 * ref
