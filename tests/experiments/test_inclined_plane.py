"""The inclined-plane rig's reading of a layer's profile, on an exact Bagnold layer."""

import math

import numpy as np
import pytest

from rollingdem.experiments.inclined_plane import G, profile_measures


def _bagnold_layer(theta, h, d, phi_bulk=0.58, density=2500.0, amplitude=40.0, slip=0.01, linear=False):
    """A profile along z of a steady uniform layer h deep on a base at z = d: phi_bulk up to its
    surface (a linear edge 0.5 d wide), u = slip + A (h^(3/2) - (h - zeta)^(3/2)) (or, ``linear``,
    a straight profile of the same surface speed), sigma_zz the weight above exactly (the integral of
    the piecewise-linear phi) and sigma_xz = -tan(theta) sigma_zz."""
    base = d
    z = np.linspace(0.0, base + h + 5 * d, 2001)
    zeta = np.clip(z - base, 0.0, None)
    edge = 0.5 * d
    phi = phi_bulk * np.clip((base + h + 0.5 * edge - z) / edge, 0.0, 1.0) * (z > base)
    # the weight above z: the integral of phi from z to the top (a ramp's area is exact)
    top_full, top_zero = base + h - 0.5 * edge, base + h + 0.5 * edge
    above = np.where(z <= top_full, phi_bulk * (top_full - np.maximum(z, base)) + phi_bulk * edge / 2,
                     phi_bulk / (2 * edge) * np.clip(top_zero - z, 0.0, None) ** 2)
    szz = density * G * math.cos(theta) * above
    if linear:
        u = slip + amplitude * h ** 1.5 * zeta / h
    else:
        u = slip + amplitude * (h ** 1.5 - np.clip(h - zeta, 0.0, None) ** 1.5)
    return {"z (m)": z, "solid_fraction (1)": phi, "velocity_x (m/s)": u * (z > base),
            "stress_zz (Pa)": szz, "stress_xz (Pa)": -math.tan(theta) * szz}, base


def test_an_exact_bagnold_layer_reads_as_one():
    """Depth within half a grid step of h, Bagnold's shape to 1e-6 of the surface speed, phi uniform,
    the stress ratio tan(theta) and the weight ratio 1 (to the trapezoid's error, 1e-4), and the
    uniform I = 1.5 A d / sqrt(g cos(theta) phi) of a Bagnold layer within 0.5 % (central
    differences), uniform within 0.5 %. A straight profile of the same surface speed is 1.3 % of it
    off Bagnold's shape over this bulk (3 d to 7 d of a 10 d layer), and its I varies by 26 %: the
    uniform I tells them apart."""
    theta, h, d = math.radians(25.0), 0.01, 1e-3
    profile, base = _bagnold_layer(theta, h, d)
    m = profile_measures(profile, base, d, 2500.0, theta)
    assert m["depth"] == pytest.approx(h / d, abs=0.02)
    assert m["bagnold_deviation"] < 1e-6
    assert m["solid_fraction_spread"] < 1e-12
    assert m["stress_ratio"] == pytest.approx(math.tan(theta), rel=1e-12)
    assert m["weight_ratio"] == pytest.approx(1.0, abs=1e-4)
    assert m["inertial_number"] == pytest.approx(1.5 * 40.0 * d / math.sqrt(G * math.cos(theta) * 0.58), rel=5e-3)
    assert m["slip_speed"] == pytest.approx(0.01, abs=1e-6)
    assert m["inertial_spread"] < 5e-3
    straight = profile_measures(_bagnold_layer(theta, h, d, linear=True)[0], base, d, 2500.0, theta)
    assert straight["bagnold_deviation"] > 0.01 and straight["inertial_spread"] > 0.15


def test_a_layer_below_its_friction_angle_stops_at_the_first_slope():
    """A layer 6 d deep poured on a 10 deg slope (well below the 20 deg its friction holds) is at rest
    after 0.3 s: the search ends at its first slope, having flowed last at 10 + step deg."""
    from rollingdem.experiments.inclined_plane import InclinedPlane, stop_angle

    e = InclinedPlane()
    assert stop_angle(e.resolve({"depth": 6.0, "length": 5.0, "width": 5.0}), 10.0, 5.0, 0.3) == (15.0, 10.0)
