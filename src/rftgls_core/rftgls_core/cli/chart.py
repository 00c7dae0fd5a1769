"""`rftgls chart speed-accuracy`: time per query against error for every method and resolution."""
from __future__ import annotations

import csv
import io
import json
import sys
from pathlib import Path

from rftgls_conventions.safe_write import output_file, write_text

from .. import accuracy as acc
from ..charts.figure_io import figure_path
from ..charts.speed_accuracy import plot_speed_accuracy
from ..quantities import SEED, bounded_int
from .common import twist_count


def add_parser(sub) -> None:
    p = sub.add_parser('chart', help='charts: speed-accuracy (with coverage), agreement')
    p.add_argument('kind', choices=['speed-accuracy', 'agreement'],
                   help='speed-accuracy: every method and resolution against direct on the '
                        'finest leg mesh; agreement: direct and twist-mesh against the '
                        'brute-force closure reference (statuses and capacities)')
    p.add_argument('--out', required=True, help='PNG file (agreement: JSON file); the numbers '
                                                 'go next to it (.csv, .json)')
    p.add_argument('--states', type=bounded_int(1, 10_000, 'state count'), default=10,
                   help='random states per robot')
    p.add_argument('--robots', nargs='+', default=['prototype', 'minirquad'],
                   choices=sorted(acc.STATE_RANGES))
    p.add_argument('--seed', type=SEED, default=0)
    p.add_argument('--quick', action='store_true', help='fewer configurations (for tests)')
    p.add_argument('--reference-twists', type=twist_count, default=100_000,
                   help='agreement: twists of the brute-force reference')
    p.add_argument('--json', action='store_true', help='also print the numbers as JSON')
    p.set_defaults(run=run)


def run(args) -> int:
    from tqdm import tqdm

    # What --out means is checked before any work (never a folder; the numbers go beside it).
    args.out = (output_file(args.out, '--out', ('.json',)) if args.kind == 'agreement'
                else figure_path(args.out))
    if args.kind == 'agreement':
        return _agreement(args, tqdm)
    configs = list(acc.DEFAULT_CONFIGS)
    if args.quick:
        configs = [acc.Config('twist-mesh', 500), acc.Config('twist-mesh', 1000),
                   acc.Config('ellipsoid', 500), acc.Config('direct', 1000, 12)]
    reference_cfg = acc.Config('direct', 1000, acc.REFERENCE_ARC)
    same_mesh_ref = acc.Config('direct', 1000)
    records: dict = {}
    jobs = [(r, c) for r in args.robots for c in [reference_cfg, same_mesh_ref] + configs]
    jobs = list(dict.fromkeys(jobs))
    states = {r: acc.sample_states(r, args.states, args.seed) for r in args.robots}
    for robot, cfg in tqdm(jobs, desc='speed/accuracy', unit='config', file=sys.stderr):
        records[(robot, cfg)] = acc.run_config(robot, cfg, states[robot])
    summaries, rows = [], []
    for cfg in configs:
        recs = [x for r in args.robots for x in records[(r, cfg)]]
        ref = [x for r in args.robots for x in records[(r, reference_cfg)]]
        same = [x for r in args.robots for x in records[(r, same_mesh_ref)]]
        s = acc.summarise(recs, ref)
        s_same = acc.summarise(recs, same)
        summaries.append(s)
        rows.append({**s.to_dict(), **{f'same_mesh_{k}': v for k, v in s_same.to_dict().items()
                                       if k.startswith(('cap_', 'twist_', 'status_', 'compared'))}})
    out = Path(args.out)
    plot_speed_accuracy(summaries, out)
    text = io.StringIO(newline='')
    w = csv.DictWriter(text, fieldnames=list(rows[0]))
    w.writeheader()
    w.writerows(rows)
    write_text(out.with_suffix('.csv'), text.getvalue())
    numbers = json.dumps({'states_per_robot': args.states, 'robots': args.robots,
                          'seed': args.seed, 'reference': reference_cfg.label, 'rows': rows},
                         indent=2)
    write_text(out.with_suffix('.json'), numbers)
    print(f'{"configuration":<34}{"ms":>8}{"cap p95 %":>11}{"cap worst %":>12}'
          f'{"over %":>8}{"twist p95":>10}{"worst":>8}{"n/mis":>8}')
    for r in rows:
        print(f'{r["config"]:<34}{r["time_ms_median"]:>8.2f}{r["cap_err_pct_p95"]:>11.3f}'
              f'{r["cap_err_pct_worst"]:>12.3f}{r["cap_over_pct_worst"]:>8.2f}'
              f'{r["twist_err_deg_p95"]:>10.2f}{r["twist_err_deg_worst"]:>8.2f}'
              f'{r["compared"]:>5}/{r["status_mismatch"]}')
    print(f'wrote {out}, {out.with_suffix(".csv")}, {out.with_suffix(".json")}')
    if args.json:
        print(numbers)
    return 0


def _agreement(args, tqdm) -> int:
    result = {}
    for robot in args.robots:
        bar = lambda jobs, r=robot: tqdm(jobs, desc=f'agreement {r}', unit='state',
                                         file=sys.stderr)
        result[robot] = acc.agreement(robot, args.states, args.seed, args.reference_twists,
                                      progress=bar)
    out = Path(args.out)
    write_text(out, json.dumps(result, indent=1))
    for robot, r in result.items():
        for m, s in r['summary'].items():
            print(f'{robot:<10}{m:<11} status agree {s["status_agree_pct"]:6.2f} %  degenerate '
                  f'{s["degenerate_pct"]:5.2f} %  cap p95 {s["cap_err_pct_p95"]:.3f} %  worst '
                  f'over {s["cap_over_pct_worst"]:+.3f} %  ({s["compared"]} compared, '
                  f'{s["time_ms_median"]:.1f} ms median)')
        print(f'{robot:<10}all three agree on the status: {r["all_agree_pct"]:.2f} %')
        e_n, e_pct = r['reference_err_N_worst'], r['reference_err_pct_worst']
        print(f'{robot:<10}reference error bound, worst: '
              + ('unknown' if e_n is None else f'{e_n:.2g} N ({e_pct:.3g} % of max(ref, floor))'))
    print(f'wrote {out}')
    if args.json:
        print(json.dumps({k: {kk: v[kk] for kk in v if kk != 'rows'} for k, v in result.items()},
                         indent=1))
    return 0
