"""The box_stress measurement: its stress on known states (a gas of free spheres, a sheared one on
its affine profile) and its pressure control through a case file."""

import math

import numpy as np
import pytest

import rollingdem as rd


def _free_spheres(sheared: bool):
    """Two spheres far apart in a 0.1 m periodic cube, no contact; in a sheared box (gradient z, 20 /s)."""
    sim = rd.Simulation(gravity=(0, 0, 0), periodic={a: (0.0, 0.1) for a in "xyz"},
                        lees_edwards=rd.LeesEdwards(shear_rate=20.0) if sheared else None)
    sim.add_material(rd.Material("m", 5e6, 0.3, 2500.0, friction=0.5))
    sim.add_particles([[0.02, 0.05, 0.02], [0.07, 0.05, 0.08]], 0.002, "m")
    return sim


def test_the_kinetic_stress_of_free_spheres_about_the_shear_profile():
    """Without contacts the stress is sum m v'(x)v' / V: p = sum m |v|^2 / (3 V), tau = -sum m v_x v_z / V
    in a box at rest; in a sheared box the spheres on the affine profile v_x = rate (z - 0.05) carry
    none (their v' is zero), and the solid fraction is the spheres' volume over the box's."""
    sim = _free_spheres(False)
    v = np.array([[0.3, 0.0, 0.2], [-0.1, 0.4, 0.0]])
    sim.set_velocities([0, 1], velocity=v)
    m = sim.masses
    values = dict(zip(rd.BoxStress.QUANTITIES, rd.BoxStress("b").values(sim)))
    assert values["pressure"] == pytest.approx(float(m @ (v ** 2).sum(axis=1)) / 3e-3, rel=1e-12)
    assert values["shear_stress"] == pytest.approx(-float(m @ (v[:, 0] * v[:, 2])) / 1e-3, rel=1e-12)
    assert values["solid_fraction"] == pytest.approx(2 * 4 / 3 * math.pi * 0.002 ** 3 / 1e-3, rel=1e-12)
    sheared = _free_spheres(True)
    sheared.set_velocities([0, 1], velocity=[[20.0 * (0.02 - 0.05), 0, 0], [20.0 * (0.08 - 0.05), 0, 0]])
    values = dict(zip(rd.BoxStress.QUANTITIES, rd.BoxStress("b").values(sheared)))
    assert values["pressure"] == 0.0 and values["shear_stress"] == 0.0
    # on the profile plus v_z = +-w and v_x' = -+0.5 w: sigma_zz = sum m w^2 / V, tau = 0.5 sum m w^2 / V,
    # and I = rate d / sqrt(sigma_zz / rho) with d = 4 mm and rho = 2500 kg/m^3
    w = 0.2
    sheared.set_velocities([0, 1], velocity=[[20.0 * (0.02 - 0.05) - 0.5 * w, 0, w],
                                             [20.0 * (0.08 - 0.05) + 0.5 * w, 0, -w]])
    values = dict(zip(rd.BoxStress.QUANTITIES, rd.BoxStress("b").values(sheared)))
    normal = float(sheared.masses.sum()) * w ** 2 / 1e-3
    assert values["normal_stress"] == pytest.approx(normal, rel=1e-12)
    assert values["friction"] == pytest.approx(0.5, rel=1e-12)
    assert values["inertial_number"] == pytest.approx(20.0 * 0.004 / math.sqrt(normal / 2500.0), rel=1e-12)


PRESSED_CASE = """\
name: pressed
materials:
  - {name: m, youngs_modulus: 5.0e6, poisson_ratio: 0.3, density: 2500.0, friction: 0.3, restitution: 0.3}
gravity: [0, 0, 0]
periodic: {x: [0.0, 0.014], y: [0.0, 0.014], z: [0.0, 0.014]}
particles:
  - insert: {type: box, lo: [0, 0, 0], hi: [0.014, 0.014, 0.014]}
    count: 300
    radius: 0.0008
    material: m
    seed: 1
measurements:
  - {name: box, type: box_stress, pressure_control: 100.0, interval: 5.0e-4, window: [0.6, 0.8]}
stages:
  - {name: press, duration: 0.8}
"""


def test_a_case_file_presses_its_box_to_the_pressure_asked(tmp_path):
    """300 spheres inserted at a solid fraction of 0.23, the box's three lengths moved at each sample
    to hold 100 Pa: over the last quarter the mean normal stress is 100 Pa within 5 % (the servo's
    noise on so few spheres) and the packing is dense (above 0.55)."""
    import json

    from typer.testing import CliRunner

    from rollingdem.cli import app

    (tmp_path / "case.yaml").write_text(PRESSED_CASE)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "case.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    box = json.loads((tmp_path / "o" / "summary.json").read_text())["measurements"]["box"]
    assert box["normal_stress"]["mean"] == pytest.approx(100.0, rel=0.05)
    assert box["solid_fraction"]["mean"] > 0.55


def test_box_stress_refuses_a_box_not_periodic_everywhere_and_bad_axes():
    sim = rd.Simulation(periodic={"x": (0.0, 0.1)})
    with pytest.raises(rd.ParameterError, match="box_stress 'b' is not allowed: the box must be periodic along x, y"):
        rd.BoxStress("b").check(sim)
    with pytest.raises(rd.ParameterError, match="axes = 'w' is not allowed"):
        rd.BoxStress("b", pressure_control=1.0, axes="w")
