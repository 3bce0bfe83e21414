"""rollingdem sweep: design expansion, the runs table (written as runs finish, resumable), failed
runs, a worker killed mid-sweep, and refusals of bad sweep files.

The physics in the rows is checked against the analytic rolling-flat solution (docs/models.md §13 T2):
the validation case holds the simulated stop distance within 0.5 % of it at mu_r = 0.2, and the
same sources of error (slip phase of the spring, 0.1 ms sampling) bound it at 1 % over 0.1-0.4.
"""

import math
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pandas as pd
import pytest

import rollingdem as rd
from rollingdem.experiments.single_sphere import analytic_flat
from rollingdem.studies.sweep import expand, load_sweep, read_table, run_id, run_sweep

FLAT = {"experiment": "rolling-flat", "fixed": {"model": "epsd", "mu": 0.8},
        "grid": {"mur": [0.1, 0.2, 0.3, 0.4], "v0": [0.5, 1.0]}, "seeds": 1}


def test_grid_expands_to_every_combination_with_seeds_and_defaults():
    spec = load_sweep(dict(FLAT, seeds=[3, 7]))
    runs = expand(spec)
    assert len(runs) == 4 * 2 * 2
    assert {(r["mur"], r["v0"], r["seed"]) for r in runs} == {(m, v, s) for m in (0.1, 0.2, 0.3, 0.4)
                                                              for v in (0.5, 1.0) for s in (3, 7)}
    assert all(r["eta_r"] == 0.3 and r["e"] == 0.5 and r["model"] == "epsd" for r in runs)  # defaults filled in
    assert len({run_id("rolling-flat", r) for r in runs}) == len(runs)


def test_latin_hypercube_puts_one_point_in_each_stratum():
    """Latin hypercube: each of the n equal bins of each range holds exactly one point."""
    spec = load_sweep({"case": "rolling-flat", "sample": {"n": 10, "seed": 4, "ranges": {"mur": [0.1, 0.5],
                                                                                         "mu": [0.4, 0.9]}}})
    runs = expand(spec)
    for name, (lo, hi) in {"mur": (0.1, 0.5), "mu": (0.4, 0.9)}.items():
        x = np.array([r[name] for r in runs])
        assert np.all((x >= lo) & (x <= hi))
        bins = np.floor((x - lo) / (hi - lo) * 10).astype(int)
        assert sorted(bins) == list(range(10))


def test_sweep_on_a_local_cluster_writes_every_row_once_and_resumes(tmp_path):
    """8 runs on a 2-worker LocalCluster: every row there once, distances on the analytic curve;
    a second invocation runs nothing; a run added to the file is the only one that runs."""
    spec = dict(FLAT, grid={"mur": [0.1, 0.2, 0.3, 0.4], "v0": [0.5, 1.0]})
    first = run_sweep(spec, tmp_path, workers=2, progress=False)
    assert first.ran == 8 and first.failed == 0
    raw = pd.read_csv(tmp_path / "runs.csv")
    assert len(raw) == 8 and raw["run_id"].is_unique and (raw["status"] == "ok").all()
    for _, row in raw.iterrows():
        s = analytic_flat(row["v0"], 0.8, row["mur"])[3]
        assert row["distance"] == pytest.approx(s, rel=0.01)
    assert (raw["version"] == rd.__version__).all() and (raw["wall_time_s"] > 0).all()
    again = run_sweep(spec, tmp_path, workers=2, progress=False)
    assert again.ran == 0 and again.skipped == 8 and len(again.table) == 8
    more = run_sweep(dict(spec, grid={"mur": [0.1, 0.2, 0.3, 0.4, 0.5], "v0": [1.0]}), tmp_path, workers=1,
                     progress=False)
    assert more.ran == 1 and more.skipped == 4
    assert len(pd.read_csv(tmp_path / "runs.csv")) == 9
    summary = pd.read_csv(tmp_path / "summary.csv")
    assert len(summary) == 5 and (tmp_path / "summary.png").exists()


def test_a_line_cut_short_by_a_crash_is_dropped_and_its_run_rerun(tmp_path):
    spec = dict(FLAT, grid={"mur": [0.2, 0.3]}, fixed={"model": "cdt"})
    run_sweep(spec, tmp_path, workers=1, progress=False)
    path = tmp_path / "runs.csv"
    lines = path.read_text().splitlines()
    path.write_text("\n".join(lines[:-1]) + "\n" + lines[-1][:25])  # the last row half written
    assert len(read_table(path)) == 1
    again = run_sweep(spec, tmp_path, workers=1, progress=False)
    assert again.ran == 1 and len(again.table) == 2 and (again.table["status"] == "ok").all()


def test_a_failing_run_is_recorded_and_the_others_go_on(tmp_path):
    """dt = 1e-3 s is above the stable limit of the pile (checked when the run starts): that run
    fails with the engine's message, the other completes."""
    spec = {"case": "angle-of-repose", "fixed": {"count": 50}, "points": [{"dt": 1e-3}], "seeds": 1}
    ok = {"case": "rolling-flat", "grid": {"mur": [0.3]}}
    bad = run_sweep(spec, tmp_path / "bad", workers=1, progress=False)
    assert bad.failed == 1 and not bad.ok
    row = bad.table.iloc[0]
    assert row["status"] == "failed" and "stable limit" in row["error"] and "dt = 0.001" in row["error"]
    assert run_sweep(ok, tmp_path / "ok", workers=1, progress=False).ok
    # a failed run is skipped on resume unless asked to retry
    assert run_sweep(spec, tmp_path / "bad", workers=1, progress=False).ran == 0
    assert run_sweep(spec, tmp_path / "bad", workers=1, progress=False, retry_failed=True).ran == 1


def test_killing_a_worker_mid_sweep_still_yields_every_row_exactly_once(tmp_path):
    """The CLI on a 2-worker LocalCluster; once the first row is in, one worker process is killed
    (SIGKILL). Its run is rerun by the scheduler on the other worker or the restarted one."""
    import psutil
    (tmp_path / "sweep.yaml").write_text(
        "case: rolling-flat\nfixed: {model: epsd}\ngrid:\n  mur: [0.05, 0.06, 0.07, 0.08, 0.09, 0.1, 0.11, 0.12]\n")
    out = tmp_path / "out"
    proc = subprocess.Popen([sys.executable, "-m", "rollingdem.cli", "sweep", str(tmp_path / "sweep.yaml"),
                             "--out", str(out), "--workers", "2", "--no-progress"],
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    killed = None
    deadline = time.time() + 300
    while time.time() < deadline and proc.poll() is None:
        table = out / "runs.csv"
        if table.exists() and len(table.read_text().splitlines()) >= 2:
            workers = [c for c in psutil.Process(proc.pid).children()
                       if "spawn_main" in " ".join(c.cmdline()) and "resource_tracker" not in " ".join(c.cmdline())]
            if workers:
                killed = workers[0].pid
                os.kill(killed, signal.SIGKILL)
                break
        time.sleep(0.2)
    output = proc.communicate(timeout=600)[0]
    assert killed is not None, output
    assert proc.returncode == 0, output
    raw = pd.read_csv(out / "runs.csv")
    assert len(raw) == 8 and raw["run_id"].is_unique and (raw["status"] == "ok").all(), raw
    assert sorted(raw["mur"]) == pytest.approx([0.05, 0.06, 0.07, 0.08, 0.09, 0.1, 0.11, 0.12])


@pytest.mark.parametrize("data, words", [
    ({"case": "rolling-flat", "grid": {"mu_roll": [0.1]}}, ["mu_roll", "not known", "mur"]),
    ({"case": "rolling-flat", "grid": {"mur": []}}, ["grid is empty", "mur"]),
    ({"case": "rolling-flat", "grid": {}}, ["grid is empty"]),
    ({"case": "rolling-flat", "grid": {"mur": [0.1]}, "seeds": -2}, ["seeds = -2", ">= 1"]),
    ({"case": "rolling-flat", "grid": {"mur": [0.1]}, "seeds": [1, -1]}, ["seeds", ">= 0"]),
    ({"case": "rolling-flat", "grid": {"mur": [-0.1]}}, ["mur = -0.1", "(0, inf)"]),
    ({"case": "rolling-flat", "grid": {"model": ["epsdd"]}}, ["model = 'epsdd'", "allowed", "epsd"]),
    ({"case": "rolling-flat"}, ["exactly one of grid, points, sample"]),
    ({"case": "rolling-flat", "grid": {"mur": [0.1]}, "points": [{"mur": 0.2}]}, ["exactly one"]),
    ({"case": "rolling-flat", "grid": {"mur": [0.1]}, "fixed": {"mur": 0.2}}, ["both fixed and swept"]),
    ({"case": "rolling-flat", "grid": {"seed": [1, 2]}}, ["seed", "seeds"]),
    ({"case": "rolling-flat", "grid": {"mur": [0.1]}, "repeats": 2}, ["repeats", "not a known key"]),
    ({"experiment": "pile", "grid": {"mur": [0.1]}}, ["experiment = 'pile'", "angle-of-repose"]),
    ({"experiment": "contact-laws", "grid": {"mur": [0.1]}}, ["'contact-laws' has no parameters to vary"]),
    ({"grid": {"mur": [0.1]}}, ["experiment", "missing"]),
    ({"experiment": "rolling-flat", "case": "rolling-flat", "grid": {"mur": [0.1]}}, ["'case'", "not a known key"]),
    ({"case": "rolling-flat", "sample": {"n": 4, "ranges": {"mur": [0.5, 0.1]}}}, ["low < high"]),
    ({"case": "rolling-flat", "sample": {"n": 4, "ranges": {"model": [0, 1]}}}, ["model", "real-valued"]),
])
def test_bad_sweep_files_are_refused_with_the_reason(data, words):
    with pytest.raises(rd.ParameterError) as err:
        load_sweep(data)
    for w in words:
        assert w in str(err.value), str(err.value)


def test_cli_refuses_a_bad_sweep_file_before_running(tmp_path):
    (tmp_path / "bad.yaml").write_text("case: rolling-flat\ngrid: {mur: [0.1]}\nseeds: 0\n")
    res = subprocess.run([sys.executable, "-m", "rollingdem.cli", "sweep", str(tmp_path / "bad.yaml"), "--out",
                          str(tmp_path / "o"), "--no-progress"], capture_output=True, text=True)
    assert res.returncode == 2 and "seeds = 0" in res.stderr
    assert not (tmp_path / "o" / "runs.csv").exists()


def test_a_table_of_another_case_is_not_mixed_in(tmp_path):
    run_sweep({"case": "rolling-flat", "grid": {"mur": [0.3]}}, tmp_path, workers=1, progress=False)
    with pytest.raises(rd.ParameterError, match="another --out folder"):
        run_sweep({"case": "inclined-wall", "grid": {"mur": [0.3]}}, tmp_path, workers=1, progress=False)


def test_a_table_from_before_an_observable_was_added_goes_on_with_it_empty(tmp_path):
    """An older rolling-flat table without its stop_time column (an observable added since): its run
    is kept, not run again, with stop_time empty; the table is written anew with today's columns,
    and the new run's stop distance is the analytic one (1 %, the module's bound)."""
    spec = dict(FLAT, grid={"mur": [0.2]}, fixed={"model": "cdt"})
    run_sweep(spec, tmp_path, workers=1, progress=False)
    path = tmp_path / "runs.csv"
    pd.read_csv(path).drop(columns=["stop_time"]).to_csv(path, index=False)
    again = run_sweep(dict(spec, grid={"mur": [0.2, 0.3]}), tmp_path, workers=1, progress=False)
    assert again.ran == 1 and len(again.table) == 2
    table = pd.read_csv(path).sort_values("mur")
    assert list(table.columns) == list(read_table(path).columns) and "stop_time" in table.columns
    assert math.isnan(table["stop_time"].iloc[0]) and table["stop_time"].iloc[1] > 0
    exact = analytic_flat(1.0, 0.8, 0.3)[3]
    assert table["distance"].iloc[1] == pytest.approx(exact, rel=0.01)


def test_example_sweep_file_is_valid():
    from pathlib import Path

    spec = load_sweep(Path(__file__).parents[2] / "examples" / "sweep_rolling_flat.yaml")
    assert len(expand(spec)) >= 4
    assert len(expand(load_sweep(Path(__file__).parents[2] / "examples" / "sweep_repose.yaml"))) == 12


def test_validation_repose_sweep_runs_through_the_sweep_table(tmp_path):
    """The PFC study of rollingdem validate writes its runs to a sweep table and, rerun on the
    same folder, runs nothing again. One pile of 600 spheres (mu = 0.6, mu_r = 0.4), seed 1.

    Its angle is not a physics check at this size: six seeds gave 15.9, 14.1, 37.4, 16.4 and 18.7
    degrees and one pile too flat to slice (cone fit R^2 0.20-0.58), so the 95 % prediction
    interval of one seed, mean +- t(0.975, 4) sd sqrt(1 + 1/5) = 20.5 +- 29 degrees, is wider
    than any band worth stating (measured with repose_sweep(count=600, frictions=(0.6,),
    rolling_frictions=(0.4,), seeds=(s,)), s = 1..6, 13-60 s each). The trend of the angle with
    mu and mu_r is tested on the quick sweep's 2000-sphere piles (test_pile_cases.py, slow). Here:
    the case's point is the run's row (one seed: its mean is that run's angle, no interval)."""
    from rollingdem.studies.repose_study import repose_sweep

    kwargs = dict(outdir=tmp_path, count=600, frictions=(0.6,), rolling_frictions=(0.4,), seeds=(1,))
    first = repose_sweep(**kwargs)
    table = tmp_path / "repose-sweep-runs" / "runs.csv"
    rows = pd.read_csv(table)
    assert len(rows) == 1 and rows["status"].iloc[0] == "ok"
    point = first.table.iloc[0]
    assert (point["mu"], point["mu_r"], point["seeds"], point["measured"]) == (0.6, 0.4, 1, 1)
    assert point["angle mean (deg)"] == rows["angle"].iloc[0] and math.isnan(point["95 % CI ± (deg)"])
    assert 0.0 < rows["settled_at"].iloc[0] <= rows["max_collapse"].iloc[0]  # measured at rest
    again = repose_sweep(**kwargs)
    assert pd.read_csv(table).equals(rows)  # nothing ran again
    assert again.table["angle mean (deg)"].iloc[0] == first.table["angle mean (deg)"].iloc[0]


def test_toml_sweep_file_and_a_missing_file(tmp_path):
    (tmp_path / "s.toml").write_text('case = "rolling-flat"\nseeds = 2\n[grid]\nmur = [0.2, 0.3]\n')
    assert len(expand(load_sweep(tmp_path / "s.toml"))) == 4
    with pytest.raises(rd.ParameterError, match="sweep file .*nope.yaml does not exist"):
        load_sweep(tmp_path / "nope.yaml")


def test_sweep_on_an_existing_cluster_by_its_scheduler_address(tmp_path):
    """--scheduler: the runs go to a cluster the user started (here a LocalCluster of 1 worker)."""
    from dask.distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        res = run_sweep({"case": "rolling-flat", "grid": {"mur": [0.3, 0.4]}}, tmp_path,
                        scheduler=cluster.scheduler_address, progress=False)
    assert res.ran == 2 and res.ok
    assert res.table.sort_values("mur")["distance"].tolist() == pytest.approx(
        [analytic_flat(1.0, 0.8, m)[3] for m in (0.3, 0.4)], rel=0.01)
    with pytest.raises(rd.ParameterError, match="no Dask scheduler answers"):
        run_sweep({"case": "rolling-flat", "grid": {"mur": [0.5]}}, tmp_path / "x", scheduler="tcp://127.0.0.1:9",
                  progress=False)


def test_an_older_sweep_file_names_its_experiment_case(tmp_path):
    """A sweep file of before experiments had their name says ``case:``: the same sweep, the same
    run ids (so its runs table resumes); and a table with a ``case`` column reads as one with an
    ``experiment`` column."""
    old = load_sweep({**{k: v for k, v in FLAT.items() if k != "experiment"}, "case": "rolling-flat"})
    new = load_sweep(FLAT)
    assert old.experiment == new.experiment == "rolling-flat"
    assert [run_id(old.experiment, r) for r in expand(old)] == [run_id(new.experiment, r) for r in expand(new)]
    from rollingdem.experiments import get_experiment
    from rollingdem.studies.sweep import _columns, read_table

    experiment = get_experiment("rolling-flat")
    columns = ["case" if c == "experiment" else c for c in _columns(experiment)]
    row = {c: None for c in columns} | {"run_id": "abc", "case": "rolling-flat", "status": "ok", "distance": 0.5}
    path = tmp_path / "runs.csv"
    pd.DataFrame([row], columns=columns).to_csv(path, index=False)
    table = read_table(path, experiment)
    assert list(table["experiment"]) == ["rolling-flat"] and list(table["distance"]) == [0.5]
