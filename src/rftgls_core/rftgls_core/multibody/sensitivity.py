"""One-at-a-time sensitivity of the predictions compared with the paper (Table II's h and
theta_B of DH, DL and SH, the burrow energy ratios DH/SH and DL/SH, the walking distance in
8 s) to the inputs that are not the paper's: the medium (xi_n, mu_surf), the servo's stall
torque, the leg mesh, the C-legs' orientation (which way the C opens is not in the paper) and
the centre of mass (assumed midway between the axles). Nothing is fitted: every run uses the
preset, the datasheet and the geometry, with one input changed. `rftgls simulate sensitivity
--out DIR` regenerates the JSON, the chart and the table.
"""
from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable

import numpy as np

from ..rft.media import get_medium
from ..robots.measured_burrows import MEASURED_BURROWS, MEASURED_ENERGY_RATIOS
from ..robots.presets import get_robot
from .gaits import TABLE_II_BURROWS, BurrowGait, WalkGait
from .robot import from_preset
from .servo import XL330_M077_5V
from .simulate import Simulator
from .sled import Sled

# mode -> (retract, final (theta_L1, theta_L2) deg, measured theta_B deg, measured h m)
TABLE_II = {m: (*TABLE_II_BURROWS[m], round(math.degrees(b.theta_b_rad), 6), b.h_m)
            for m, b in MEASURED_BURROWS['minirquad'].items()}
PAPER_RATIOS = {f'{m}/SH': MEASURED_ENERGY_RATIOS['minirquad'][m] for m in ('DH', 'DL')}
PAPER_WALK_M = 1.0 / 3.0      # ~1 m over three 8 s walks (Fig. 12)

# (label, parameter, values): the nominal run is shared; each value changes one input.
SWEEPS = (
    ('xi_n x', 'xi_scale', (0.5, 0.71, 1.41, 2.0)),
    ('mu_surf', 'mu_surf', (0.1, 0.25, 0.55, 0.7)),
    ('stall torque, N m', 'stall', (0.172, 0.18, 0.228, 0.258)),
    ('arc segments', 'n_arc', (12, 48)),
    ('centre of mass x, mm', 'com_dx_mm', (-10.0, 10.0)),
    ('C-leg orientation', 'pull', ('forward',)),
)
NOMINAL = {'xi_scale': 1.0, 'mu_surf': 0.4, 'stall': 0.215, 'n_arc': 24, 'pull': 'backward',
           'com_dx_mm': 0.0}


def predictions(params: dict, walk: bool = True, modes=tuple(TABLE_II),
                sled_kg: float | None = None) -> dict:
    """Every prediction for one set of inputs (NOMINAL with some replaced): the burrows of
    `modes`, each tied to a sled of sled_kg (None: no tether), and the walk."""
    p = {**NOMINAL, **params}
    base = get_medium('m90_sand')
    medium = dataclasses.replace(base, name=f'm90_sand x{p["xi_scale"]:g}',
                                 xi_n=base.xi_n * p['xi_scale'], zeta=base.zeta * p['xi_scale'],
                                 mu_surf=p['mu_surf'])
    servo = XL330_M077_5V.scaled(p['stall'] / XL330_M077_5V.stall_torque)
    robot = from_preset(get_robot('minirquad', int(p['n_arc'])), p['pull'])
    if p['com_dx_mm']:
        # the centre of mass (assumed midway between the axles) moved along x_B
        robot = dataclasses.replace(robot, com=robot.com + np.array([1e-3 * p['com_dx_mm'],
                                                                     0.0, 0.0]))
    out: dict = {'params': p}
    for mode in modes:
        retract, final, _, _ = TABLE_II[mode]
        gait = BurrowGait(robot, (0.0, 0.0), tuple(map(math.radians, retract)),
                          tuple(map(math.radians, final)))
        sled = None if sled_kg is None else Sled(sled_kg)
        res = Simulator(robot, medium, servo, sled=sled).run(gait)
        s = res.summary()
        out[mode] = {k: s.get(k) for k in ('h_m', 'theta_b_deg', 'energy_elec_J',
                                           'energy_mech_J', 'status', 'reason')}
        out[mode]['stalls'] = len(s['stalled'])
    e_sh = out['SH']['energy_elec_J'] if 'SH' in out else None
    for key in PAPER_RATIOS:
        mode = key.split('/')[0]
        e = out[mode]['energy_elec_J'] if mode in out else None
        out[key] = e / e_sh if e is not None and e_sh else None
    if walk:
        s = Simulator(robot, medium, servo).run(WalkGait(robot, duration=8.0)).summary()
        out['walk'] = {k: s.get(k) for k in ('distance_m', 'h_mean_m', 'energy_elec_J',
                                             'status', 'reason')}
    return out


def run_sweeps(walk: bool = True, progress: Callable[[str], None] | None = None,
               modes=tuple(TABLE_II), sled_kg: float | None = None) -> dict:
    """The nominal predictions and one run per swept value (burrows of `modes`, tied to a
    sled of sled_kg or untethered)."""
    if progress:
        progress('nominal')
    sweeps: list[dict] = []
    data = {'nominal': predictions({}, walk, modes, sled_kg), 'sweeps': sweeps,
            'modes': list(modes), 'sled_kg': sled_kg}
    for label, key, values in SWEEPS:
        for v in values:
            if progress:
                progress(f'{label} = {v}')
            sweeps.append({'label': label, 'param': key, 'value': v,
                                   'result': predictions({key: v}, walk, modes, sled_kg)})
    data['paper'] = {'table_ii': {m: {'theta_b_deg': t[2], 'h_m': t[3]}
                                  for m, t in TABLE_II.items()},
                     'energy_ratios': PAPER_RATIOS, 'walk_m_per_8s': PAPER_WALK_M}
    return data


def markdown_table(data: dict) -> str:
    """The sweeps as a Markdown table (theta_B and h per burrow, the energy ratios; a run that
    ended without a value shows its reason), as docs/design/walk-burrow-physics.md lists it."""
    modes = data.get('modes', list(TABLE_II))

    def cells(r: dict) -> list[str]:
        out = []
        for m in modes:
            x = r[m]
            out.append(x['reason'] if x['h_m'] is None else
                       f"{x['theta_b_deg']:.1f}°, {x['h_m'] * 1e3:.0f} mm")
        out += [f'{r[k]:.2f}' if r.get(k) is not None else '-' for k in PAPER_RATIOS]
        return out
    head = ['input'] + [f'{m} θB, h' for m in modes] + [f'E {k}' for k in PAPER_RATIOS]
    rows = [head, ['---'] * len(head), ['nominal'] + cells(data['nominal'])]
    rows += [[f"{s['label']} = {s['value']}"] + cells(s['result']) for s in data['sweeps']]
    return '\n'.join('| ' + ' | '.join(r) + ' |' for r in rows) + '\n'
