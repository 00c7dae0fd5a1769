"""`rftgls map plot`: a heatmap slice of a map; pixels are the map's own single-query answers."""
from __future__ import annotations

import math

import numpy as np
import pytest
from tolerances import INTERPOLATION_ATOL, INTERPOLATION_RTOL

from rftgls_core.cli.main import main
from rftgls_core.cli.map_plot import map_slice
from rftgls_core.maps import CapacityMap, shipped_map_path
from rftgls_core.types import AnchorState, Status


def test_slice_pixels_are_map_queries():
    cmap = CapacityMap.load(shipped_map_path('minirquad'))
    fixed = {'h': 0.034, 'theta_b': math.radians(5.0), 'theta_l1': 0.0, 'theta_l2': 0.0}
    phi = math.radians(-20.0)
    xs, ys, cap, unsup = map_slice(cmap, 'theta_l1', 'theta_l2', fixed, phi, 'backward', 9)
    assert xs[0] == cmap.axes['theta_l1'][0] and xs[-1] == cmap.axes['theta_l1'][-1]
    assert unsup.any() and np.isfinite(cap).any()
    for i in (0, 4, 8):
        for j in (0, 3, 8):
            r = cmap.query(AnchorState(0.034, fixed['theta_b'], xs[j], ys[i]), phi, 'backward')
            if r.status.has_value:
                # batched pixels against single queries: tests/tolerances.py
                assert cap[i, j] == pytest.approx(r.capacity_N, rel=INTERPOLATION_RTOL,
                                                  abs=INTERPOLATION_ATOL)
            else:
                assert math.isnan(cap[i, j])
                assert unsup[i, j] == (r.status is Status.UNSUPPORTED)


def test_cli_writes_png(tmp_path, capsys):
    out = tmp_path / 'slice.png'
    assert main(['map', 'plot', 'minirquad', '--x', 'theta_l1', '--y', 'theta_l2', '--h', '34',
                 '--theta-b', '5', '--phi', '-20', '--pull', 'backward', '--n', '41',
                 '--out', str(out)]) == 0
    assert out.read_bytes()[:8] == b'\x89PNG\r\n\x1a\n'
    assert 'unsupported' in capsys.readouterr().out


@pytest.mark.parametrize('argv', [
    ['--x', 'h', '--y', 'h'],
    ['--theta-b', '80'],
    ['--pull', 'sideways'],
    ['--n', '3'],
])
def test_cli_bad_input_exits_2(tmp_path, argv):
    assert main(['map', 'plot', 'minirquad', *argv, '--out', str(tmp_path / 'x.png')]) == 2
    assert not (tmp_path / 'x.png').exists()
