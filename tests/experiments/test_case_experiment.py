"""A user's case file swept and calibrated (issue 44, items 4 and 7): its numbers addressed by path
and short name, its measurements as observables, a calibration that finds the density a measured
mass asks for, and failed runs that say why."""

import json
import math

import pytest
from typer.testing import CliRunner

from rollingdem.cli import app
from rollingdem.errors import ParameterError
from rollingdem.experiments import get_experiment
from rollingdem.experiments.case_file import numeric_leaves, set_path

R = 0.002  # m
# 8 spheres listed (no seed: deterministic) resting on a floor, probed by a box around them
CASE = f"""\
name: beads
dt: 1.0e-5
materials:
  - {{name: glass, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5}}
walls:
  - {{type: plane, name: floor, material: glass}}
particles:
  - positions: [[0, 0, {R}], [0.01, 0, {R}], [0.02, 0, {R}], [0.03, 0, {R}], [0, 0.01, {R}], [0.01, 0.01, {R}],
                [0.02, 0.01, {R}], [0.03, 0.01, {R}]]
    radius: {R}
    material: glass
measurements:
  - {{name: box, type: probe, region: {{type: box, lo: [-0.01, -0.01, 0], hi: [0.04, 0.02, 0.01]}}}}
  - {{name: load, type: wall, wall: floor}}
stages:
  - {{name: rest, duration: 0.002}}
output:
  plot: false
"""
MASS = 8 * 4 / 3 * math.pi * R ** 3  # kg per kg/m^3 of density


def test_paths_name_list_entries_by_name_and_leave_vectors_out():
    data = {"materials": [{"name": "glass", "density": 2500.0}], "particles": [{"count": 3, "radius": 0.1}],
            "walls": [{"name": "floor", "point": [0, 0, 1]}], "stages": [{"name": "fill", "duration": 1}]}
    leaves = numeric_leaves(data)
    assert leaves == {"materials.glass.density": 2500.0, "particles.0.count": 3, "particles.0.radius": 0.1,
                      "stages.fill.duration": 1}
    set_path(data, "materials.glass.density", 1000.0)
    set_path(data, "particles.0.count", 5)
    assert data["materials"][0]["density"] == 1000.0 and data["particles"][0]["count"] == 5
    with pytest.raises(KeyError):
        set_path(data, "materials.steel.density", 1.0)


def test_a_case_files_parameters_and_observables(tmp_path):
    case = tmp_path / "beads.yaml"
    case.write_text(CASE)
    exp = get_experiment(str(case), observable=True)
    names = [p.name for p in exp.parameters]
    assert {"mu", "density", "E", "nu", "materials.glass.density", "stages.rest.duration"} <= set(names)
    assert "seed" not in names and not exp.stochastic  # spheres listed: nothing random
    assert {"box.mass", "box.count", "load.fz", "load.power"} <= set(exp.observables)
    with pytest.raises(ParameterError, match="'materials.steel.density' is not allowed: beads.yaml has no number"):
        exp.resolve({"materials.steel.density": 1.0})
    with pytest.raises(ParameterError, match="beads.yaml with mu = -1.0: .*friction"):
        exp.resolve({"mu": -1.0})
    with pytest.raises(ParameterError, match="'density' and 'materials.glass.density' are one number"):
        exp.resolve({"density": 1.0, "materials.glass.density": 2.0})


def test_coarse_graining_is_a_short_name_of_the_one_material_written_or_not(tmp_path):
    """A file that leaves coarse_graining out means 1 (no parcels); the short name sets the
    material's, adding the key; a value the material refuses is refused as the file would be."""
    case = tmp_path / "beads.yaml"
    case.write_text(CASE)
    exp = get_experiment(str(case), observable=True)
    assert exp.by_name["coarse_graining"].default == 1.0
    data = exp.case_data(exp.resolve({"coarse_graining": 2.0}))
    assert data["materials"][0]["coarse_graining"] == 2.0
    with pytest.raises(ParameterError, match="beads.yaml with coarse_graining = 0.5: .*coarse_graining"):
        exp.resolve({"coarse_graining": 0.5})


def test_a_sweep_of_a_case_file_measures_what_each_density_gives(tmp_path):
    """The probe's mass is 8 (4/3) pi r^3 rho: the sweep over rho through the short name gives it
    to round-off; the floor carries the spheres' weight (a 2 ms rest: within the 1 % their settling
    bounce leaves)."""
    (tmp_path / "beads.yaml").write_text(CASE)
    (tmp_path / "sweep.yaml").write_text("experiment: beads.yaml\ngrid:\n  density: [1000.0, 3000.0]\n")
    result = CliRunner().invoke(app, ["sweep", str(tmp_path / "sweep.yaml"), "--out", str(tmp_path / "o"),
                                      "--workers", "1", "--no-progress"])
    assert result.exit_code == 0, result.output
    import pandas as pd

    runs = pd.read_csv(tmp_path / "o" / "runs.csv").sort_values("density")
    assert list(runs["box.mass"]) == pytest.approx([1000.0 * MASS, 3000.0 * MASS], rel=1e-12)
    assert list(runs["box.count"]) == [8, 8]


def test_calibrating_a_case_file_finds_the_density_a_measured_mass_asks_for(tmp_path):
    """Target box.mass = 2000 kg/m^3 x 8 (4/3) pi r^3: the mass is linear in the density, so the
    monotone interpolation between the swept points gives 2000 to round-off."""
    case = tmp_path / "beads.yaml"
    case.write_text(CASE)
    target = 2000.0 * MASS
    result = CliRunner().invoke(app, ["calibrate", str(case), "--target", f"box.mass={target!r}",
                                      "--free", "density=500:3500", "--coarse", "4", "--rounds", "0",
                                      "--out", str(tmp_path / "cal"), "--workers", "1", "--no-progress"])
    assert result.exit_code == 0, result.output
    found = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert found["value"] == pytest.approx(2000.0, rel=1e-9)


def test_failed_runs_say_why_and_a_calibration_with_none_usable_exits_2(tmp_path):
    """A stage of negative duration fails each run with the case file's own message: the sweep
    prints the count and the first reason; a calibration whose runs all failed exits 2 with it."""
    case = tmp_path / "beads.yaml"
    case.write_text(CASE)
    result = CliRunner().invoke(app, ["calibrate", str(case), "--target", "box.mass=0.001",
                                      "--free", "stages.rest.duration=-0.002:-0.001", "--coarse", "3", "--rounds", "0",
                                      "--out", str(tmp_path / "cal"), "--workers", "1", "--no-progress"])
    assert result.exit_code == 2, result.output
    line = [x for x in result.output.splitlines() if x.startswith("error:")]
    assert len(line) == 1
    assert "calibration needs at least two points with a finite box.mass, and has 0: 3 of 3 runs failed" in line[0]
    assert "duration = -0.002 is not allowed" in line[0] and "runs.csv (column error)" in line[0]
    bad = CliRunner().invoke(app, ["calibrate", str(case), "--target", "box.weight=1", "--free", "density=1:2",
                                   "--out", str(tmp_path / "c2"), "--no-progress"])
    assert bad.exit_code == 2 and "beads.yaml measures box.count" in bad.output


def test_the_shipped_case_files_are_listed_shown_and_valid(tmp_path):
    """``rollingdem experiments list`` names each shipped case file and built-in experiment; ``show``
    prints a file that, saved, ``rollingdem check`` accepts; an unknown name is refused."""
    from rollingdem.experiments.case_file import shipped_cases

    listed = CliRunner().invoke(app, ["experiments", "list"])
    assert listed.exit_code == 0
    for name in (*shipped_cases(), "rotating-drum", "silo-discharge"):
        assert f"  {name} " in listed.output
    for name, path in shipped_cases().items():  # each case file's first sentence, whole, across its lines
        line = next(x for x in listed.output.splitlines() if x.startswith(f"  {name} ")).strip()[len(name):].lstrip()
        comment = " ".join(" ".join(x.lstrip("#").strip() for x in path.read_text().splitlines()
                                    if x.startswith("#")).split())
        assert line.endswith(".") and comment.startswith(line) and comment[len(line):len(line) + 1] in ("", " ")
    for name, path in shipped_cases().items():
        shown = CliRunner().invoke(app, ["experiments", "show", name])
        assert shown.exit_code == 0 and shown.output == path.read_text()
        (tmp_path / f"{name}.yaml").write_text(shown.output)
        checked = CliRunner().invoke(app, ["check", str(tmp_path / f"{name}.yaml")])
        assert checked.exit_code == 0, checked.output
    bad = CliRunner().invoke(app, ["experiments", "show", "angle-of-repos"])
    assert bad.exit_code == 2 and "the case files shipped are pile, drum-slice, drum, hopper, repose-rough-base, silo" in bad.output
    assert "the built-in experiments are" in bad.output and "angle-of-repose" in bad.output


def test_runs_that_share_their_first_stage_share_it_and_end_as_from_scratch(tmp_path):
    """A sweep over the second stage's duration: the first stage (a bed of 40 spheres poured onto a
    floor) is the same for both runs, so the second starts from the first's state at its end. Its
    observables equal, bit for bit, those of the same run from scratch (``resume_case`` continues bit
    for bit), and runs.csv says what the preparation saved."""
    import pandas as pd

    from rollingdem.experiments.case_file import CaseExperiment

    text = CASE.replace("""  - positions: [[0, 0, {R}], [0.01, 0, {R}], [0.02, 0, {R}], [0.03, 0, {R}], [0, 0.01, {R}], [0.01, 0.01, {R}],
                [0.02, 0.01, {R}], [0.03, 0.01, {R}]]
    radius: {R}
    material: glass""".format(R=R), """  - insert: {type: box, lo: [-0.01, -0.01, 0.0], hi: [0.04, 0.02, 0.03]}
    count: 40
    radius: 0.002
    material: glass
    seed: 1""").replace("  - {name: rest, duration: 0.002}", "  - {name: pour, duration: 0.02}\n"
                                                                 "  - {name: rest, duration: 0.002}")
    assert "pour" in text and "insert" in text
    (tmp_path / "bed.yaml").write_text(text)
    (tmp_path / "sweep.yaml").write_text("experiment: bed.yaml\ngrid:\n  stages.rest.duration: [0.002, 0.004]\n")
    result = CliRunner().invoke(app, ["sweep", str(tmp_path / "sweep.yaml"), "--out", str(tmp_path / "o"),
                                      "--workers", "1", "--no-progress"])
    assert result.exit_code == 0, result.output
    runs = pd.read_csv(tmp_path / "o" / "runs.csv").sort_values("stages.rest.duration")
    assert (runs["prepared.seconds_saved"] > 0).sum() == 1
    assert "1 of 2 runs started from a bed an earlier run prepared" in result.output
    scratch = CaseExperiment(tmp_path / "bed.yaml")
    for _, row in runs.iterrows():
        fresh = scratch.observe(scratch.resolve({"stages.rest.duration": row["stages.rest.duration"], "seed": 1}))
        for name, value in fresh.items():
            if name != "prepared.seconds_saved":
                assert value == row[name] or (math.isnan(value) and math.isnan(row[name])), name


def test_a_wall_driven_in_rpm_turns_at_two_pi_rpm_over_60_radians_a_second(tmp_path):
    """A drum's motion given as rpm: 30 rpm is pi rad/s about its axis, for the mesh drum and for a
    plane cap turning with it (a plane turns about its own point: it takes no rotation point)."""
    import rollingdem as rd

    (tmp_path / "drum.yaml").write_text(f"""\
name: rpm
dt: 1.0e-5
gravity: [0, -9.81, 0]
materials:
  - {{name: glass, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5}}
walls:
  - {{type: mesh, name: drum, material: glass, shape: drum, size: {{radius: 0.05, length: 0.02, caps: false}}}}
  - {{type: plane, name: cap, material: glass, point: [0, 0, 0], normal: [0, 0, 1]}}
particles:
  - {{positions: [[0, -0.04, 0.01]], radius: {R}, material: glass}}
stages:
  - name: turn
    duration: 0.0001
    wall_motion:
      - {{wall: drum, rotate: {{axis: [0, 0, 1], point: [0, 0, 0], rpm: 30}}}}
      - {{wall: cap, rotate: {{axis: [0, 0, 1], rpm: 30}}}}
output: {{plot: false, report: null}}
""")
    result = CliRunner().invoke(app, ["run", str(tmp_path / "drum.yaml"), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    walls = {w.name: w for w in rd.Simulation.restore(tmp_path / "o" / "final.npz").walls}
    for name in ("drum", "cap"):
        assert walls[name].angular_velocity == pytest.approx((0.0, 0.0, math.pi), abs=1e-12), name
    bad = (tmp_path / "drum.yaml").read_text().replace("{axis: [0, 0, 1], rpm: 30}", "{axis: [0, 0, 1], rpm: 30, "
                                                                                     "point: [0, 0, 0]}")
    (tmp_path / "bad.yaml").write_text(bad)
    refused = CliRunner().invoke(app, ["check", str(tmp_path / "bad.yaml")])
    assert refused.exit_code == 2 and "a plane or cylinder turns about its own point" in refused.output


def test_a_target_the_first_runs_cannot_reach_is_refused_in_one_line(tmp_path):
    """The probe's mass over densities 500-3500 kg/m^3 spans 500-3500 x 8 (4/3) pi r^3; a target of
    ten times the top is outside what the first runs give: one line naming the target, the range
    and what to do, exit 2, the runs kept."""
    case = tmp_path / "beads.yaml"
    case.write_text(CASE)
    result = CliRunner().invoke(app, ["calibrate", str(case), "--target", f"box.mass={35000 * MASS!r}",
                                      "--free", "density=500:3500", "--coarse", "3", "--rounds", "0",
                                      "--out", str(tmp_path / "cal"), "--workers", "1", "--no-progress"])
    assert result.exit_code == 2, result.output
    line = [x for x in result.output.splitlines() if x.startswith("error:")]
    assert len(line) == 1 and "is outside what density in [500, 3500] gives" in line[0]
    assert "widen the range with --free density=LOW:HIGH" in line[0]
    assert (tmp_path / "cal" / "runs.csv").exists()


FLAT = """\
name: layer
materials:
  - {{name: glass, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5, restitution: 0.3}}
walls:
  - {{type: plane, name: floor, material: glass}}
particles:
  - positions: {positions}
    radius: 0.0025
    material: glass
measurements:
  - {{name: surface, type: profile, file: measured.csv, shape: heap, center: [0, 0]}}
stages:
  - {{name: land, duration: 0.04}}
output: {{plot: false, report: null}}
"""


def test_a_measured_profile_calibrates_the_size_that_matches_it(tmp_path):
    """A layer of spheres on a floor, its surface measured as flat at 4 mm (a CSV of r, h): the
    profile's misfit is |2 R - 4 mm| over the layer, lowest at R = 2 mm, which the minimum search
    over R in [1.5, 3] mm finds within a tenth of a millimetre (its last round's spacing is 0.075
    mm and the parabola through five points of a V stays within one spacing of its tip)."""
    import numpy as np

    from rollingdem.io.rig_measurements import SurfaceProfile, read_profile

    g = np.arange(-0.026, 0.0261, 0.0065)
    xy = np.array([(a, b) for a in g for b in g])
    positions = [[float(a), float(b), 0.0031] for a, b in xy]
    (tmp_path / "layer.yaml").write_text(FLAT.format(positions=positions))
    (tmp_path / "measured.csv").write_text("r,h\n" + "".join(f"{r:.4f},0.004\n" for r in np.linspace(0, 0.015, 7)))
    assert read_profile(tmp_path / "measured.csv").shape == (7, 2)
    result = CliRunner().invoke(app, ["calibrate", str(tmp_path / "layer.yaml"), "--target", "surface.rmse=min",
                                      "--free", "particles.0.radius=0.0015:0.003", "--coarse", "5", "--refine", "3",
                                      "--rounds", "2", "--out", str(tmp_path / "cal"), "--workers", "1",
                                      "--no-progress"])
    assert result.exit_code == 0, result.output
    found = json.loads((tmp_path / "cal" / "calibration.json").read_text())
    assert abs(found["value"] - 0.002) < 1e-4 and found["direction"] == "minimum"
    with pytest.raises(ParameterError, match="profile shape = 'cone' is not allowed"):
        SurfaceProfile("p", [[0, 0], [1, 1]], shape="cone")
    (tmp_path / "bad.csv").write_text("r\n1\n2\n")
    with pytest.raises(ParameterError, match="must hold two columns of numbers"):
        read_profile(tmp_path / "bad.csv")


def test_the_parabola_minimum_on_made_up_curves():
    """A parabola's vertex exactly (y = (x - 0.3)^2 + 1 at five points: 0.3 to round-off); a curve
    that opens downwards, or whose vertex lies outside the points, gives its lowest point."""
    import numpy as np

    from rollingdem.studies.calibration import parabola_minimum

    x = np.array([0.0, 0.15, 0.25, 0.4, 0.6])
    assert parabola_minimum(x, (x - 0.3) ** 2 + 1) == pytest.approx(0.3, abs=1e-12)
    assert parabola_minimum(x, -(x - 0.2) ** 2) == 0.6  # opens downwards: the lowest point
    assert parabola_minimum(x, (x - 2.0) ** 2) == 0.6  # vertex beyond the points


def test_a_heap_profile_is_read_at_its_end_state_and_a_drum_profile_over_its_window(tmp_path):
    """The layer falls 0.6 mm onto the floor in its first 11 ms: a heap's misfit, sampled every 2 ms
    over a window from t = 0, is the end state's (the sample at 40 ms), not the window's mean, which
    the fall raises; the same measurement as a drum's is the misfit of its surface averaged over the
    window."""
    import numpy as np

    from rollingdem.experiments.case_file import CaseExperiment
    from rollingdem.io.rig_measurements import SurfaceProfile

    g = np.arange(-0.026, 0.0261, 0.0065)
    positions = [[float(a), float(b), 0.0031] for a in g for b in g]
    text = FLAT.format(positions=positions).replace("shape: heap, center: [0, 0]}",
                                                    "shape: heap, center: [0, 0], interval: 0.002, window: [0, 0.04]}")
    (tmp_path / "layer.yaml").write_text(text)
    (tmp_path / "measured.csv").write_text("r,h\n" + "".join(f"{r:.4f},0.004\n" for r in np.linspace(0, 0.015, 7)))
    exp = CaseExperiment(tmp_path / "layer.yaml")
    got = exp.observe(exp.resolve({"particles.0.radius": 0.002}))["surface.rmse"]
    heap = SurfaceProfile("p", [[0, 0], [1, 1]])
    drum = SurfaceProfile("p", [[0, 0], [1, 1]], shape="drum")
    for m in (heap, drum):
        m._rows = [(0.0, 0, [3.0, 1.0]), (1.0, 1, [1.0, 1.0])]
        m.window = (0.0, 1.0)
    # the drum's two surfaces (heights 3, -1 and -3, 3 at the points) average to the measured one
    drum._heights = [np.array([3.0, -1.0]), np.array([-3.0, 3.0])]
    assert heap.summary()["rmse"]["value"] == 1.0 and drum.summary()["rmse"]["value"] == 0.0
    assert got < 1e-4  # the end state: 2 R = 4 mm, on the floor


def test_the_minimum_interval_spans_a_flat_bottom_and_is_narrow_at_a_sharp_one():
    """Made-up misfits with a standard error of 0.1 at each point, points packed near the lowest
    as refinement packs them. A flat bottom (0 on [0.4, 0.6], rising 10 per unit outside) is
    indistinguishable over its whole width, so the 95 % interval must reach most of it, beyond the
    five points nearest the lowest (0.44-0.52); a sharp one, 5 (x - 0.5)^2 * 100, gives an
    interval a few hundredths wide about 0.5."""
    import numpy as np

    from rollingdem.studies.calibration import local_minimum, minimum_interval

    x = np.array([0.0, 0.2, 0.4, 0.44, 0.46, 0.48, 0.5, 0.52, 0.6, 0.8, 1.0])
    flat = 10.0 * np.maximum(np.maximum(0.4 - x, x - 0.6), 0.0)
    errors = np.full(len(x), 0.1)
    low, high = minimum_interval(x, flat, errors, 2000, np.random.default_rng(1))
    assert low <= 0.42 and high >= 0.58
    sharp = 500.0 * (x - 0.5) ** 2
    assert local_minimum(x, sharp) == pytest.approx(0.5, abs=1e-9)
    low, high = minimum_interval(x, sharp, errors, 2000, np.random.default_rng(1))
    assert low < 0.5 < high and high - low < 0.05


def test_a_minimum_target_refuses_what_it_cannot_search_in_one_line(tmp_path):
    (tmp_path / "beads.yaml").write_text(CASE)
    cases = [
        (["--target", "box.mass=min", "--free", "density"], "free = 'density' is not allowed without its range"),
        (["--target", "box.mass=min", "--target", "load.fz=1", "--free", "density=1:2"],
         "a minimum is searched over one free parameter of one case file"),
        (["--target", "box.weight=min", "--free", "density=1:2"], "observable = 'box.weight' is not known"),
    ]
    for args, message in cases:
        result = CliRunner().invoke(app, ["calibrate", str(tmp_path / "beads.yaml"), *args, "--out",
                                          str(tmp_path / "cal"), "--no-progress"])
        assert result.exit_code == 2 and "Traceback" not in result.output, result.output
        assert result.output.startswith("error:") and message in result.output and result.output.count("\n") == 1
