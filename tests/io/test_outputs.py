"""Outputs a user opens elsewhere: CSV in pandas, VTU/PVD in ParaView (read back with meshio), the CLI."""

import json
import math
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

import rollingdem as rd
from rollingdem.cli import app
from conftest import R


def small_scene(table1):
    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), dt=1e-5)
    sim.add_material(table1())
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m"))
    sim.add_particles([[0, 0, R], [3 * R, 0, R]], R, "m", velocity=[[0.1, 0, 0], [0, 0, 0]])  # resting on the plate
    return sim


def test_time_series_csv_and_snapshots(table1, tmp_path):
    meshio = pytest.importorskip("meshio")
    sim = small_scene(table1)
    series = rd.TimeSeries(tmp_path / "series.csv", interval=1e-3, particles=[0])
    snaps = rd.VTKSnapshots(tmp_path / "vtk", interval=5e-3)
    sim.run(0.02, observers=[series, snaps])
    df = pd.read_csv(tmp_path / "series.csv")
    assert len(df) == 21  # t = 0, 1 ms, ..., 20 ms
    assert np.allclose(np.diff(df["time"]), 1e-3)
    # the columns hold what they say: the last row is the present state
    tr, rot = sim.kinetic_energy()
    assert df["kinetic_translational"].iloc[-1] == tr and df["kinetic_rotational"].iloc[-1] == rot
    assert df["p0_x"].iloc[-1] == sim.positions[0, 0] and df["p0_wy"].iloc[-1] == sim.angular_velocities[0, 1]
    assert df["contacts"].iloc[-1] == sim.number_of_contacts() == 2  # both spheres on the plate
    state_at_20ms = {"x": sim.positions.copy(), "w": sim.angular_velocities.copy()}
    # a second run appends without repeating the row at the shared instant
    sim.run(0.005, observers=[series])
    df2 = pd.read_csv(tmp_path / "series.csv")
    assert len(df2) == 26 and df2["time"].is_monotonic_increasing and df2["step"].is_unique

    pvd = ET.parse(tmp_path / "vtk" / "particles.pvd").getroot()
    files = [d.get("file") for d in pvd.iter("DataSet")]
    assert len(files) == 5  # 0, 5, 10, 15, 20 ms
    mesh = meshio.read(tmp_path / "vtk" / files[-1])
    np.testing.assert_array_equal(mesh.points, state_at_20ms["x"])
    np.testing.assert_array_equal(mesh.point_data["radius"], sim.radii)
    np.testing.assert_array_equal(mesh.point_data["angular_velocity"], state_at_20ms["w"])
    assert mesh.point_data["material"].tolist() == [0, 0]


CASE = """
name: tiny
dt: 1.0e-5
materials:
  - {name: m, youngs_modulus: 4.0e7, poisson_ratio: 0.49, density: 1056, friction: 0.8, rolling_friction: 0.2}
contact: {normal: hertz, rolling: cdt}
walls:
  - {type: plane, name: floor, material: m}
  - {type: cylinder, name: tube, material: m, radius: 0.02}
particles:
  - insert: {type: cylinder, radius: 0.02, z_min: 0.0, z_max: 0.05}
    count: 20
    radius: {distribution: uniform, low: 0.003, high: 0.004}
    material: m
    seed: 4
stages:
  - {name: settle, duration: 0.02}
  - {name: release, remove_walls: [tube], duration: 0.01}
output:
  time_series: {interval: 0.001}
  snapshots: {interval: 0.01}
"""


def test_cli_runs_a_case_file(tmp_path):
    case = tmp_path / "tiny.yaml"
    case.write_text(CASE)
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["steps"] == 3000 and summary["particles"] == 20
    assert (out / "kinetic_energy.png").stat().st_size > 1000
    assert len(pd.read_csv(out / "series.csv")) == 31
    restored = rd.Simulation.restore(out / "final.npz")
    assert restored.step == 3000 and restored.n_particles == 20 and len(restored.walls) == 1


def test_cli_reports_bad_case_clearly(tmp_path):
    case = tmp_path / "bad.yaml"
    case.write_text(CASE.replace("count: 20", "cuont: 20"))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 2
    assert "particles.0" in result.output and "cuont" in result.output and "not a known key" in result.output
    assert "did you mean 'count'?" in result.output
    result = CliRunner().invoke(app, ["run", str(tmp_path / "nope.yaml")])
    assert result.exit_code == 2 and "does not exist" in result.output


def test_default_case_is_valid():
    """The main job: 4,000 free spheres over a rough base (on which the pile ends at rest, README),
    a tube lifted off it slowly, and the pile measured at the end."""
    from rollingdem.io.casefile import build_simulation, default_case_path, load_case

    spec = load_case(default_case_path())
    sim = build_simulation(spec)
    assert int((~sim.fixed).sum()) == 4000 and sim.fixed.any() and spec.dt is None and sim.dt_automatic
    # 0.2 x the Rayleigh time of the smallest sphere (LIGGGHTS's formula; E 40 MPa, nu 0.49, rho 1056)
    shear = 40e6 / (2 * 1.49)
    rayleigh = math.pi * sim.radii.min() * math.sqrt(1056.0 / shear) / (0.1631 * 0.49 + 0.8766)
    assert sim.dt == pytest.approx(0.2 * rayleigh, rel=1e-12) and 2.3e-5 < sim.dt < 2.34e-5
    assert [w.name for w in sim.walls] == ["plate", "tube"]
    assert spec.output.repose_angle is not None
    lift = spec.stages[1].wall_motion[0]
    assert lift.wall == "tube" and lift.velocity[2] * spec.stages[1].duration > 0.11  # above the pile's apex
    # the base reaches past the pile's foot (about 0.2 m from the axis; README): 0.3 m each way
    assert sim.positions[sim.fixed, 0].min() < -0.29 and sim.positions[sim.fixed, 0].max() > 0.29
    checked = CliRunner().invoke(app, ["check", str(default_case_path())])
    fixed = int(sim.fixed.sum())
    assert f"valid; {4000 + fixed} particles (4000 free, {fixed} fixed), 2 walls" in checked.output, checked.output


def test_a_case_reports_the_repose_angle_of_its_pile(tmp_path):
    """``output: {repose_angle: {}}`` measures the free spheres' pile at the end: printed, in
    summary.json and drawn in pile.png. The spheres stand as an exact 30-degree pile (every surface
    top on the cone, tests/analysis/test_analysis.py's ideal_pile, on which the fit is exact to 0.01 degree)
    and the run is of no steps (the measurement is what is tested, not the run), so the printed
    angle must be 30 to the fit's 0.01 degree.
    A fixed sphere below the floor would pull the floor down if it were measured with the pile:
    the floor is the top of the highest fixed sphere."""
    from helpers import RADIUS, ideal_pile

    pos = ideal_pile(30.0, n_base=8, foot_width=1, seed=3)  # 462 spheres: the small scenes' serial kernel
    case = tmp_path / "pile.yaml"
    case.write_text(f"""
name: pile
dt: 1.0e-5
gravity: [0, 0, 0]
materials:
  - {{name: m, youngs_modulus: 4.0e7, poisson_ratio: 0.49, density: 1056, friction: 0.8, rolling_friction: 0.2}}
contact: {{normal: hertz, rolling: cdt}}
particles:
  - {{positions: {json.dumps(pos.tolist())}, radius: {RADIUS}, material: m, allow_overlap: true}}
  - {{positions: [[0.5, 0.5, {-RADIUS}]], radius: {RADIUS}, material: m, fixed: true}}
stages: [{{duration: 0.0}}]
output: {{time_series: {{interval: 0.001}}, repose_angle: {{floor: 0.0}}}}
""")
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["repose_angle"]["angle"] == pytest.approx(30.0, abs=0.01)
    assert f"repose angle: {summary['repose_angle']['angle']:.1f} deg" in result.output
    assert (tmp_path / "o" / "pile.png").stat().st_size > 10_000
    # without a floor given, the top of the highest fixed sphere (z = 0 here) is the floor
    case.write_text(case.read_text().replace("repose_angle: {floor: 0.0}", "repose_angle: {}"))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o2"), "--no-progress"])
    assert json.loads((tmp_path / "o2" / "summary.json").read_text())["repose_angle"]["floor"] == 0.0
    # a heap too flat to fit a cone is said in one line, and the run still succeeds
    flat = pos[pos[:, 2] < 2 * RADIUS]
    case.write_text(case.read_text().replace(json.dumps(pos.tolist()), json.dumps(flat.tolist())))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o3"), "--no-progress"])
    assert result.exit_code == 0 and "repose angle: not measured:" in result.output


def test_case_file_selects_rolling_and_twisting_models_with_their_parameters(tmp_path):
    """Every rolling model and its parity preset are reachable from a case file; a parameter the
    model does not have is refused with its name, its value and the allowed names."""
    from rollingdem.io.casefile import build_simulation, load_case

    case = tmp_path / "models.yaml"
    contact = ("contact: {normal: hertz, rolling: {model: epsd, parity: liggghts, damping_ratio: 0.1}, "
               "twisting: marshall}")
    case.write_text(CASE.replace("contact: {normal: hertz, rolling: cdt}", contact))
    sim = build_simulation(load_case(case))
    assert isinstance(sim.contact.rolling, rd.EPSD) and sim.contact.rolling.parity == "liggghts"
    assert sim.contact.rolling.damping_ratio == 0.1 and isinstance(sim.contact.twisting, rd.Marshall)
    case.write_text(CASE.replace("rolling: cdt", "rolling: {model: sds, rolling_stifness: 1.0e4}"))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 2
    assert "rolling_stifness = 10000.0 is not known" in result.output and "rolling_stiffness" in result.output
    case.write_text(CASE.replace("rolling: cdt", "rolling: {model: cdt, parity: pfc}"))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 2 and "cdt parity = 'pfc' is not known" in result.output


def test_a_case_refused_in_a_later_stage_keeps_its_outputs(tmp_path):
    """check_case refuses what is known before the first step; a refusal that depends on the state
    a stage reaches (here the second stage sets a speed whose Hertz time the dt exceeds) comes
    from run alone, as one line that names the stage and the output folder, whose files stay
    readable."""
    case = tmp_path / "late.yaml"
    case.write_text(CASE.replace("{name: release, remove_walls: [tube], duration: 0.01}",
                                 "{name: kick, duration: 0.01, set_velocity: {particles: [0], velocity: [0, 0, -2000]}}"))
    checked = CliRunner().invoke(app, ["check", str(case)])
    assert checked.exit_code == 0, checked.output
    out = tmp_path / "out"
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    assert result.exit_code == 2 and "Traceback" not in result.output, result.output
    line = [x for x in result.output.splitlines() if x.startswith("error:")][0]
    assert "stage 'kick' at t = 0.02 s: dt = 1e-05 s exceeds the stable limit" in line and str(out) in line
    assert "set check_timestep: false in the case file" in line
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"].startswith("failed: dt = 1e-05 s") and summary["steps"] == 2000
    assert len(pd.read_csv(out / "series.csv")) == 21
    assert rd.Simulation.restore(out / "final.npz").step == 2000


def test_progress_bar_says_compiling_and_leaves_the_compile_out_of_its_rate(table1):
    """The first chunk of a fresh kernel is its compilation: the bar says so, and its time counts
    in neither the steps/s nor the time left (a 30 s compile of 64 steps would show 2 steps/s and
    hours left). A kernel that has run before counts from the first chunk."""
    from rollingdem.scene.progress import Progress as _Progress

    sim = small_scene(table1)
    bar = _Progress(sim, 10_064, "settle")
    assert bar.bar.desc == "settle (compiling)"
    bar.update(sim, 64, 30.0)
    bar.update(sim, 2_000, 1.0)
    assert bar.bar.desc == "settle"
    assert bar.bar.postfix == "2,000 steps/s, 0:04 left"  # 8,000 steps left at 2,000 steps/s
    bar.close()
    warm = _Progress(sim, 4_000, "collapse", warm=True)
    assert warm.bar.desc == "collapse"
    warm.update(sim, 1_000, 1.0)
    assert warm.bar.postfix == "1,000 steps/s, 0:03 left"
    warm.close()


@pytest.mark.slow
def test_the_default_case_ends_at_rest_and_measures_its_pile(tmp_path):
    """``rollingdem run`` with no file (about 3 minutes on 2 cores): both stages that wait for the
    bed end settled, not at their limits; the kinetic energy at the end is below 1e-8 of its peak
    (the rough base stops spin about any axis, README). The pile is a cone: the fit's R² at least
    0.8 (0.915, 0.912 and 0.914 for seeds 1 to 3), the angle between 20 and 40 degrees (31.06,
    31.44 and 31.06 at mu_r = 0.2), and each of the estimator's options (exclude_apex 0.05-0.35,
    exclude_toe 0.05-0.25) reads it within 1.6 degrees (seed 1: -1.53 to +1.24; seeds 2 and 3:
    -1.31 to +0.95 and -1.31 to +1.32; the lowest reading, for every seed, leaves out the most of
    the toe and the least of the apex): the bound is these seeds' spread, not a law. At the report's
    1e-5 s the same seeds' options read -1.61 to +1.21, -1.26 to +0.97 and -1.73 to +1.07: the
    spread is the estimator's on this pile, not the time step's."""
    result = CliRunner().invoke(app, ["run", "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    series = pd.read_csv(tmp_path / "o" / "series.csv")
    assert series["kinetic_total"].iloc[-1] < 1e-8 * series["kinetic_total"].max()
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert [s["ended"][:7] for s in summary["stages"]] == ["settled", "duratio", "settled"]
    pile = summary["repose_angle"]
    assert 20.0 < pile["angle"] < 40.0 and pile["r_squared"] >= 0.8
    assert max(abs(a - pile["angle"]) for a in pile["options"].values()) <= 1.6
    assert (tmp_path / "o" / "pile.png").exists() and "repose angle:" in result.output


def test_planes_and_cylinders_are_in_the_snapshots_once_while_they_stand_still(tmp_path):
    """Spheres falling in an infinite upright tube onto a floor, beside a finite cylinder lying along
    x, snapshot 4 times: each wall is one VTU file with one entry in its PVD (none moved). The
    floor's patch lies in its plane and covers every sphere seen from above; the tubes' vertices
    lie on their radius about their axes (1e-12 m); the lying one spans exactly its extent, the
    upright one every sphere's height."""
    import xml.etree.ElementTree as ET

    import meshio

    sim = rd.Simulation(gravity=(0, 0, -9.81))
    sim.add_material(rd.Material("m", 1e7, 0.3, 1000.0, friction=0.5, restitution=0.5))
    sim.add_wall(rd.Plane((0, 0, 0), (0, 0, 1), material="m", name="floor"))
    sim.add_wall(rd.Cylinder(0.03, material="m", name="tube"))
    sim.add_wall(rd.Cylinder(0.02, point=(0.5, 0.0, 0.1), axis=(1, 0, 0), extent=(0.0, 0.2), material="m",
                             name="roller"))
    sim.insert(rd.CylinderRegion(0.03, 0.0, 0.1), 40, 0.004, "m", seed=1)
    sim.run(0.03, observers=[rd.VTKSnapshots(tmp_path / "vtk", interval=0.01)])
    for name in ("floor", "tube", "roller"):
        entries = list(ET.parse(tmp_path / "vtk" / f"wall_{name}.pvd").getroot().iter("DataSet"))
        assert len(entries) == 1 and len(list((tmp_path / "vtk").glob(f"wall_{name}_*.vtu"))) == 1
    read = {n: meshio.read(next((tmp_path / "vtk").glob(f"wall_{n}_*.vtu"))).points for n in ("floor", "tube", "roller")}
    assert np.all(read["floor"][:, 2] == 0.0)
    half = read["floor"][:, :2].max(axis=0)
    assert np.all(np.abs(sim.positions[:, :2]) < half)
    assert np.allclose(np.hypot(read["tube"][:, 0], read["tube"][:, 1]), 0.03, atol=1e-12)
    assert read["tube"][:, 2].min() < sim.positions[:, 2].min() and read["tube"][:, 2].max() > sim.positions[:, 2].max()
    assert np.allclose(np.hypot(read["roller"][:, 1], read["roller"][:, 2] - 0.1), 0.02, atol=1e-12)
    assert sorted(set(np.round(read["roller"][:, 0], 12))) == [0.5, 0.7]


def test_the_schema_command_prints_a_json_schema_the_shipped_cases_meet():
    """``rollingdem schema`` prints the case file's JSON Schema: every shipped case file meets it
    (jsonschema), and a case with an unknown top-level key, a mesh wall without its material or a
    restitution of 0 (outside the declared (0, 1]) does not; a material's properties carry the
    unit, bounds and description the contact laws declare."""
    import jsonschema

    from rollingdem.experiments.case_file import shipped_cases
    from rollingdem.io.mapping_file import read_mapping

    result = CliRunner().invoke(app, ["schema"])
    assert result.exit_code == 0
    schema = json.loads(result.output)
    for path in shipped_cases().values():
        jsonschema.validate(read_mapping(path)[0], schema)
    data = read_mapping(shipped_cases()["drum"])[0]
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate({**data, "colour": "red"}, schema)
    bad = json.loads(json.dumps(data))
    bad["materials"][0]["restitution"] = 0.0
    with pytest.raises(jsonschema.ValidationError, match="less than or equal to the minimum of 0"):
        jsonschema.validate(bad, schema)
    data["walls"][0] = {k: v for k, v in data["walls"][0].items() if k != "material"}
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(data, schema)
    material = schema["$defs"]["MaterialSpec"]["properties"]
    assert material["surface_energy"]["unit"] == "J/m^2" and material["surface_energy"]["minimum"] == 0.0
    assert material["poisson_ratio"]["exclusiveMaximum"] == 0.5
    assert "rolling friction" in material["rolling_friction"]["description"]


def test_no_command_shows_a_type_for_a_flag():
    """Every command's help: a flag (--overwrite, --no-progress, --help) takes no value, so no
    ``<bool>`` is shown; options that take one keep their type (``<path>``)."""
    commands = ["run", "validate", "bench", "sweep", "calibrate", "check", "schema", "experiments"]
    for command in commands:
        result = CliRunner().invoke(app, [command, "--help"], env={"COLUMNS": "200"})
        assert result.exit_code == 0 and "<bool>" not in result.output, command
    assert "<path>" in CliRunner().invoke(app, ["run", "--help"], env={"COLUMNS": "200"}).output


def test_each_command_s_help_runs_on_unbroken_and_lists_what_there_is():
    """A command's description is its docstring's paragraphs, each one line for the terminal to
    wrap: at 400 columns each first paragraph stands on one line of its help (a docstring's own line
    breaks once cut sentences in two). ``shapes`` lists every ready-made mesh shape with each of
    its dimensions, and ``experiments show`` a built-in experiment's every parameter with its
    default, and every observable."""
    import inspect

    from rollingdem.experiments import EXPERIMENTS
    from rollingdem.scene.mesh import SHAPES

    def walk(typer_app, prefix=()):
        for info in typer_app.registered_commands:
            yield prefix + ((info.name or info.callback.__name__).replace("_", "-").removeprefix("experiments-"),), info
        for group in typer_app.registered_groups:
            yield from walk(group.typer_instance, prefix + (group.name,))

    for words, info in walk(app):
        first = " ".join(inspect.cleandoc(info.callback.__doc__).split("\n\n")[0].split())
        out = CliRunner().invoke(app, [*words, "--help"], env={"COLUMNS": "400"}).output
        assert first in " ".join(line.strip(" │") for line in out.splitlines()), words
        assert any(first in line for line in out.splitlines()), words
    listed = CliRunner().invoke(app, ["shapes"]).output
    for name, make in SHAPES.items():
        line = next(s for s in listed.splitlines() if s.startswith(f"{name}: "))
        assert all(k in line for k in inspect.signature(make).parameters), line
    shown = CliRunner().invoke(app, ["experiments", "show", "rotating-drum"]).output
    drum = EXPERIMENTS["rotating-drum"]
    for p in drum.parameters:
        assert any(s.split()[:3] == [p.name, "default", repr(p.default)] for s in shown.splitlines()), p.name
    assert all(any(s.split()[:1] == [k] for s in shown.splitlines()) for k in drum.observables)
