"""A run survives a kill (issue 44, item 8): ``rollingdem run`` killed with SIGKILL in the middle of
a stage that waits for a condition, then ``rollingdem run --resume DIR``, ends bit for bit where
the same run ends uninterrupted: the final state, the time series, the measurements and the
snapshots. And a folder that holds an earlier run is refused unless asked to overwrite it."""

import json
import os
import pickle
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from typer.testing import CliRunner

from rollingdem.cli import app

# A silo of 500 spheres fills behind a gate, then drains until 150 are out (about 4 s on 2 cores).
CASE = """\
name: resume-test
dt: 1.5e-5
materials:
  - {name: glass, youngs_modulus: 5.0e6, poisson_ratio: 0.3, density: 2500.0, friction: 0.4,
     rolling_friction: 0.05, restitution: 0.5, rolling_damping: 0.3}
contact: {normal: hertz, rolling: epsd}
walls:
  - {type: mesh, name: silo, material: glass, shape: silo, size: {radius: 0.02, height: 0.08, orifice_radius: 0.008}}
  - {type: plane, name: gate, material: glass, point: [0, 0, -0.004], normal: [0, 0, 1]}
particles:
  - insert: {type: cylinder, radius: 0.0175, z_min: 0.002, z_max: 0.075}
    count: 500
    radius: {distribution: uniform, low: 0.0012, high: 0.0016}
    material: glass
    seed: 2
outlets:
  - {name: orifice, region: {type: box, lo: [-0.05, -0.05, -0.2], hi: [0.05, 0.05, -0.03]}}
measurements:
  - {name: flow, type: mass_flow, point: [0, 0, -0.01], normal: [0, 0, -1], interval: 0.002}
  - {name: out, type: outlet, outlet: orifice, interval: 0.002}
stages:
  - {name: fill, until: settled, max_duration: 0.25}
  - {name: discharge, remove_walls: [gate], until: {measurement: out.count, above: 150}, max_duration: 2.0}
output:
  time_series: {interval: 0.005}
  snapshots: {interval: 0.05}
  checkpoint: {interval: 0.013}
  plot: false
"""


def _run_state(folder: Path):
    try:
        with open(folder / "checkpoints" / "run_state.pkl", "rb") as fh:
            return pickle.load(fh)
    except (OSError, EOFError, pickle.UnpicklingError):
        return None


def _last_step(series: Path) -> int:
    """The step of the last whole row of a time series (-1 for none)."""
    try:
        lines = series.read_bytes().splitlines(keepends=True)
        return int(next(x for x in reversed(lines) if x.endswith(b"\n") and x[:1].isdigit()).split(b",")[1])
    except (OSError, StopIteration, ValueError, IndexError):
        return -1


def _files(folder: Path) -> dict:
    return {str(p.relative_to(folder)): p for p in sorted(folder.rglob("*")) if p.is_file()}


def test_a_run_killed_mid_stage_and_resumed_ends_bit_for_bit_where_it_would_have(tmp_path):
    case = tmp_path / "silo.yaml"
    case.write_text(CASE)
    whole = CliRunner().invoke(app, ["run", str(case), "--out", str(tmp_path / "whole"), "--no-progress"])
    assert whole.exit_code == 0, whole.output
    killed = tmp_path / "killed"
    child = subprocess.Popen([sys.executable, "-m", "rollingdem.cli", "run", str(case), "--out", str(killed),
                              "--no-progress"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    deadline, state = time.time() + 120, None
    while time.time() < deadline and child.poll() is None:
        state = _run_state(killed)
        # inside the discharge, a checkpoint written, and rows written after it that the resume must cut
        if state is not None and state.stage == 1 and state.begun and _last_step(killed / "series.csv") > state.step:
            break
        time.sleep(0.005)
    assert child.poll() is None, "the run ended before it could be killed"
    os.kill(child.pid, signal.SIGKILL)
    child.wait()
    assert not (killed / "summary.json").exists()  # it was stopped, not finished
    resumed = CliRunner().invoke(app, ["run", "--resume", str(killed), "--no-progress"])
    assert resumed.exit_code == 0, resumed.output
    assert "resuming case 'resume-test'" in resumed.output and "stage 'discharge'" in resumed.output
    a, b = np.load(tmp_path / "whole" / "final.npz"), np.load(killed / "final.npz")
    assert sorted(a.files) == sorted(b.files)
    for name in a.files:
        if name != "meta":
            assert np.array_equal(a[name], b[name]), name
    meta_a, meta_b = json.loads(str(a["meta"])), json.loads(str(b["meta"]))
    assert meta_a["step"] == meta_b["step"] and meta_a["time"] == meta_b["time"]
    files_a, files_b = _files(tmp_path / "whole"), _files(killed)
    compared = [n for n in files_a if n.endswith((".csv", ".vtu", ".pvd"))]
    assert set(compared) == {n for n in files_b if n.endswith((".csv", ".vtu", ".pvd"))}
    assert len([n for n in compared if n.endswith(".vtu")]) > 5
    for name in compared:
        assert files_a[name].read_bytes() == files_b[name].read_bytes(), name
    summary = json.loads((killed / "summary.json").read_text())
    assert summary["status"] == "ok" and summary["stages"][-1]["ended"].startswith("out.count >= 150")


def test_an_earlier_run_is_refused_unless_overwritten_and_resume_refuses_what_it_cannot_continue(tmp_path):
    case = tmp_path / "silo.yaml"
    case.write_text(CASE.replace("count: 500", "count: 50").replace("max_duration: 0.25", "max_duration: 0.002")
                    .replace("above: 150}, max_duration: 2.0", "above: 150}, max_duration: 0.002"))
    out = tmp_path / "o"
    (tmp_path / "o").mkdir()
    (out / "notes.txt").write_text("mine")
    first = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    assert first.exit_code == 0, first.output
    series = (out / "series.csv").read_text()
    again = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress"])
    assert again.exit_code == 2 and "it holds an earlier run" in again.output and "--overwrite" in again.output
    assert (out / "series.csv").read_text() == series  # nothing was touched
    over = CliRunner().invoke(app, ["run", str(case), "--out", str(out), "--no-progress", "--overwrite"])
    assert over.exit_code == 0, over.output
    assert (out / "series.csv").read_text() == series  # the same run again, not appended to the old one
    assert (out / "notes.txt").read_text() == "mine"  # what is not a run's output stays
    done = CliRunner().invoke(app, ["run", "--resume", str(out), "--no-progress"])
    assert done.exit_code == 2 and "that run finished" in done.output
    empty = CliRunner().invoke(app, ["run", "--resume", str(tmp_path), "--no-progress"])
    assert empty.exit_code == 2 and "holds no run checkpoint" in empty.output
    both = CliRunner().invoke(app, ["run", str(case), "--resume", str(out)])
    assert both.exit_code == 2 and "is not allowed with CASE" in both.output
    summary = json.loads((out / "summary.json").read_text())
    (out / "summary.json").write_text(json.dumps(dict(summary, status="failed: killed")))
    state = out / "checkpoints" / "run_state.pkl"
    state.write_bytes(state.read_bytes()[:100])  # cut short, as a full disk leaves it
    cut = CliRunner().invoke(app, ["run", "--resume", str(out), "--no-progress"])
    assert cut.exit_code == 2 and "checkpoints/run_state.pkl cannot be read" in cut.output, cut.output
    assert len(cut.output.strip().splitlines()) == 1 and "Traceback" not in cut.output
