"""capacity_bench runs on a clean machine and measures the node as deployed: capacity_node in
its own process (real DDS on loopback), its in-node figures read from its /diagnostics.

Only that the bench works and what it reports is asserted here; the rates it finds depend on
the machine (they are figures for the README, not verdicts of a test)."""
import math
import os

import pytest


def test_live_bench_runs_the_node_in_its_own_process_and_reads_its_figures():
    pytest.importorskip('rclpy')
    from rftgls_ros.capacity_bench import RATES_HZ, run
    res = run('', n=40)
    assert res['predictor'] == 'live:direct-warm (own process)'
    assert res['status_last'] == 'ok'             # it really solved, with every input fresh
    assert math.isfinite(res['capacity_last_N']) and res['capacity_last_N'] > 0.0
    # the node's own figures (from /diagnostics) are there and sane
    assert 0.0 < res['node_processing_ms_median'] <= res['node_latency_ms_median']
    assert res['node_latency_ms_median'] <= res['node_latency_ms_p99']
    assert res['solver_steps'] >= 40 and 0.0 <= res['solver_fallback_rate'] <= 1.0
    assert res['solver_solve_us_median'] > 0.0
    # the figures say where they were measured: this machine's CPU and cores
    assert res['machine']['cores'] == len(os.sched_getaffinity(0)), res['machine']
    assert res['machine']['cpu_model'] and res['machine']['numba_target'], res['machine']
    # the sustained phase went through the rates in order and stopped at the first drop
    tried = [r for r in RATES_HZ if f'rate_{r}hz_delivered' in res]
    assert tried == list(RATES_HZ[:len(tried)]) and tried
    full = [r for r in tried if res[f'rate_{r}hz_delivered'] == 1.0]
    assert res['node_sustained_rate_hz'] == (full[-1] if full else 0)
    assert full == tried[:len(full)]
