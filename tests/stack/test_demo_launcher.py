"""The demo launcher end to end: one short cycle, own domain id, report written, exits by itself;
every tug on the lower bound, and a sled no mode's lower bound holds refused cleanly. The
decisions' numbers are checked on the scripted body (its burrows end where the gait map
predicts); the default body, the physics, is checked for what it must do whatever the sand
does: burrow with the physics, decide on the lower bound, say why, exit cleanly. The
per-sled summary line is checked from report rows too, without a stack."""
from __future__ import annotations

import math
import os
import re
import shlex
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from rftgls_ros.behavior.report import read_csv
from rftgls_ros.demo import stop_process

REPO = Path(__file__).resolve().parents[2]
G = 9.81


PROGRAMS = ('minirquad_sim', 'bridge_node', 'capacity_node', 'state_publisher', 'behavior_node')
TUG_PATH = {'bridge_node', 'capacity_node', 'behavior_node'}


def demo(out: Path, sled: float, *params: str, body: str = 'scripted', run_s: float = 60.0,
         nice: dict[str, set[int]] | None = None) -> subprocess.CompletedProcess:
    """One cycle of behavior_demo; run_s: its per-sled timeout (--timeout), s. nice, if given,
    collects the nice levels seen for each of PROGRAMS among the demo's processes while it
    runs (every 0.1 s)."""
    env = {k: v for k, v in os.environ.items() if k != 'ROS_DOMAIN_ID'}
    extra = [a for kv in params for a in ('--param', kv)]
    body_arg = ['--body', body] if body else []
    argv = ['ros2', 'run', 'rftgls_ros', 'behavior_demo', '--out', str(out), '--sleds', str(sled),
            '--cycles', '1', '--param', 'walk_time_s:=1.0', '--param', 'idle_measure_time_s:=0.5',
            *extra, *body_arg, '--timeout', f'{run_s:g}']
    if nice is None:
        return subprocess.run(argv, cwd=REPO, env=env, capture_output=True, text=True,
                              timeout=run_s + 30.0)
    logs = out.parent / 'demo_stdout.txt', out.parent / 'demo_stderr.txt'
    with logs[0].open('w') as o, logs[1].open('w') as e:
        proc = subprocess.Popen(argv, cwd=REPO, env=env, stdout=o, stderr=e, text=True)
        try:
            end = time.monotonic() + run_s + 30.0
            while proc.poll() is None and time.monotonic() < end:
                for pid in descendants(proc.pid):
                    name, level = program_nice(pid)
                    if name:
                        nice.setdefault(name, set()).add(level)
                time.sleep(0.1)
        finally:
            stop_process(proc, timeout=10.0)    # past its time: stopped as a user would
    return subprocess.CompletedProcess(argv, proc.returncode, logs[0].read_text(),
                                       logs[1].read_text())


def descendants(pid: int) -> list[int]:
    """Every process below pid (Linux's /proc/PID/task/PID/children lists)."""
    found, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            kids = [int(k) for k in Path(f'/proc/{p}/task/{p}/children').read_text().split()]
        except OSError:                  # gone meanwhile
            continue
        found += kids
        todo += kids
    return found


def program_nice(pid: int) -> tuple[str | None, int]:
    """Which of PROGRAMS pid runs (None: another, or `nice` itself before it execs the
    program: its level is not set yet) and its nice level."""
    try:
        argv = Path(f'/proc/{pid}/cmdline').read_bytes().decode().split('\0')
        level = os.getpriority(os.PRIO_PROCESS, pid)
    except OSError:
        return None, 0
    if Path(argv[0]).name == 'nice':
        return None, 0
    names = [n for n in PROGRAMS if any(Path(a).name == n for a in argv[:3])]
    return (names[0] if names else None), level


@pytest.mark.slow
def test_demo_one_cycle_exits_and_writes_report(tmp_path):
    out = tmp_path / 'demo'
    nice: dict[str, set[int]] = {}
    proc = demo(out, 0.4, nice=nice)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    # The tug path runs 5 nice levels above the demo, as bringup.launch.py runs it on the
    # robot; the simulator and state_publisher at the demo's own level. Only a process allowed
    # to raise a priority gets it (root here; otherwise nice warns and runs the node as is).
    base = os.getpriority(os.PRIO_PROCESS, 0)
    raised = base - 5 if os.geteuid() == 0 else base
    assert nice == {n: {raised if n in TUG_PATH else base} for n in PROGRAMS}, nice
    assert 'tug path (bridge_node, capacity_node, behavior_node) behind nice -n -5' in text
    m = re.search(r'ROS_DOMAIN_ID=(\d+), DDS discovery LOCALHOST', text)
    assert m and 1 <= int(m.group(1)) <= 100, text
    # the solvers compiled (or loaded) before any node needs them (rftgls_ros/warm_up.py)
    assert text.index('solvers ready') < text.index('[behavior_node]'), text
    # The default burrows are planned: the cheapest gait of the 400 g gait map whose lower
    # bound covers 1.96 N (docs/design/burrow-planner.md: (-40, -20) -> (-40, -20), 2.74 N).
    assert 'decision (planned pose): g-40/-20>-40/-20' in text
    # The cycle's burrows: the planned gait first, then any re-burrow its check asked for
    # (a measured pitch outside the replayed band: seen once under CI load, the scripted body
    # then at -11.6 deg); the numbers are those of the gait the tug was decided on.
    line = re.search(r'400 g sled -> g-40/-20>-40/-20(?:, g-[\d/>-]+)*: lower bound ([\d.]+) N '
                     r'\(chosen on\), ([\d.]+) N at the measured pose \(tug started on\), '
                     r'point estimate ([\d.]+) N, need ([\d.]+) N; burrow energy [\d.]+ J above '
                     r'idle predicted, [\d.]+ J measured', text)
    assert line, text
    lower, started, point, need = map(float, line.groups())
    assert point > lower >= need == pytest.approx(0.5 * 0.4 * G, abs=0.01)
    assert started >= need
    assert (out / 'cycle_report.csv').exists() and (out / 'cycle_report.png').exists()
    # Never a reel-in below the need: the machine books capacity_node's lower bound against
    # the need at every step that commanded the winch in (reel_lower_margin_n).
    rows = read_csv(out / 'cycle_report.csv')
    assert rows and all(r.outcome == 'ok' for r in rows), rows
    assert all(r.reel_lower_margin_n >= 0.0 for r in rows), rows


@pytest.mark.slow
def test_the_default_demo_burrows_with_the_physics_and_decides_on_the_lower_bound(tmp_path):
    """`make demo`'s body: the simulator's whole-robot physics takes the body from standing
    (nothing copied from Table II). Whatever pose the sand gives, every tug is decided on
    the lower bound, the choice is printed with its reason, the physics never stops, and a
    cycle ends ok or stopped (a re-burrow that still falls short), never aborted."""
    out = tmp_path / 'demo'
    # The physics body's re-burrows with the sled tied run behind real time when the two
    # workers are busy (one took 60 s where it usually takes 38 s): this test is about what
    # the run decides, not how fast, so it gets twice the scripted body's time.
    proc = demo(out, 0.4, body='', run_s=120.0)
    text = proc.stdout + proc.stderr
    assert proc.returncode == 0, text
    assert '(simulated MiniRQuad, burrow-physics body)' in text, text
    assert re.search(r'decision \(planned pose\): g-[\d/>-]+: cheapest sufficient planned gait',
                     text), text
    # the check at the measured pose: the burrow replayed over the legs the robot measured
    assert re.search(r'check g-[\d/>-]+ at the measured pose .* lower bound', text), text
    rows = read_csv(out / 'cycle_report.csv')
    assert rows and all(r.outcome in ('ok', 'stopped') for r in rows), rows
    # Never a reel-in below the need; NaN is a cycle whose winch never reeled in (report.py),
    # which only a stopped one may be (seen under the load of three test workers: three
    # burrows, none whose pose check passed, no tug).
    assert all(r.reel_lower_margin_n >= 0.0
               or (r.outcome == 'stopped' and math.isnan(r.reel_lower_margin_n))
               for r in rows), rows
    report = (out / 'logs' / 'sled_400g' / 'minirquad_sim.log').read_text()
    assert 'physics stopped' not in report and 'physics_behind_s' in report, report


def dh_lower_bound() -> float:
    """DH's lower bound (N) as capacity_node computes it with the shipped parameters, from
    rftgls_core alone: the shipped map at Table II's DH pose, the smaller of the one-sided
    confidence bound (rftgls_core.uncertainty) and the smallest capacity over the height band
    (34 +- 2 x 1 mm, the five heights capacity_node scans), the weaker of phi 0 and -20 deg."""
    import yaml

    from rftgls_core.maps import CapacityMap, shipped_map_path
    from rftgls_core.types import AnchorState
    from rftgls_core.uncertainty import capacity_lower_bound
    p = yaml.safe_load((REPO / 'ros2_ws/params/capacity_node.yaml').read_text())
    p = p['/**/capacity_node']['ros__parameters']
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    dh = AnchorState.from_degrees(0.034, 5.0, -40.0, 30.0)
    out = []
    for phi in (0.0, math.radians(-20.0)):
        def cap(st, phi=phi):
            return cmap.query(st, phi, 'backward')
        c = cap(dh).capacity_N
        sigma = capacity_lower_bound(cap, dh, phi, c, p['lower_bound_level'], p['h_sigma_m'],
                                     p['theta_b_sigma_rad'], p['capacity_rel_sigma'])
        band = min(cap(AnchorState(dh.h + f * 0.002, *dh.as_tuple()[1:])).capacity_N
                   for f in (-1.0, -0.5, 0.0, 0.5, 1.0))
        out.append(min(sigma, band))
    return min(out)


@pytest.mark.slow
def test_demo_refuses_a_sled_no_lower_bound_covers(tmp_path):
    # 1 kg needs 4.9 N: DH's point estimate (5.24 N) covers it, its lower bound (capacity_node's:
    # the medium's 5 % and one sigma of pose, and 34 +- 2 mm) does not. No burrow, no tug,
    # exit 4 and the reason on stderr.
    out = tmp_path / 'demo'
    proc = demo(out, 1.0, 'burrow_modes:=table_ii')   # no gait map for a 1 kg sled
    text = proc.stdout + proc.stderr
    assert proc.returncode == 4, text
    # (the need over the tug ratio: the guard's 0.97, or lower for a tether the reel would
    # crawl in past the tug timeout, behavior/reel.py)
    said = re.search(r'1000 g REFUSED, no tug: no mode suffices: need 4\.9\d N x 1\.00 / '
                     r'0\.9\d, strongest DH has a lower bound of (\d+\.\d\d) N', proc.stderr)
    assert said, text
    # printed to 0.01 N; the map's DH pose lies away from its support edge, where
    # capacity_node's live answers would replace the map's
    assert float(said.group(1)) == pytest.approx(dh_lower_bound(), abs=0.0051), text
    assert '1000 g sled -> REFUSED' in proc.stdout, text
    (row,) = read_csv(out / 'cycle_report.csv')
    assert (row.mode, row.outcome, row.reason) == ('-', 'refused', 'no_sufficient_mode')
    assert row.point_n > row.need_n > row.lower_n
    assert 'BURROW' not in text and '[live] tug' not in text


@pytest.mark.slow
def test_demo_planned_refuses_a_sled_without_a_gait_map(tmp_path):
    proc = demo(tmp_path / 'demo', 1.0)
    text = proc.stdout + proc.stderr
    assert proc.returncode != 0, text
    assert "burrow_modes 'planned': no gait map for a 1000 g sled" in text, text
    assert '[live] tug' not in text


def test_the_sled_line_names_each_gait_burrowed_once_in_order_with_both_bounds():
    """behavior_demo's per-sled line from report rows (no stack): a re-burrowed cycle's mode
    is 'A+B'; the line lists A, B once each, first burrowed first, and the bounds of the last
    cycle that chose: the one it was chosen on and the one its tug was started on."""
    from rftgls_ros.behavior.report import CycleRecord
    from rftgls_ros.demo import sled_line

    def row(cycle, mode, lower, started):
        return CycleRecord(0.4, cycle, mode, 'ok', 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.1, 0.5,
                           1.962, 1.962, 1.0, lower_n=lower, point_n=lower + 0.5,
                           energy_pred_j=1.0, check_lower_n=started)

    line = sled_line([row(1, 'g-b', 3.0, 3.1), row(2, 'g-a+g-b', 2.5, 2.9),
                      row(3, 'g-a', 2.4, 2.2)])
    assert line.startswith('400 g sled -> g-b, g-a: lower bound 2.40 N (chosen on), 2.20 N at '
                           'the measured pose (tug started on), point estimate 2.90 N'), line
    untugged = sled_line([row(1, 'g-b', 3.0, math.nan)])
    assert 'lower bound 3.00 N (chosen on), no tug started,' in untugged, untugged


def test_the_demo_prefixes_the_tug_path_as_the_launch_files_do(capsys):
    """behavior_demo's default --tug-path-prefix is bringup.launch.py's tug_path_prefix (one
    priority for the tug path, on the robot and in the demo); a prefix that is no command is a
    one-line usage error before anything starts."""
    from rftgls_ros import launch_model
    from rftgls_ros.demo import TUG_PATH_PREFIX, command_prefix, main
    launch = launch_model.parse(REPO / 'src/rftgls_ros/launch/bringup.launch.py')
    assert not launch.problems, launch.problems
    prefixes = {p.executable: p.prefix for p in launch.nodes}
    assert all(prefixes[n] == command_prefix(TUG_PATH_PREFIX) == ['nice', '-n', '-5']
               for n in TUG_PATH), prefixes
    assert prefixes['state_publisher'] == []
    assert command_prefix('') == []
    for bad, why in (("nice -n '-5", 'No closing quotation'),
                     ('no-such-program-here -n -5', 'is not a program on PATH')):
        with pytest.raises(SystemExit) as exit_:
            main(['--tug-path-prefix', bad, '--out', '/nonexistent/never-written'])
        err = capsys.readouterr().err
        assert exit_.value.code == 2 and err.count('\n') == 1, err
        assert err.startswith('behavior_demo: error: argument --tug-path-prefix: ') and why in err


@pytest.mark.skipif(os.geteuid() != 0 or shutil.which('setpriv') is None,
                    reason='runs the prefix as another user (root and setpriv needed)')
def test_a_prefix_without_the_right_to_raise_priority_is_said_once_or_refused(tmp_path, capsys):
    """As a user without the right to raise a priority (nobody, through setpriv): GNU nice
    warns and runs the command, so the demo runs and says so in its tug-path line; chrt runs
    nothing, so the demo refuses it before starting anything (a stack whose nodes never start
    would sit out its timeout)."""
    from rftgls_ros.demo import main, try_prefix, tug_path_line
    nobody = ['setpriv', '--reuid=65534', '--regid=65534', '--clear-groups']
    code, said = try_prefix([*nobody, 'nice', '-n', '-5'])
    assert code == 0 and 'cannot set niceness' in said, said
    line = tug_path_line(['nice', '-n', '-5'], said)
    assert line.startswith('behavior_demo: tug path (bridge_node, capacity_node, behavior_node) '
                           'behind nice -n -5 (it says: nice: cannot set niceness'), line
    assert "docs/design/stop-budget.md, 'Priority of the tug path'" in line
    assert (REPO / 'docs/design/stop-budget.md').read_text().count(
        '## Priority of the tug path') == 1
    assert try_prefix(['nice', '-n', '-5']) == (0, '')      # root may
    out = tmp_path / 'never'
    with pytest.raises(SystemExit) as exit_:
        main(['--tug-path-prefix', shlex.join([*nobody, 'chrt', '-f', '10']), '--out', str(out)])
    err = capsys.readouterr().err
    assert exit_.value.code == 2 and err.count('\n') == 1, err
    assert "fails here (exit 1): chrt: failed to set pid 0's policy" in err, err
    assert not out.exists()
