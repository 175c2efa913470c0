"""The limit-surface oracle (tests/limit_surface_oracle.py) against closed forms, so that the limit-surface tests
can trust it.

Uniform pressure: a disk spinning in place feels torque (2/3) mu m g R; any body sliding without spin feels mu m g
opposite its velocity and no torque about its COM; a centred square of side a spinning feels
mu m g a (sqrt 2 + ln(1 + sqrt 2)) / 6; a disk sliding and spinning tends to v / (R omega) = 0.653 (Farkas et al.).
"""

import math

import numpy as np
import pytest

from limit_surface_oracle import disk_nodes, disk_slip_ratio_limit, friction_wrench, rect_nodes

MU, MASS, G = 0.3, 2.0, 9.81


def test_disk_spinning_in_place_feels_two_thirds_mu_m_g_r():
    R = 0.1
    nodes, weights = disk_nodes(R)
    assert weights.sum() == pytest.approx(math.pi * R * R, rel=1e-13)
    fx, fy, tau = friction_wrench(nodes, weights, (0.0, 0.0, 3.0), MU, MASS, G)
    assert abs(fx) < 1e-12 and abs(fy) < 1e-12
    # (the points model's four default support points on the ring R / sqrt 2 give mu m g R / sqrt 2 instead: 6 % more)
    assert tau == pytest.approx(-2.0 / 3.0 * MU * MASS * G * R, rel=1e-12)


@pytest.mark.parametrize("direction", [(1.0, 0.0), (0.6, -0.8)])
def test_sliding_without_spin_feels_mu_m_g_and_no_torque(direction):
    for nodes, weights in (disk_nodes(0.1), rect_nodes(0.0, 0.0, 0.2, 0.05)):
        f = friction_wrench(nodes, weights, (2.0 * direction[0], 2.0 * direction[1], 0.0), MU, MASS, G)
        np.testing.assert_allclose(f[:2], -MU * MASS * G * np.array(direction), rtol=1e-12, atol=1e-12)
        assert abs(f[2]) < 1e-12


def test_square_spinning_in_place_matches_the_closed_form():
    a = 0.2
    nodes, weights = rect_nodes(0.0, 0.0, a / 2, a / 2, n=256)
    tau = friction_wrench(nodes, weights, (0.0, 0.0, -1.0), MU, MASS, G)[2]
    # integral of |r| over the square: a^3 (sqrt 2 + ln(1 + sqrt 2)) / 6; the point singularity at the centre limits
    # Gauss-Legendre to about 1e-6 at 256 x 256 nodes
    assert tau == pytest.approx(MU * MASS * G * a * (math.sqrt(2) + math.log(1 + math.sqrt(2))) / 6, rel=1e-5)


def test_sliding_and_spinning_disk_tends_to_the_farkas_ratio():
    coarse, fine = disk_slip_ratio_limit(64, 256), disk_slip_ratio_limit(128, 512)
    assert abs(coarse - fine) < 5e-4               # converged in the nodes
    assert fine == pytest.approx(0.653, abs=1e-3)  # Farkas, Bartels, Unger & Wolf 2003
