"""Li 2013 generic 2D RFT fit (rft/li.py) against the reference values of
docs/design/models-rft.md 2.6."""
from __future__ import annotations

import numpy as np
import pytest

from rftgls_core.rft.li import GENERIC, POPPY_CP, POPPY_LP, coefficient_set, li_alpha

# docs/design/models-rft.md 2.6, "Grid for unit tests": alpha_x / alpha_z, generic set, zeta = 1;
# rows beta, columns gamma, degrees.
GAMMAS = (-90, -45, 0, 45, 90)
GRID = {
    -60: ('+0.037/-0.103', '+0.224/-0.133', '+0.235/-0.014', '+0.064/+0.184', '-0.190/+0.346'),
    -30: ('+0.037/-0.201', '+0.142/-0.153', '+0.118/+0.155', '-0.019/+0.542', '-0.190/+0.782'),
    0: ('+0.000/-0.250', '+0.096/-0.067', '+0.136/+0.375', '+0.096/+0.817', '+0.000/+1.000'),
    30: ('-0.037/-0.201', '+0.134/+0.039', '+0.271/+0.426', '+0.294/+0.734', '+0.190/+0.782'),
    60: ('-0.037/-0.103', '+0.216/+0.059', '+0.388/+0.257', '+0.377/+0.376', '+0.190/+0.346'),
    90: ('+0.000/-0.054', '+0.262/-0.027', '+0.370/+0.037', '+0.262/+0.101', '+0.000/+0.128'),
}
# docs/design/models-rft.md 2.6, single cases: (beta, gamma) deg -> (alpha_x, alpha_z)
CASES = {
    (0, 90): (0.000, 1.000),      # horizontal plate, straight down
    (0, -90): (0.000, -0.250),    # horizontal plate, straight up
    (0, 0): (0.136, 0.375),       # horizontal plate, horizontal drag (lift)
    (90, 0): (0.370, 0.037),      # vertical plate, horizontal drag
    (90, 90): (0.000, 0.128),     # vertical plate, straight down
    (45, 90): (0.219, 0.564),
    (45, 0): (0.341, 0.363),
    (-45, 0): (0.165, 0.049),
}
HALF_ULP_3DP = 0.0005 + 1e-12      # the tables are rounded to 3 decimals


@pytest.mark.parametrize('beta', sorted(GRID))
def test_reference_grid(beta):
    for gamma, cell in zip(GAMMAS, GRID[beta]):
        ref_x, ref_z = (float(s) for s in cell.split('/'))
        ax, az = li_alpha(np.radians(beta), np.radians(gamma))
        assert abs(ax - ref_x) <= HALF_ULP_3DP, (beta, gamma)
        assert abs(az - ref_z) <= HALF_ULP_3DP, (beta, gamma)


@pytest.mark.parametrize('case', sorted(CASES))
def test_single_cases(case):
    ax, az = GENERIC.alpha(*np.radians(case))
    assert ax == pytest.approx(CASES[case][0], abs=HALF_ULP_3DP)
    assert az == pytest.approx(CASES[case][1], abs=HALF_ULP_3DP)


def test_generic_normalisation():
    # docs/design/models-rft.md 2.3: alpha_z^gen(0, pi/2) = 0.206+0.169+0.212+0.358+0.055 = 1.000
    assert GENERIC.penetration == pytest.approx(1.0, abs=1e-12)
    assert GENERIC.alpha(0.0, np.pi / 2)[1] == pytest.approx(1.0, abs=1e-12)
    # docs/design/models-rft.md 3.4 / 8: alpha_1 = alpha_x^gen(0, 0) = 0.136
    assert GENERIC.drag == pytest.approx(0.136, abs=1e-12)


def test_poppy_sets_are_in_n_per_cm3():
    # docs/design/models-rft.md 2.4: alpha_z(0, pi/2) = 0.254 (LP) and 0.464 (CP) N/cm^3
    assert POPPY_LP.unit == POPPY_CP.unit == 'N/cm^3'
    assert POPPY_LP.penetration == pytest.approx(0.254, abs=1e-12)
    assert POPPY_CP.penetration == pytest.approx(0.464, abs=1e-12)


@pytest.mark.parametrize('coeffs', [GENERIC, POPPY_LP, POPPY_CP])
def test_c_cosine_d_sine_pairing(coeffs):
    # docs/design/models-rft.md 2.2 and 5: only the C-cos / D-sin pairing makes alpha_x vanish for a
    # horizontal plate moving straight down or up (the swapped IsaacLab form gives 0.224)
    for gamma in (np.pi / 2, -np.pi / 2):
        assert coeffs.alpha(0.0, gamma)[0] == pytest.approx(0.0, abs=1e-15)


@pytest.mark.parametrize('coeffs', [GENERIC, POPPY_LP, POPPY_CP])
def test_mirror_relations_and_periodicity(coeffs):
    # docs/design/models-rft.md 2.5:
    # az(b, g) = az(-b, pi - g), ax(b, g) = -ax(-b, pi - g); pi-periodic in b
    rng = np.random.default_rng(7)
    beta = rng.uniform(-np.pi, np.pi, 500)
    gamma = rng.uniform(-np.pi, np.pi, 500)
    ax, az = coeffs.alpha(beta, gamma)
    mx, mz = coeffs.alpha(-beta, np.pi - gamma)
    np.testing.assert_allclose(mz, az, rtol=0, atol=1e-12)
    np.testing.assert_allclose(mx, -ax, rtol=0, atol=1e-12)
    px, pz = coeffs.alpha(beta + np.pi, gamma)
    np.testing.assert_allclose(px, ax, rtol=0, atol=1e-12)
    np.testing.assert_allclose(pz, az, rtol=0, atol=1e-12)


def test_trig_free_form_matches_angles():
    rng = np.random.default_rng(3)
    beta, gamma = rng.uniform(-4, 4, (2, 200))
    np.testing.assert_allclose(
        GENERIC.alpha_cs(np.cos(2 * beta), np.sin(2 * beta), np.cos(gamma), np.sin(gamma)),
        GENERIC.alpha(beta, gamma), atol=1e-15)


def test_unknown_set():
    with pytest.raises(ValueError, match='unknown Li coefficient set'):
        coefficient_set('sand')
