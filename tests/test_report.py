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
