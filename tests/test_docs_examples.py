"""The examples of README.md run as a user would paste them, scaled down where the text says how
long they take, and deliver what their text promises."""

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

ROOT = Path(__file__).parents[1]


def python_block(path: Path, after: str) -> str:
    """The first ```python block of ``path`` after the line ``after``."""
    text = path.read_text()
    return text[text.index(after):].split("```python\n", 1)[1].split("```", 1)[0]


def scaled(code: str, replacements: dict) -> str:
    """``code`` with each replacement made exactly once (a README edit that drops one fails here
    instead of running the example at full size)."""
    for old, new in replacements.items():
        assert code.count(old) == 1, f"README example changed: {old!r} found {code.count(old)} times"
        code = code.replace(old, new)
    return code


def test_the_readme_python_example_runs_and_its_checkpoint_continues_bit_for_bit(tmp_path, monkeypatch, capsys):
    """README, "Python": 1,500 spheres settle in a tube on a rough base, the tube is lifted 2 s, the
    pile rests; at a third of the spheres (500) in a tube of 0.045 m instead of 0.06 on a base of
    0.15 m instead of 0.2, the lift 1.5 s, the pile cut in 4 slices instead of 8 (too few surface
    spheres for 8). Both waiting runs end settled, the pile's angle is printed (a pile of 500
    spheres, a few layers high: between 10 and 45 degrees; a spread monolayer reads below 10), the time series has a row every
    1 ms with particle 0's columns, the VTK snapshots their PVD, and ``rd.Simulation.restore``
    continues the checkpoint bit for bit: 300 more steps of the restored run and of the original
    give equal positions and angular velocities."""
    import re

    import rollingdem as rd

    code = scaled(python_block(ROOT / "README.md", "## Python"),
                  {"count=1500": "count=500", "rd.CylinderRegion(0.06, 0.01, 0.35)": "rd.CylinderRegion(0.045, 0.01, 0.35)",
                   "rd.Cylinder(radius=0.06,": "rd.Cylinder(radius=0.045,",
                   "((-0.2, 0.2), (-0.2, 0.2))": "((-0.15, 0.15), (-0.15, 0.15))", "sim.run(2.0,": "sim.run(1.5,",
                   "floor=floor)": "floor=floor, n_slices=4)"})
    monkeypatch.chdir(tmp_path)
    scope = {}
    exec(compile(code.replace("progress=True", "progress=False"), "README.md", "exec"), scope)
    sim = scope["sim"]
    printed = capsys.readouterr().out.splitlines()
    assert printed[0].startswith("settled") and printed[1].startswith("settled")
    angle = float(re.match(r"repose angle ([0-9.]+) deg", printed[2]).group(1))
    assert 10.0 < angle < 45.0
    series = pd.read_csv(tmp_path / "out" / "series.csv")
    assert np.allclose(np.diff(series["time"])[:100], 1e-3) and any(c.startswith("p0_") for c in series.columns)
    assert len(list((tmp_path / "out" / "vtk").glob("particles_*.vtu"))) >= 20
    assert list((tmp_path / "out" / "vtk").glob("*.pvd"))
    restored = rd.Simulation.restore("out/final.npz")
    sim.run(steps=300)
    restored.run(steps=300)
    np.testing.assert_array_equal(restored.positions, sim.positions)
    np.testing.assert_array_equal(restored.angular_velocities, sim.angular_velocities)


def test_the_readme_boundaries_example_delivers_what_it_says():
    """README, "Fixed particles, outlets, inflows and periodic boundaries", run 0.02 s: the rough
    base never moves (its positions stay bit for bit), the inflow has inserted rate x t spheres at
    its last action t (it acts every 1 ms rounded to whole steps, 19 or 20 actions, so 95 or 100
    spheres, and its region holds them: no shortfall), every x lies in the periodic box, and each
    particle keeps its number."""
    import math

    import rollingdem as rd

    scope = {"rd": rd}
    exec(compile(python_block(ROOT / "README.md", "Fixed particles, outlets, inflows and periodic"),
                 "README.md", "exec"), scope)
    sim = scope["sim"]
    base = sim.n_particles
    fixed_at = sim.positions.copy()
    assert sim.fixed.all() and base > 100
    sim.run(0.02)
    counts = sim.boundary_counts()
    every = max(1, round(1e-3 / sim.dt))
    last = (sim.step // every) * every * sim.dt
    inserted = math.floor(5000 * last * (1 + 1e-12))
    assert inserted in (95, 100)
    assert counts["inflow_#0_count"] == inserted and counts["inflow_#0_shortfall"] == 0
    assert counts["outlet_orifice_count"] == 0  # nothing reaches z < -0.05 in 0.02 s
    assert sim.n_particles == base + inserted
    np.testing.assert_array_equal(sim.positions[:base], fixed_at)
    x = sim.positions[:, 0]
    assert (x >= -0.05).all() and (x < 0.05).all()
    np.testing.assert_array_equal(sim.particle_ids, np.arange(sim.n_particles))


def test_the_readme_servo_example_presses_its_spheres_to_two_kilopascals(capsys):
    """README, the wall programs: at full size (3 s). The lid comes down from 8 mm onto the settled
    300 spheres (their top some 6.5 mm: 300 x 4.19e-9 m^3 at a solid fraction near 0.6 on 4 cm^2)
    and holds 2 kPa: the printed pressure within 1 % of it, as the servo's own test holds it."""
    import rollingdem as rd

    scope = {"rd": rd}
    exec(compile(python_block(ROOT / "README.md", "Here a lid presses 300"), "README.md", "exec"), scope)
    sim, lid = scope["sim"], scope["lid"]
    top = float((sim.positions[:, 2] + 1e-3).max())
    assert lid.point[2] < 0.008 and abs(lid.point[2] - top) < 1e-4  # resting on the top spheres
    printed = capsys.readouterr().out
    pressure = float(printed.split("pressure ")[1].split(" Pa")[0])
    assert abs(pressure / 2000.0 - 1.0) < 0.01, printed


def test_the_readme_bonds_example_bonds_the_pairs_within_the_gap():
    """README, "Bonded particles": on a row of three spheres, the first two touching and the third
    2e-5 m from the second, ``gap=1e-5`` bonds the touching pair only, and the table names it,
    intact and unloaded (the bond starts at the pair's present distance)."""
    import rollingdem as rd

    sim = rd.Simulation(gravity=(0, 0, 0), dt=1e-6)
    sim.add_material(rd.Material("m", 1e8, 0.3, 2500))
    r = 0.001
    sim.add_particles([[0, 0, 0], [2 * r, 0, 0], [4 * r + 2e-5, 0, 0]], r, "m")
    scope = {"rd": rd, "sim": sim}
    code = python_block(ROOT / "README.md", "Bonded particles (Potyondy")
    exec(compile(code.replace("sim.bonds()", "table = sim.bonds()"), "README.md", "exec"), scope)
    table = scope["table"]
    assert list(zip(table["i"], table["j"])) == [(0, 1)]
    assert list(table["status"]) == ["intact"] and table["normal_force"].abs().max() == 0.0
    assert sim.bond_counts() == {"bonds_intact": 1, "bonds_broken_tension": 0, "bonds_broken_shear": 0}


def test_the_readme_convert_example_gives_mercurys_rolling_law():
    """README, "Other codes' parameters": MercuryDPM's rolling spring k at the lever 2 R* is the
    torque spring 4 k R*^2 of SDS (stiffness 4 k = 1000 N/m), and its force limit mu |F_n| at 2 R*
    the moment limit 2 mu R* |F_n| (mu_r = 2 mu = 0.2), which the material gets."""
    import rollingdem as rd

    scope = {"rd": rd}
    exec(compile(python_block(ROOT / "README.md", "## Other codes' parameters"), "README.md", "exec"), scope)
    sim = scope["sim"]
    assert sim.contact.rolling.name == "sds" and sim.contact.rolling.settings()["rolling_stiffness"] == 1000.0
    assert sim.materials["m"].rolling_friction == 0.2


def test_the_readme_sweep_and_calibration_example(tmp_path, monkeypatch):
    """README, "In Python" of the sweeps: the sweep of rolling-flat at mu_r = 0.1, 0.2, 0.3 as
    written (3 runs of about a second, on one worker here) gives the stop distances of the
    analytic solution (docs/models.md §13 T2) within 1 %; the calibration line runs scaled down:
    rolling-flat's stop distance (deterministic, 1 run a point) instead of the pile's angle
    (piles of 2,000 spheres over seeds, hours), target the analytic distance at mu_r = 0.25 with
    an uncertainty of 1 % of it: the mu_r found is 0.25 to within the 1 % of the distance (which
    moves mu_r by about as much) and its 95 % interval holds 0.25."""
    from rollingdem.experiments.single_sphere import analytic_flat

    code = scaled(python_block(ROOT / "README.md", "In Python:"),
                  {'"sweep-out").table': '"sweep-out", workers=1, progress=False).table',
                   'calibrate("angle-of-repose", target=25.0, uncertainty=1.0, fix={"mu": 0.5}, free="mur", '
                   'out="cal-out")': 'calibrate("rolling-flat", target=TARGET, uncertainty=0.01 * TARGET, '
                                     'fix={"mu": 0.8}, free=("mur", (0.1, 0.5)), out="cal-out", progress=False)'})
    monkeypatch.chdir(tmp_path)
    target = analytic_flat(1.0, 0.8, 0.25)[3]
    scope = {"TARGET": target}
    exec(compile(code, "README.md", "exec"), scope)
    table = scope["table"].sort_values("mur")
    for mur, distance in zip(table["mur"], table["distance"]):
        assert abs(distance - analytic_flat(1.0, 0.8, mur)[3]) < 0.01 * distance
    res = scope["res"]
    assert abs(res.value - 0.25) < 0.02 * 0.25 and res.low <= 0.25 <= res.high


def test_the_insertion_snippet_of_the_studies_doc_fills_its_cylinder():
    """docs/studies.md, "Inserting spheres into a region": 500 spheres with radii in [4, 5] mm,
    each wholly inside the cylinder (r + R <= 0.05 m, R <= z <= 0.2 - R), none overlapping
    another, the same positions from the same seed."""
    from scipy.spatial import cKDTree

    import rollingdem as rd

    code = python_block(ROOT / "docs" / "studies.md", "## Inserting spheres into a region")
    ends = []
    for _ in range(2):
        sim = rd.Simulation()
        sim.add_material(rd.Material("glass", 63e9, 0.24, 2500))
        exec(compile(code, "studies.md", "exec"), {"rd": rd, "sim": sim})
        ends.append(sim.positions)
    x, a = sim.positions, sim.radii
    assert sim.n_particles == 500 and a.min() >= 0.004 and a.max() <= 0.005
    assert (np.hypot(x[:, 0], x[:, 1]) + a <= 0.05 + 1e-12).all()
    assert (x[:, 2] - a >= -1e-12).all() and (x[:, 2] + a <= 0.2 + 1e-12).all()
    pairs = cKDTree(x).query_pairs(0.01, output_type="ndarray")
    assert (np.linalg.norm(x[pairs[:, 0]] - x[pairs[:, 1]], axis=1) >= a[pairs[:, 0]] + a[pairs[:, 1]] - 1e-12).all()
    np.testing.assert_array_equal(ends[0], ends[1])


def test_the_mesh_fill_snippet_of_the_studies_doc_fills_its_drum_to_a_quarter(capsys):
    """docs/studies.md, "Filling a closed mesh": the drum (radius 50 mm, 40 mm long) holds spheres
    of 4 to 6 mm diameter whose volume is a quarter of its own within half a sphere's, each wholly
    inside; the printed line gives the count and two realised mass fractions within 0.05 of
    0.4 and 0.6 (a few hundred spheres: a few percent of sampling error)."""
    import rollingdem as rd

    sim = rd.Simulation()
    sim.add_material(rd.Material("glass", 63e9, 0.24, 2500))
    exec(compile(python_block(ROOT / "docs" / "studies.md", "### Filling a closed mesh"), "studies.md", "exec"),
         {"rd": rd, "sim": sim})
    region = rd.MeshRegion(sim.walls[0])
    x, r = sim.positions, sim.radii
    assert abs(np.sum(4 / 3 * np.pi * r ** 3) / region.volume() - 0.25) <= 0.5 * 4 / 3 * np.pi * 0.003 ** 3 / region.volume()
    assert region.contains(x, r).all() and 2 * r.min() >= 0.004 and 2 * r.max() <= 0.006
    line = capsys.readouterr().out
    assert line.startswith(f"{len(r)} spheres in MeshRegion(")
    got = [float(v) for v in line.split("mass fractions ")[1].split(" (asked")[0].split()]
    assert got == [pytest.approx(0.4, abs=0.05), pytest.approx(0.6, abs=0.05)]


def test_the_measurements_doc_python_example_settles_and_balances_its_mass(monkeypatch, capsys):
    """docs/measurements.md, "Measurements": the bed settles before its 1 s (the run says so), and
    the mass through the plane at 1 cm equals the mass below it now less the mass below it at the
    start to round-off (sums of 300 masses of 4.5e-3 kg in all: 300 x 2.2e-16 x 4.5e-3 = 3e-16 kg), the
    probe's last mass being the mass below the plane."""
    code = python_block(ROOT / "docs" / "measurements.md", "In Python a measurement is an observer")
    scope = {}
    exec(compile(code, "measurements.md", "exec"), scope)
    sim, down, bed = scope["sim"], scope["down"], scope["bed"]
    assert scope["ended"].startswith("settled") and sim.time < 1.0
    below = float(sim.masses[sim.positions[:, 2] < 0.01].sum())
    import rollingdem as rd

    fresh = rd.Simulation(gravity=(0, 0, -9.81), periodic={"x": (0, 0.03), "y": (0, 0.03)})
    fresh.add_material(rd.Material("m", youngs_modulus=40e6, poisson_ratio=0.49, density=1056, friction=0.3,
                                   rolling_friction=0.1, restitution=0.5))
    fresh.insert(rd.BoxRegion((0, 0, 0), (0.03, 0.03, 0.04)), 300, 0.0015, "m", seed=1)
    below0 = float(fresh.masses[fresh.positions[:, 2] < 0.01].sum())
    assert abs(down.mass - (below - below0)) < 1e-15
    assert bed.series()["mass"].iloc[-1] == below
    assert "down (mass flow" in capsys.readouterr().out


def test_the_measurements_doc_case_file_snippet_is_a_valid_case(tmp_path):
    """docs/measurements.md, "Stage conditions": the YAML snippet, completed with a material, a
    silo, a gate and an outlet, passes ``rollingdem check``."""
    import yaml

    from rollingdem.io.case_check import check_case
    from rollingdem.io.casefile import load_case

    text = (ROOT / "docs" / "measurements.md").read_text()
    snippet = text[text.index("is in them."):].split("```yaml\n", 1)[1].split("```", 1)[0]
    data = yaml.safe_load(snippet)
    data.update({"materials": [{"name": "m", "youngs_modulus": 5e6, "poisson_ratio": 0.3, "density": 2500.0}],
                 "walls": [{"type": "mesh", "name": "silo", "material": "m", "shape": "silo",
                            "size": {"radius": 0.02, "height": 0.08, "orifice_radius": 0.008}},
                           {"type": "plane", "name": "gate", "material": "m", "point": [0, 0, -0.004]}],
                 "particles": [{"insert": {"type": "cylinder", "radius": 0.0175, "z_min": 0.0, "z_max": 0.075},
                                "count": 100, "radius": 0.0015, "material": "m"}],
                 "outlets": [{"name": "bin", "region": {"type": "box", "lo": [-1, -1, -1], "hi": [1, 1, -0.05]}}]})
    sim = check_case(load_case(data))
    assert sim.n_particles == 100


def test_the_readme_measurements_snippet_completes_the_shipped_hopper(tmp_path):
    """README, "Case files": the measurements-and-stages snippet, put into the shipped hopper in
    place of its own, passes ``rollingdem check`` (its sensors lie in the scene, its stages' limits
    are given)."""
    import yaml

    from rollingdem.experiments.case_file import shipped_cases
    from rollingdem.io.case_check import check_case
    from rollingdem.io.casefile import load_case

    text = (ROOT / "README.md").read_text()
    snippet = yaml.safe_load(text[text.index("Measurements and stage conditions"):].split("```yaml\n", 1)[1]
                             .split("```", 1)[0])
    from rollingdem.io.mapping_file import read_mapping

    data = read_mapping(shipped_cases()["hopper"])[0]
    data.update(snippet)
    sim = check_case(load_case(data))
    assert sim.n_particles == 4000


def test_the_hopper_example_reads_its_stl_in_mm_and_drains_into_its_bin(tmp_path):
    """examples/hopper/hopper.yaml at a tenth of its spheres (400) and a fill of 0.4 s: the STL drawn
    in mm is read at scale 0.001 (its rim at 30 mm), the hopper drains until the flow stops (no
    sphere through the disk under the orifice for 0.25 s), every sphere that crossed that disk is in
    the bin (none is still in flight 0.25 s later; this bed, two diameters deep, keeps most of its
    spheres on the floor), and the probe over the orifice saw the bed before the gate opened
    and none of it once the flow stopped (what is left lies on the floor around the orifice)."""
    import json
    import shutil

    from typer.testing import CliRunner

    from rollingdem.cli import app

    for name in ("hopper.yaml", "hopper_mm.stl"):
        shutil.copy(ROOT / "examples" / "hopper" / name, tmp_path / name)
    case = tmp_path / "hopper.yaml"
    text = scaled(case.read_text(), {"count: 4000": "count: 400", "{name: fill, duration: 0.8}":
                                     "{name: fill, duration: 0.4}", "window: {stage: fill, start: 0.65}":
                                     "window: {stage: fill, start: 0.3}"})
    case.write_text(text)
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert summary["stages"][1]["ended"].startswith("discharge.rate <= 1e-06 for 0.25 s")
    m = summary["measurements"]
    out = m["bin"]["count"]["final"]
    assert m["discharge"]["count"]["final"] == out and out + summary["particles_left"] == 400 and out > 50
    assert m["bed"]["count"]["mean"] > 10 and m["bed"]["count"]["final"] < m["bed"]["count"]["mean"]
    from rollingdem.scene.mesh import TriangleMesh

    rim = TriangleMesh.from_file(tmp_path / "hopper_mm.stl", scale=0.001).vertices
    assert abs(np.hypot(rim[:, 0], rim[:, 1]).max() - 0.03) < 0.03 * 6e-8  # a binary STL holds float32


def test_the_readme_case_file_settles_its_pile_and_prints_its_angle(tmp_path):
    """README, "Case files": the pile of 1,500 spheres at a third of them (500, the tube and the
    base scaled as in the Python example's test, 4 slices): each waiting stage ends settled, and the
    run prints the pile's angle and writes pile.png (a pile a few layers high: 10 to 45 degrees)."""
    import json

    import yaml
    from typer.testing import CliRunner

    from rollingdem.cli import app

    text = (ROOT / "README.md").read_text()
    block = text[text.index("## Case files"):].split("```yaml\n", 1)[1].split("```", 1)[0]
    block = scaled(block, {"count: 1500": "count: 500", "radius: 0.06, extent": "radius: 0.045, extent",
                           "{type: cylinder, radius: 0.06, z_min": "{type: cylinder, radius: 0.045, z_min",
                           "[[-0.2, 0.2], [-0.2, 0.2]]": "[[-0.15, 0.15], [-0.15, 0.15]]",
                           "duration: 2.0}": "duration: 1.5}", "n_slices: 8": "n_slices: 4"})
    assert yaml.safe_load(block)["name"] == "my-pile"
    (tmp_path / "my-pile.yaml").write_text(block)
    result = CliRunner().invoke(app, ["run", str(tmp_path / "my-pile.yaml"), "--out", str(tmp_path / "o"),
                                      "--no-progress"])
    assert result.exit_code == 0, result.output
    summary = json.loads((tmp_path / "o" / "summary.json").read_text())
    assert [s["ended"][:7] for s in summary["stages"]] == ["settled", "duratio", "settled"]
    assert 10.0 < summary["repose_angle"]["angle"] < 45.0 and "repose angle:" in result.output
    assert (tmp_path / "o" / "pile.png").exists()


def test_the_readme_case_file_programs_build_what_they_say(tmp_path):
    """README, the wall programs "In a case file": the plane's ``oscillate`` fragment builds an
    oscillation of 20 Hz, 0.5 mm along z, starting at rest (phase 90 deg = pi/2), and a ``table``
    read from a CSV with the columns it names repeats the table's rows."""
    import math
    import re

    import yaml

    from rollingdem.io.case_schema import MotionSpec, PlaneSpec
    from rollingdem.io.casefile import _program

    text = (ROOT / "README.md").read_text()
    start = text.index("In a case file the programs are")
    fragments = re.findall(r"`([^`]*)`", text[start:text.index("docs/models.md §16", start)])
    plane = yaml.safe_load(next(f for f in fragments if f.startswith("- {type: plane")))[0]
    program = _program(PlaneSpec(**plane), tmp_path)
    assert program.frequency == 20.0 and program.amplitude == (0.0, 0.0, 0.0005)
    assert program.phase == pytest.approx(math.pi / 2)
    table = yaml.safe_load("{" + next(f for f in fragments if f.startswith("table:")) + "}")
    columns = next(f for f in fragments if f.startswith("t, dx"))
    (tmp_path / "kinematics.csv").write_text(columns + "\n0, 0, 0, 0\n0.1, 0.001, 0, 0\n0.2, 0, 0, 0\n")
    repeated = _program(MotionSpec(**table, velocity=(0, 0, 0)), tmp_path)
    assert repeated.repeat and repeated.position(0.25)[0][0] == pytest.approx(0.0005)  # 0.05 s into a new round


def test_the_readme_clumps_example_pours_tetrahedra_onto_the_floor(capsys):
    """README, "Clumps": the equivalent mu_r is printed (a trimer lying flat tips over the edge
    facing downhill: tan theta = (r / sqrt 3) / r, 0.577); 60 clumps of 240 spheres come to rest on the floor within 0.3 s (each below 0.05 m/s,
    and the highest centre below the 30 mm they were poured from), and the case-file block builds
    60 tetrahedra."""
    import math
    import re

    import yaml

    import rollingdem as rd
    from rollingdem.io.case_schema import ClumpSpec
    from rollingdem.io.casefile import _add_clumps

    exec(compile(python_block(ROOT / "README.md", "Clumps (multispheres)"), "README.md", "exec"), scope := {})
    printed = capsys.readouterr().out.splitlines()
    mu_r = float(re.search(r"mu_r = ([0-9.]+)", printed[0]).group(1))
    assert mu_r == pytest.approx(1 / math.sqrt(3), abs=5e-4)
    assert printed[1].startswith("60 clumps of 240 spheres")
    sim = scope["sim"]
    assert np.linalg.norm(sim.clumps["velocity"], axis=1).max() < 0.05
    assert float(re.search(r"highest centre ([0-9.]+) mm", printed[1]).group(1)) < 30.0
    text = (ROOT / "README.md").read_text()
    block = yaml.safe_load(text[text.index("Clumps (multispheres)"):].split("```yaml\n", 1)[1].split("```", 1)[0])
    fresh = rd.Simulation()
    fresh.add_material(rd.Material("glass", youngs_modulus=1e8, poisson_ratio=0.3, density=2500))
    for spec in block["particles"]:
        _add_clumps(fresh, ClumpSpec(**spec), ROOT)
    assert len(fresh.clumps["mass"]) == 61 and fresh.n_particles == 60 * 4 + 2


def test_the_readme_coarse_graining_example_delivers_what_it_says(capsys):
    """README, "Coarse graining", as printed: 27,000 grains of 1 mm are 27,000 / 3^3 = 1,000 parcels of
    3 mm, whose mass is the grains' (2650 kg/m^3 x 27,000 x 4/3 pi (1 mm)^3, to round-off) and whose
    time step is 3 times the real grains' (every limit of models.md §2 is a contact time ~ alpha)."""
    import math

    import rollingdem as rd

    scope = {}
    exec(compile(python_block(ROOT / "README.md", "Coarse graining: a material"), "README.md", "exec"), scope)
    sim = scope["sim"]
    assert "1000 parcels of 3 mm stand for 27000 grains" in capsys.readouterr().out
    assert float(sim.masses.sum()) == pytest.approx(2650 * 27000 * 4 / 3 * math.pi * 1e-9, rel=1e-12)
    real = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"))
    real.add_material(rd.Material("sand", youngs_modulus=5e6, poisson_ratio=0.3, density=2650, friction=0.5,
                                  rolling_friction=0.3, restitution=0.5))
    real.add_particles([[0, 0, 0.001]], 0.001, "sand")
    assert scope["sim"].time == pytest.approx(0.2, abs=sim.dt)
    assert sim.dt == pytest.approx(3 * real.dt, rel=1e-12)


def test_the_fields_example_of_the_analysis_page_prints_the_virial(capsys):
    """docs/analysis.md, "Continuum fields": the contact stress summed over the grid is f_x b_x =
    2 N x 2 mm = 0.004 N m, as its comment says (1e-12)."""
    exec(python_block(ROOT / "docs" / "analysis.md", "## Continuum fields"), {})
    assert float(capsys.readouterr().out) == pytest.approx(0.004, rel=1e-12)


def test_the_analysis_doc_fields_measurement_example_writes_what_it_lists(tmp_path, monkeypatch, capsys):
    """docs/analysis.md, "Continuum fields", the measurement: six samples (0 to 0.05 s every 10 ms),
    their .vti files, the series and the profile; the summary line names what it says."""
    monkeypatch.chdir(tmp_path)
    exec(python_block(ROOT / "docs" / "analysis.md", "During a run, the `fields` measurement"), {})
    line = capsys.readouterr().out
    assert line.startswith("bed (continuum fields") and "solid_fraction" in line and "Pa" in line
    assert sorted(p.name for p in (tmp_path / "fields" / "bed").glob("*.vti")) == [f"bed_{k:05d}.vti" for k in range(6)]
    for name in ("bed.csv", "bed_profile.csv", "bed_mean.vti", "bed.pvd"):
        assert (tmp_path / "fields" / name).exists()
