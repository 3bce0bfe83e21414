"""The simple-shear rig's parts on known inputs: the box's stress, the traction across a plane of a
periodic box (the method of planes) and the pressure servo; and a short sheared run that holds its
normal stress and gives the traction across the sheared end equal to the box's mean shear stress."""

import math

import numpy as np
import pytest

from rollingdem.analysis.rheology import box_stress
from rollingdem.experiments.simple_shear import SimpleShear, plane_traction
from rollingdem.io.box_measurements import MAX_STRAIN_PER_MOVE, BoxServo


def test_the_box_stress_is_the_virial_and_the_kinetic_stress_over_the_volume():
    """One contact, force f on i along its branch b (a repulsion): sigma = f (x) b / V, compressive
    positive; two particles moving at +-u along x about a streaming v_x = 0.5 u each add
    m (v_x - 0.5 u)^2 / V to sigma_xx and nothing to sigma_xz or sigma_zz."""
    f, b = np.array([[2.0, 0.0, 1.0]]), np.array([[0.004, 0.0, 0.002]])
    sigma = box_stress(f, b, [], [], 1e-6)
    np.testing.assert_allclose(sigma, np.outer(f[0], b[0]) / 1e-6, rtol=1e-15)
    assert sigma[0, 0] > 0.0  # a repulsion is compressive: positive
    m, u = np.array([1e-3, 2e-3]), 0.3
    v = np.array([[u, 0.0, 0.0], [-u, 0.0, 0.0]])
    streaming = np.array([[0.5 * u, 0.0, 0.0], [0.5 * u, 0.0, 0.0]])
    kinetic = box_stress(np.zeros((0, 3)), np.zeros((0, 3)), m, v, 2e-6, streaming)
    assert kinetic[0, 0] == pytest.approx((1e-3 * (0.5 * u) ** 2 + 2e-3 * (1.5 * u) ** 2) / 2e-6, rel=1e-14)
    assert kinetic[0, 2] == 0.0 and kinetic[2, 2] == 0.0


def test_the_plane_traction_counts_the_contacts_across_the_plane_and_its_images():
    """Three contacts in a box 1 m long along z, the plane z = 0 (and its images at +-1 m): i at
    z = 0.05 with its partner's image at -0.05 (branch +0.1: across; force on i, the upper one, so
    the lower takes -f), i at 0.97 with its partner at 1.03 (across the image at z = 1: i is the lower
    one), i at 0.5 with its partner at 0.4 (across nothing). Traction = the forces on the lower
    members over the area."""
    positions = np.array([[0, 0, 0.05], [0, 0, 0.97], [0, 0, 0.5]])
    contacts = {"i": np.array([0, 1, 2]), "force": np.array([[1.0, 0, 2.0], [3.0, 0, -4.0], [7.0, 0, 7.0]]),
                "branch": np.array([[0, 0, 0.1], [0, 0, -0.06], [0, 0, 0.1]])}
    t = plane_traction(contacts, positions, 0.0, 1.0, 2.0)
    np.testing.assert_allclose(t, (-np.array([1.0, 0, 2.0]) + np.array([3.0, 0, -4.0])) / 2.0, rtol=1e-15)
    assert np.all(plane_traction(contacts, positions, 0.7, 1.0, 2.0) == 0.0)  # no contact crosses z = 0.7


class _Box:
    """A stand-in simulation with a periodic box whose set_length the servo calls."""

    def __init__(self):
        self.periodic = {"x": (0.0, 1.0), "y": (0.0, 1.0), "z": (0.0, 2.0)}
        shear = self

        class Shear:
            @staticmethod
            def set_length(axis, length):
                lo, _ = shear.periodic[axis]
                shear.periodic[axis] = (lo, lo + length)
        self.shear = Shear()


def test_the_servo_moves_the_lengths_towards_the_pressure():
    """Above P the box grows by gain (sigma - P) / P, below it shrinks; at most MAX_STRAIN_PER_MOVE a
    move; the other lengths stay."""
    sim = _Box()
    servo = BoxServo(1000.0, "z", effective_modulus=1e9, gain=0.5)
    gain = 0.5 * (1000.0 / 1e9) ** (2 / 3)
    sigma = np.diag([0.0, 0.0, 1000.0 * (1 + 0.1)])
    servo.move(sim, sigma)
    assert sim.periodic["z"][1] == pytest.approx(2.0 * (1 + gain * 0.1), rel=1e-14)
    servo.move(sim, np.diag([0.0, 0.0, 0.9 * 1000.0]))  # below: shrink
    assert sim.periodic["z"][1] == pytest.approx(2.0 * (1 + gain * 0.1) * (1 - gain * 0.1), rel=1e-14)
    servo.move(sim, np.diag([0.0, 0.0, 1000.0 * (1 + 10.0 / gain)]))  # far above: grow by the cap
    assert sim.periodic["z"][1] == pytest.approx(2.0 * (1 - (gain * 0.1) ** 2) * (1 + MAX_STRAIN_PER_MOVE), rel=1e-14)
    assert sim.periodic["x"] == (0.0, 1.0)


def test_a_short_shear_holds_its_normal_stress_and_its_sheared_end_carries_the_shear_stress():
    """200 spheres compressed to 1 kPa and sheared at I = 0.01 to a strain of 1 (the first 0.5 left
    out): the servo holds sigma_zz within 5 % of P; the contacts across the sheared end carry the
    box's mean contact shear stress within 4 standard errors; the friction lies between the
    frictionless spheres' (about 0.1) and the bulk friction of any sphere packing (below 0.7)."""
    e = SimpleShear()
    out = e.observe(e.resolve({"count": 200, "inertial_number": 0.01, "strain": 1.0, "transient": 0.5}))
    assert out["normal_stress"] == pytest.approx(1000.0, rel=0.05)
    assert abs(out["end_traction_ratio"] - 1.0) < 4 * out["end_traction_error"]
    assert 0.2 < out["friction"] < 0.7
    assert out["inertial_number"] == pytest.approx(0.01, rel=0.05)
    assert 0.55 < out["solid_fraction"] < 0.64 and math.isfinite(out["friction_error"])


def test_the_rigid_limit_is_found_from_two_stiffnesses():
    """phi = phi_rigid + c (P / E*)^(2/3) at E and 10 E: the offset recovers phi_rigid exactly (to
    round-off), whatever c; a stiff packing compressed as 1/E instead gives another value."""
    from rollingdem.experiments.simple_shear import rigid_limit_offset

    phi_rigid, c, p_over_e = 0.639, 2.7, 1.9e-4
    soft = phi_rigid + c * p_over_e ** (2 / 3)
    stiff = phi_rigid + c * (p_over_e / 10.0) ** (2 / 3)
    assert soft - rigid_limit_offset(soft, stiff, 10.0) == pytest.approx(phi_rigid, abs=1e-14)
    linear_stiff = phi_rigid + c * p_over_e ** (2 / 3) / 10.0  # had the compression gone as 1/E
    assert abs(soft - rigid_limit_offset(soft, linear_stiff, 10.0) - phi_rigid) > 1e-3


def _synthetic_runner(mu_s_of, end_ratio=1.0):
    """A runner that answers each point from a known rheology instead of running it: mu(I) of Jop
    et al. with mu_s = ``mu_s_of(mu, mur)``, mu_2 = 0.64, I_0 = 0.28; phi = phi_max - 0.2 I with
    phi_max 0.6485 for frictionless spheres at E = 10 MPa (0.6405 ten times stiffer: rigid 0.6382),
    0.596 - 0.1 mu_r otherwise; the end traction ``end_ratio`` +- 0.01."""
    from rollingdem.analysis.rheology import mu_of_i

    def answer(params):
        i, mu, mur = params["inertial_number"], params["mu"], params["mur"]
        stiff = params["youngs_modulus"] > 1e7
        phi_max = (0.6405 if stiff else 0.6485) if mu == 0.0 else 0.596 - 0.1 * mur
        return {"friction": float(mu_of_i(i, mu_s_of(mu, mur), 0.64, 0.28)), "friction_error": 0.005,
                "solid_fraction": phi_max - 0.2 * i, "solid_fraction_error": 0.001, "inertial_number": i,
                "normal_stress": 1000.0, "end_traction_ratio": end_ratio, "end_traction_error": 0.01,
                "shear_rate": 1.0, "samples": 100, "steps": 1000, "wall_time": 1.0}

    return lambda run, items: [answer(p) for p in items]


def test_the_validations_checks_on_a_known_rheology():
    """Fed a known rheology, every check of the validation passes: the fits find mu_s, phi_max less
    the rigid offset 0.6382, the rises with mu_r, the end traction. A mu_s that falls with mu_r, an
    end traction 3 % off, a frictionless mu_s of 0.15 each fail their check; a creeping model's
    rises are reported, not checked."""
    def rising(mu, mur):
        return 0.10 if mu == 0.0 else 0.38 + 0.3 * mur

    e = SimpleShear()
    result = e.validate(quick=True, runner=_synthetic_runner(rising))
    assert result.passed, [c.as_dict() for c in result.checks if not c.passed]
    assert len(result.checks) == 6
    assert result.table.loc[0, "phi_max rigid"] == pytest.approx(0.6485 - (0.6485 - 0.6405) * 10 ** (2 / 3)
                                                                 / (10 ** (2 / 3) - 1), abs=1e-9)
    failing = {"falling": e.validate(quick=True, runner=_synthetic_runner(lambda mu, mur: 0.10 if mu == 0 else
                                                                          0.38 - 0.1 * mur)),
               "end": e.validate(quick=True, runner=_synthetic_runner(rising, end_ratio=1.03)),
               "frictionless": e.validate(quick=True, runner=_synthetic_runner(lambda mu, mur: 0.15 if mu == 0
                                                                               else rising(mu, mur)))}
    words = {"falling": "smallest rise of mu_s", "end": "traction across the sheared end",
             "frictionless": "frictionless spheres: mu_s"}
    for key, res in failing.items():
        assert [c.quantity for c in res.checks if not c.passed] and \
            all(words[key] in c.quantity for c in res.checks if not c.passed), key
    creeping = e.validate(quick=True, model="cdt", runner=_synthetic_runner(rising))
    assert len(creeping.checks) == 4 and any("reported, not checked" in n for n in creeping.notes)


def test_the_shipped_shear_cell_case_file_gives_the_rigs_point(tmp_path):
    """``rollingdem run`` on the shipped simple-shear case file (564 spheres pressed along z to 1 kPa,
    then sheared at 20 /s: I = 0.031): the box's normal stress is 1 kPa within 2 % over the window,
    its friction that of the rig at I = 0.03 (0.384 at the quick size) within 0.03 (the window's
    standard error is about 0.01 and the sizes differ)."""
    import json

    from typer.testing import CliRunner

    from rollingdem.cli import app
    from rollingdem.experiments.case_file import shipped_cases

    result = CliRunner().invoke(app, ["run", str(shipped_cases()["simple-shear"]), "--out", str(tmp_path / "o"),
                                      "--no-progress"])
    assert result.exit_code == 0, result.output
    box = json.loads((tmp_path / "o" / "summary.json").read_text())["measurements"]["box"]
    assert box["normal_stress"]["mean"] == pytest.approx(1000.0, rel=0.02)
    assert box["inertial_number"]["mean"] == pytest.approx(0.0316, rel=0.05)
    assert box["friction"]["mean"] == pytest.approx(0.384, abs=0.03)
