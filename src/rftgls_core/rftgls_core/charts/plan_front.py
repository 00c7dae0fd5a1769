"""The burrow plan as a picture: every candidate gait's lower-bound capacity against its
predicted electrical energy, the Pareto front, the need, the chosen gait and the paper's
DH, DL and SH (planning/plan.py)."""
from __future__ import annotations

from pathlib import Path

from .figure_io import pyplot, save


def plot_front(plan, path: str | Path, title: str = '') -> Path:
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(7.0, 4.8))
    cands = [a for a in plan.answers if a.candidate]
    ax.scatter([a.energy_elec_J for a in cands], [a.lower_bound_N for a in cands], s=18,
               color='0.65', label=f'candidate gaits ({len(cands)})', zorder=2)
    front = sorted(plan.front, key=lambda a: a.energy_elec_J)
    if front:
        ax.step([a.energy_elec_J for a in front], [a.lower_bound_N for a in front],
                where='post', color='tab:blue', lw=1.5, zorder=3,
                label=f'Pareto front ({len(front)})')
        ax.scatter([a.energy_elec_J for a in front], [a.lower_bound_N for a in front], s=28,
                   color='tab:blue', zorder=4)
    ax.axhline(plan.need_N, color='tab:red', ls='--', lw=1.0,
               label=f'need {plan.need_N:.3g} N')
    if plan.chosen is not None:
        c = plan.chosen
        ax.scatter([c.energy_elec_J], [c.lower_bound_N], marker='*', s=220, color='gold',
                   edgecolor='k', zorder=6, label=f'chosen {c.gait.to_json()["retract_deg"]}'
                   f' -> {c.gait.to_json()["final_deg"]} deg')
    absent = []
    for (name, a), colour in zip(sorted(plan.modes.items()),
                                 ('tab:green', 'tab:purple', 'tab:orange')):
        if a.candidate:
            ax.scatter([a.energy_elec_J], [a.lower_bound_N], marker='D', s=60, color=colour,
                       edgecolor='k', zorder=5, label=f'{name} ({plan.mode_place(a)})')
            ax.annotate(name, (a.energy_elec_J, a.lower_bound_N), xytext=(6, 6),
                        textcoords='offset points', fontsize=9)
        else:
            absent.append(f'{name}: {a.status} ({a.reason.split(":")[0]})')
    ax.set_xlabel('predicted electrical energy of the burrow, J (standby removed)')
    ax.set_ylabel(f'lower bound at {plan.level:.0%}, N (weakest tether angle)')
    head = title + (': ' if title else '') + ('plan ' + plan.status)
    if absent:
        head += '\nno candidate: ' + '; '.join(absent)
    ax.set_title(head, fontsize=9)
    ax.grid(True, alpha=0.3)
    ax.set_ylim(bottom=0.0)
    ax.legend(fontsize=8, loc='best')
    save(fig, path)
    return Path(path)
