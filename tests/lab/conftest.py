"""Fixtures of the lab tests: a small set of synthetic pull-test bags, made once per worker."""
from __future__ import annotations

import pytest
from _lab_common import TRUTH  # noqa: E402  (shared with the tests)

CONFIGS = ((-40, 0, 'forward'), (-40, 20, 'backward'), (-20, 0, 'backward'),
           (-20, 20, 'backward'), (0, 40, 'backward'), (-20, 0, 'forward'))


@pytest.fixture(scope='session')
def synthetic_bags(tmp_path_factory):
    """Six short synthetic tests (12 mm of slip, 2 mm Euler steps) of a medium with known
    (xi_n, mu_surf) = TRUTH, recorded as glass beads (the nominal medium)."""
    pytest.importorskip('rosbags')
    from rftgls_ros.lab.synthetic import main
    out = tmp_path_factory.mktemp('synthetic')
    args = ['--out-dir', str(out), '--xi-n', str(TRUTH[0]), '--mu-surf', str(TRUTH[1]),
            '--step', '0.002', '--max-travel', '0.012', '--integrator', 'euler', '--seed', '7']
    for l1, l2, pull in CONFIGS:
        args.append(f'--config={l1},{l2},{pull}')
    assert main(args) == 0
    return sorted(p for p in out.iterdir() if p.is_dir())
