"""The report every run writes (issue 44, item 3): report.html with the scene at each stage's start
and end and at the times asked for, each measurement's series, the energy, the end summary."""

import re

from typer.testing import CliRunner

from rollingdem.cli import app

CASE = """\
name: report-test
dt: 1.0e-5
materials:
  - {name: glass, youngs_modulus: 1.0e7, poisson_ratio: 0.3, density: 2500.0, friction: 0.5}
walls:
  - {type: plane, name: floor, material: glass}
  - {type: cylinder, name: tube, material: glass, radius: 0.02}
particles:
  - insert: {type: cylinder, radius: 0.018, z_min: 0.0, z_max: 0.04}
    count: 40
    radius: 0.002
    material: glass
    seed: 1
measurements:
  - {name: bed, type: probe, region: {type: cylinder, radius: 0.02, z_min: 0, z_max: 0.01}}
stages:
  - {name: fall, duration: 0.01}
  - {name: rest, duration: 0.01}
output:
  time_series: {interval: 0.001}
  report: {pictures: [0.005]}
"""


def test_every_run_writes_a_report_with_its_scene_measurements_and_energy(tmp_path):
    case = tmp_path / "case.yaml"
    case.write_text(CASE)
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    page = (tmp_path / "o" / "report.html").read_text()
    shown = re.findall(r"src='(report/[^']+)'", page)
    # t = 0, the asked 0.005 s, the end of 'fall' (0.01 s; also the start of 'rest') and of 'rest'
    scenes = [s for s in shown if "scene_" in s]
    assert len(scenes) == 4
    assert re.findall(r"<p>t = ([0-9.e-]+) s</p><img src='report/scene_", page) == ["0", "0.005", "0.01", "0.02"]
    for png in shown:
        assert (tmp_path / "o" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "measurement_bed.png" in page and "energy.png" in page
    assert "<td>fall</td><td>duration</td>" in page and "<td>bed</td><td>bulk_density</td>" in page
    assert "40 free particles; walls: floor, tube" in page and "contact: normal hertz" in page


def test_the_report_header_says_what_ran_and_what_changed(tmp_path):
    """The header describes the scene as the run started (40 spheres, the floor and the tube), and
    adds a line for the end where it differs: the tube removed and the spheres an outlet took out
    (those whose centres come below 4 mm: the bottom layer of the 2 mm spheres)."""
    case = tmp_path / "case.yaml"
    case.write_text(CASE.replace("stages:\n", "outlets:\n  - {name: low, region: {type: box, lo: [-1, -1, -1], hi: [1, 1, 0.004]}}"
                             "\nstages:\n")
                    .replace("  - {name: rest, duration: 0.01}", "  - {name: rest, duration: 0.01, remove_walls: [tube]}")
                    .replace("measurements:\n", "measurements:\n  - {name: out, type: outlet, outlet: low}\n"))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    page = (tmp_path / "o" / "report.html").read_text()
    head = page[page.index("<p>") + 3:page.index("</p>")].split("<br>")
    assert head[0].startswith("40 free particles; walls: floor, tube; dt = 1e-05 s"), head
    end = [line for line in head if line.startswith("at the end: ")]
    assert len(end) == 1 and "; walls: floor; dt" in end[0], head
    left = int(end[0].removeprefix("at the end: ").split()[0])
    assert 0 < left < 40  # the outlet took the lowest layer
    # the measurements lead with their headline lines; the table below gives a cumulative count's
    # final value and no mean of the running sum
    lines = page.split("<h2>Measurements</h2>")[1]
    assert lines.index("out (") < lines.index("<details>") and f"count {40 - left} at the end" in lines
    assert f"<td>out</td><td>count</td><td>{40 - left}</td><td>–</td><td>–</td>" in page


def test_the_pile_line_gives_the_estimators_range_in_degrees_to_a_tenth(tmp_path):
    from rollingdem.io.report import write_report

    summary = {"stages": [], "status": "ok", "repose_angle": {"angle": 30.52, "r_squared": 0.912, "slice_mean": 30.61,
                                                              "slice_std": 1.49,
                                                              "option_range": [28.900254832707315, 31.03394995087698]}}
    page = write_report(tmp_path, summary, ["a header"], {}, None, "pile").read_text()
    assert "repose angle 30.5° (cone fit R² 0.91); 28.9–31.0° over the estimator's options" in page
    assert "28.900" not in page and "[" not in page.split("<h2>The pile</h2>")[1].split("</p>")[0]


def test_a_coarse_grained_run_says_its_counts_are_of_parcels(tmp_path):
    import rollingdem as rd
    from rollingdem.io.report import write_report

    probe = rd.Probe("bed", rd.BoxRegion((0, 0, 0), (1, 1, 1)))
    for header, said in ((["1000 free particles; parcels of alpha 2, standing for 8000 particles"], True),
                         (["1000 free particles"], False)):
        page = write_report(tmp_path, {"stages": []}, header, {"bed": probe}, None, "cg").read_text()
        assert ("Counts are of parcels, each standing for alpha³ real particles" in page) == said


def test_a_coarse_grained_run_prints_that_its_counts_are_of_parcels(tmp_path):
    """The same run with its glass coarse-grained by 2: 40 particles stand as 5 parcels; the printed
    measurement lines are followed by the line saying counts are of parcels, and the report says it."""
    case = tmp_path / "case.yaml"
    case.write_text(CASE.replace("density: 2500.0, friction: 0.5}", "density: 2500.0, friction: 0.5, coarse_graining: 2}"))
    result = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "o"), "--no-progress"])
    assert result.exit_code == 0, result.output
    assert "parcels of alpha 2, standing for 40 particles" in result.output
    lines = result.output.splitlines()
    bed = next(k for k, line in enumerate(lines) if line.startswith("  bed ("))
    assert lines[bed + 1].startswith("  (counts are of parcels, each standing for alpha^3 real particles")
    assert "Counts are of parcels" in (tmp_path / "o" / "report.html").read_text()
