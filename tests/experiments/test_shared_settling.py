"""A calibration's runs starting from one settled bed (``share_settling``): a material's contact
properties changed between stages act at once, and a pile settled once serves every run."""

import math
from pathlib import Path

import numpy as np
import pytest

import rollingdem as rd
from rollingdem.errors import ParameterError

from helpers import measurement_material as measurements_material

G = 9.81


def _material(**kw):
    """Table 1's spheres (test_measurements), stiff to sliding (mu = 0.8), held by mu_r = 0.5."""
    return measurements_material(**{"friction": 0.8, "rolling_friction": 0.5, "rolling_damping": 0.0, **kw})


def test_a_new_rolling_friction_frees_a_sphere_held_on_a_slope():
    """A sphere on a slope of tan(beta) = 0.2 held by mu_r = 0.5 (EPSD: it rolls once tan(beta) > mu_r,
    docs/models.md) rests; given mu_r = 0.05 (``set_material``) it rolls without sliding (mu = 0.8) at
    the acceleration (5/7) g (sin beta - mu_r cos beta) of a sphere whose rolling resistance is at
    its cap mu_r R F_n (the rolling-resistance torque on the rolling sphere, I = 2/5 m R^2 about the
    centre, 7/5 m R^2 about the contact). After 0.1 s the speed is within 2 % of it (the spring's
    first steps and the overlap's small change of the lever arm)."""
    beta = math.atan(0.2)
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=1e-5,
                        gravity=(G * math.sin(beta), 0.0, -G * math.cos(beta)))
    sim.add_material(_material())
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m"))
    r = 0.005
    sim.add_particles([[0.0, 0.0, r]], r, "m", allow_overlap=True)
    sim.run(0.2)
    assert abs(sim.velocities[0, 0]) < 1e-3  # held
    sim.set_material(_material(rolling_friction=0.05))
    v0 = sim.velocities[0, 0]
    sim.run(0.1)
    expected = 5.0 / 7.0 * G * (math.sin(beta) - 0.05 * math.cos(beta)) * 0.1
    assert sim.velocities[0, 0] - v0 == pytest.approx(expected, rel=0.02)
    with pytest.raises(ParameterError, match="material 'm': density = 2000 is not allowed: it is 1056"):
        sim.set_material(_material(density=2000.0))
    with pytest.raises(ParameterError, match="material = 'glass' is not known"):
        sim.set_material(rd.Material("glass", 5e6, 0.3, 1000.0, friction=0.5))


def test_a_pile_settled_once_serves_every_material_and_says_what_it_saved(tmp_path):
    """``settled_column``: the first run with a reference settles the column and keeps it; a second
    run with another material starts from the very same state (equal positions, bit for bit) with
    its own material in force, and reports the wall time of the settling it did not repeat."""

    from rollingdem.experiments.pile import PileMaterial, PileSetup, pile_case, settled_column

    def case(mur):
        return pile_case(count=150, seed=3, material=PileMaterial(rolling_friction=mur), setup=PileSetup(base="rough"))

    reference = case(0.3)
    first, saved_first = settled_column(case(0.1), reference, tmp_path)
    second, saved_second = settled_column(case(0.5), reference, tmp_path)
    assert saved_first == 0.0 and saved_second > 0.0
    assert np.array_equal(first.positions, second.positions)
    assert first.materials["beads"].rolling_friction == 0.1 and second.materials["beads"].rolling_friction == 0.5
    assert second.materials["beads"].to_dict() == {**first.materials["beads"].to_dict(), "rolling_friction": 0.5}
    alone, _ = settled_column(case(0.3), None, None)
    assert np.array_equal(alone.positions, first.positions)  # the reference's own settling, as it runs alone


def test_share_settling_is_refused_where_there_is_nothing_to_share(tmp_path):
    from rollingdem.studies.calibration import Search, calibrate

    with pytest.raises(ParameterError, match="share_settling is not allowed for experiment 'inclined-wall'"):
        calibrate("inclined-wall", 20.0, 0.5, free=("mur", (0.02, 1.0)), out=tmp_path, progress=False,
                  search=Search(share_settling=True))


def test_a_joint_calibration_settles_each_seed_once_at_the_middle_of_the_box(tmp_path):
    """(mu, mu_r) in [0.3, 0.8] x [0.05, 0.35] against a pile of 400 spheres, 3 points, one seed:
    the pile's column settles once, with mu = 0.55 and mu_r = 0.2 (the box's middle), kept as one
    settled state; the runs that started from it say what they saved and the calibration sums it.
    Targets that no experiment can share are refused before any run."""
    import json

    from rollingdem.scene.simulation import Simulation
    from rollingdem.studies.calibration import Execution
    from rollingdem.studies.joint_calibration import JointSearch, Target, calibrate_joint
    from rollingdem.studies.sweep import read_table

    free = {"mu": (0.3, 0.8), "mur": (0.05, 0.35)}
    res = calibrate_joint([Target("repose-rough-base", "angle", 25.0, 1.0)], free,
                          fix={"count": 400, "lift_speed": 0.0, "max_collapse": 1.0}, seeds=[1],
                          search=JointSearch(initial=3, rounds=0, share_settling=True), out=tmp_path,
                          execution=Execution(workers=1), progress=False)
    settled = sorted((tmp_path / "repose-rough-base" / "settled").glob("settled-*.npz"))
    assert len(settled) == 1
    beads = Simulation.restore(settled[0]).materials["beads"]
    assert (beads.friction, beads.rolling_friction) == (pytest.approx(0.55), pytest.approx(0.2))
    table = read_table(tmp_path / "repose-rough-base" / "runs.csv")
    saved = table["settle_seconds_saved"].astype(float)
    assert len(table) == 3 and (saved > 0).sum() >= 2  # one run settled it; with one worker, the others not
    assert res.settle_seconds_saved == pytest.approx(saved.sum())
    assert json.loads((tmp_path / "calibration.json").read_text())["settle_seconds_saved"] == pytest.approx(saved.sum())
    with pytest.raises(ParameterError, match="share_settling is not allowed for experiments 'inclined-wall'"):
        calibrate_joint([Target("inclined-wall", "critical_angle", 20.0, 0.1)], {"mu": (0.3, 0.5), "mur": (0.3, 0.45)},
                        search=JointSearch(share_settling=True), out=tmp_path / "wall", progress=False)
    assert not (tmp_path / "wall" / "inclined-wall").exists()


def test_the_command_refuses_sharing_where_no_target_can_share_in_one_line(tmp_path):
    import subprocess
    import sys

    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", "calibrate", "--target",
                          "inclined-wall.critical_angle=20±0.1", "--free", "mu=0.3:0.5", "--free", "mur=0.3:0.45",
                          "--share-settling", "--out", str(tmp_path / "cal"), "--no-progress"],
                         capture_output=True, text=True)
    assert res.returncode == 2 and "Traceback" not in res.stderr, res.stderr
    assert res.stderr.startswith("error: share_settling is not allowed for experiments 'inclined-wall'")
    assert len(res.stderr.strip().splitlines()) == 1


def test_a_case_run_from_a_reference_first_stage_goes_on_with_its_own_material(tmp_path):
    """``run_prepared`` with a reference: the slope of the test above as a case file, a 0.2 s stage
    that holds the sphere, then 0.1 s. The reference (mu_r = 0.5) holds it through the first stage,
    made once and kept; a run with mu_r = 0.05 starts from that end and rolls at (5/7) g (sin beta -
    mu_r cos beta) over the second stage only (2 %, as above): its own material through both
    stages would give it 3 times that speed, the reference's none. A second run from the kept
    stage says what it saved; the first made it and saved nothing."""
    from rollingdem.experiments.case_file import stage_keys
    from rollingdem.io.casefile import load_case
    from rollingdem.io.runner import run_prepared
    from rollingdem.scene.simulation import Simulation

    beta = math.atan(0.2)
    r = 0.005

    def data(mur):
        m = {"name": "m", "youngs_modulus": 40e6, "poisson_ratio": 0.49, "density": 1056.0, "friction": 0.8,
             "rolling_friction": mur, "restitution": 0.5, "rolling_damping": 0.0}
        return {"name": "slope", "dt": 1e-5, "gravity": [G * math.sin(beta), 0.0, -G * math.cos(beta)],
                "contact": {"normal": "hertz", "rolling": "epsd"}, "materials": [m],
                "walls": [{"type": "plane", "name": "floor", "material": "m"}],
                "particles": [{"positions": [[0.0, 0.0, r]], "radius": r, "material": "m", "allow_overlap": True}],
                "stages": [{"name": "hold", "duration": 0.2}, {"name": "roll", "duration": 0.1}],
                "output": {"plot": False}}

    reference = data(0.5)
    keys = stage_keys(reference)
    first = run_prepared(load_case(data(0.05)), tmp_path / "a", tmp_path / "cache", keys, echo=lambda *_: None,
                         reference=load_case(reference))
    second = run_prepared(load_case(data(0.1)), tmp_path / "b", tmp_path / "cache", keys, echo=lambda *_: None,
                          reference=load_case(reference))
    assert [p.name for p in (tmp_path / "cache").iterdir()] == [keys[0]]
    assert first["prepared"]["seconds_saved"] == 0.0 and second["prepared"]["seconds_saved"] > 0.0
    for summary, mur in ((first, 0.05), (second, 0.1)):
        assert summary["status"] == "ok" and summary["prepared"]["after_stage"] == "hold"
        end = Simulation.restore(Path(summary["output"]) / "final.npz")
        expected = 5.0 / 7.0 * G * (math.sin(beta) - mur * math.cos(beta)) * 0.1
        assert end.velocities[0, 0] == pytest.approx(expected, rel=0.02)
