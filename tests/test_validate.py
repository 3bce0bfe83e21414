"""rollingdem validate: checks, the report it writes, its exit status, and the repose statistics."""

import json
import math

import pandas as pd
import pytest
from typer.testing import CliRunner

import rollingdem as rd
from rollingdem import validate
from rollingdem.experiments.results import ValidationResult, Check
from rollingdem.cli import app


def test_check_tolerances():
    assert Check("c", "m", "q", 1.004, 1.0, 0.005).passed  # relative
    assert not Check("c", "m", "q", 1.006, 1.0, 0.005).passed
    assert Check("c", "m", "q", 0.3, 0.0, 0.5, relative=False).passed
    assert Check("c", "m", "q", 1e-8, 1e-7, 0.0, bound="upper").passed
    assert not Check("c", "m", "q", -1.0, 0.0, 0.0, bound="lower").passed
    assert not Check("c", "m", "q", math.nan, 1.0, 1.0).passed  # a failed measurement never passes


def fake_cases(tmp_ok=True):
    def good(quick=False, outdir=None, progress=None, runner=map):
        return ValidationResult("good", "A good case", pd.DataFrame({"model": ["x"], "value": [1.0]}),
                          [Check("good", "x", "value", 1.0, 1.0, 0.01, source="theory")])

    def bad(quick=False, outdir=None, progress=None, runner=map):
        raise RuntimeError("the kernel fell over")

    return {"good": good, "bad": bad}


def test_report_records_every_check_and_a_crashed_case(tmp_path, monkeypatch):
    monkeypatch.setattr(validate, "available_experiments", fake_cases)
    results = validate.run_validation(tmp_path, progress=False, workers=1)
    assert [r.passed for r in results] == [True, False]
    data = json.loads((tmp_path / "results.json").read_text())
    assert data["passed"] is False
    good = [c for c in data["checks"] if c["case"] == "good"][0]
    assert good == {"case": "good", "model": "x", "quantity": "value", "measured": 1.0, "reference": 1.0,
                    "tolerance": 0.01, "tolerance_kind": "relative", "source": "theory", "pass": True}
    bad = [c for c in data["checks"] if c["case"] == "bad"][0]
    assert bad["pass"] is False and "the kernel fell over" in bad["source"]
    assert "the kernel fell over" in (tmp_path / "report.md").read_text()
    assert "<table>" in (tmp_path / "report.html").read_text()


def test_cases_run_one_at_a_time_make_one_report(tmp_path, monkeypatch):
    """``--case`` runs into the same folder add up: the second keeps the first's checks, table and
    figures in results.json and report.md; running a case again replaces its earlier result."""
    monkeypatch.setattr(validate, "available_experiments", fake_cases)
    validate.run_validation(tmp_path, experiments=["good"], progress=False, workers=1)
    validate.run_validation(tmp_path, experiments=["bad"], progress=False, workers=1)
    data = json.loads((tmp_path / "results.json").read_text())
    assert sorted(data["cases"]) == ["bad", "good"] and data["passed"] is False
    assert [c["case"] for c in data["checks"]].count("good") == 1
    report = (tmp_path / "report.md").read_text()
    assert "the kernel fell over" in report and "| x | value |" in report
    validate.run_validation(tmp_path, experiments=["good"], progress=False, workers=1, quick=True)
    data = json.loads((tmp_path / "results.json").read_text())
    assert [c["case"] for c in data["checks"]].count("good") == 1 and data["quick"] is False  # 'bad' was full
    assert "(full)" in (tmp_path / "report.md").read_text()


def test_cli_exit_status(tmp_path, monkeypatch):
    monkeypatch.setattr(validate, "available_experiments", fake_cases)
    ok = CliRunner().invoke(app, ["validate", "--out", str(tmp_path / "a"), "--case", "good", "--no-progress", "-w", "1"])
    assert ok.exit_code == 0, ok.output
    failing = CliRunner().invoke(app, ["validate", "--out", str(tmp_path / "b"), "--no-progress", "-w", "1"])
    assert failing.exit_code == 1 and "bad" in failing.output
    unknown = CliRunner().invoke(app, ["validate", "--out", str(tmp_path / "c"), "--case", "nope", "--no-progress", "-w", "1"])
    assert unknown.exit_code == 2 and "experiment = nope is not known" in unknown.output


def test_unknown_model_is_refused():
    from rollingdem.experiments import rolling_flat
    with pytest.raises(rd.ParameterError, match="models = \\['epsd9'\\] are not known"):
        rolling_flat(models=["epsd9"])


def test_student_t_interval_matches_the_table_value():
    """Three values 1, 2, 3: mean 2, s = 1, t(0.975, 2 dof) = 4.303 (printed tables): 4.303 / sqrt(3)."""
    from rollingdem.analysis.intervals import confidence_interval
    mean, half = confidence_interval([1.0, 2.0, 3.0, math.nan])
    assert mean == 2.0 and half == pytest.approx(4.303 / math.sqrt(3), abs=1e-3)
    assert math.isnan(confidence_interval([5.0])[1])


def test_repose_trend_checks_use_the_measured_points():
    """A pile at mu_r = 0 that did not settle has no angle: the trend checks compare the measured
    points, pass on a rising table, fail on a falling one, and fail when nothing is measured."""
    import pandas as pd

    from rollingdem.studies.repose_study import sweep_checks

    def table(angles):
        rows = [{"mu": mu, "mu_r": mur, "angle mean (deg)": a, "95 % CI ± (deg)": 0.5}
                for (mu, mur), a in angles.items()]
        return pd.DataFrame(rows)

    rising = {(0.2, 0.0): math.nan, (0.2, 0.1): 15.0, (0.2, 0.4): 20.0, (0.2, 0.8): 20.4,
              (0.6, 0.0): 12.0, (0.6, 0.1): 18.0, (0.6, 0.4): 26.0, (0.6, 0.8): 30.0}
    checks, _ = sweep_checks(table(rising), (0.2, 0.6), "rrlinear")
    assert all(c.passed for c in checks), [c.as_dict() for c in checks]
    grows = [c for c in checks if "at mu=0.2" in c.quantity][0]
    assert grows.measured == pytest.approx(5.4) and "mu_r=0.1)" in grows.quantity
    falling = {**rising, (0.6, 0.8): 10.0}
    assert not all(c.passed for c in sweep_checks(table(falling), (0.2, 0.6), "rrlinear")[0])
    empty = {k: math.nan for k in rising}
    assert not any(c.passed for c in sweep_checks(table(empty), (0.2, 0.6), "rrlinear")[0])


def test_repose_sweep_runs_creeping_piles_again_longer(tmp_path, monkeypatch):
    """A pile still creeping at max_collapse is run again to RETRY_COLLAPSE times it, and its
    angle enters the table; a pile without rolling resistance (it never settles) is not; a rerun
    on the same folder runs nothing. Stand-in piles: one at mu_r settles after 1 + 3 mu_r s, so
    mu_r = 1 needs 4 s (> 3.5 s, the full sweep's limit; < 7 s)."""
    from types import SimpleNamespace

    from rollingdem.experiments import repose
    from rollingdem.studies.repose_study import repose_sweep

    calls = []

    def fake_pile(rolling, twisting, seed, material, collapse, **kw):
        rolling_friction, max_collapse = material.rolling_friction, collapse.max_time
        calls.append((rolling_friction, seed, max_collapse))
        settle = 1.0 + 3.0 * rolling_friction if rolling_friction > 0 else math.inf
        if settle > max_collapse:
            return SimpleNamespace(angle=None, settled_at=math.nan, wall_time=1.0,
                                   angle_error=f"the pile did not settle within {max_collapse} s")
        return SimpleNamespace(angle=SimpleNamespace(angle=10.0 + 20.0 * rolling_friction + 0.1 * seed,
                                                     slice_std=0.5, r_squared=0.95),
                               settled_at=settle, angle_error="", wall_time=1.0)

    monkeypatch.setattr(repose, "pile_run", fake_pile)
    args = dict(frictions=(0.2, 0.6), rolling_frictions=(0.0, 0.5, 1.0), seeds=(1, 2), count=1000,
                outdir=tmp_path)
    result = repose_sweep(**args)
    assert len(calls) == 12 + 4  # the grid, then mu_r = 1 at both mu and both seeds, to 7 s
    assert sorted(c for c in calls if c[2] == 7.0) == [(1.0, 1, 7.0), (1.0, 1, 7.0), (1.0, 2, 7.0), (1.0, 2, 7.0)]
    table = result.table.set_index(["mu", "mu_r"])
    assert table.loc[(0.6, 1.0), "measured"] == 2
    assert table.loc[(0.6, 1.0), "angle mean (deg)"] == pytest.approx(30.15)
    assert table.loc[(0.2, 0.0), "measured"] == 0
    assert any("run again to 7 s" in n for n in result.notes)
    calls.clear()
    repose_sweep(**args)
    assert calls == []


def test_model_reaches_the_pile_cases_and_a_case_without_it_is_announced(tmp_path, monkeypatch):
    """--model goes to every case that runs models: the single-sphere cases and angle-of-repose take
    the list of theirs, repose-sweep its one model; a case that runs none of them is left out with
    a note (refused when named with --case); an unknown name is refused before anything is written."""
    calls = {}

    def fake(name):
        def case(quick=False, outdir=None, progress=None, runner=map, **kw):
            calls[name] = kw
            return ValidationResult(name, name, pd.DataFrame(), [Check(name, "x", "value", 1.0, 1.0, 0.01)])
        return case

    names = ["rolling-flat", "angle-of-repose", "repose-sweep"]
    monkeypatch.setattr(validate, "available_experiments", lambda: {n: fake(n) for n in names})
    notes = []
    validate.run_validation(tmp_path / "a", models=["epsd"], progress=False, workers=1, echo=notes.append)
    assert calls == {"rolling-flat": {"models": ["epsd"]}, "angle-of-repose": {"models": ["epsd"]},
                     "repose-sweep": {"model": "epsd"}} and notes == []
    calls.clear()
    validate.run_validation(tmp_path / "b", models=["sds", "epsd (liggghts)"], progress=False, workers=1,
                            echo=notes.append)
    assert calls == {"rolling-flat": {"models": ["sds", "epsd (liggghts)"]}}
    assert len(notes) == 2 and notes[0].startswith("angle-of-repose: left out") and "sweeps one rolling model" in notes[1]
    with pytest.raises(rd.ParameterError, match="model = 'sds' is not known to the experiments chosen"):
        validate.run_validation(tmp_path / "c", experiments=["angle-of-repose"], models=["sds"], progress=False, workers=1)
    with pytest.raises(rd.ParameterError, match="model = 'sds' is not allowed with experiment angle-of-repose: it runs "
                                                "none of them"):
        validate.run_validation(tmp_path / "c", experiments=["rolling-flat", "angle-of-repose"], models=["sds"],
                                progress=False, workers=1)
    with pytest.raises(rd.ParameterError, match="model = 'nonsense' is not known"):
        validate.run_validation(tmp_path / "c", models=["nonsense"], progress=False, workers=1)
    assert not (tmp_path / "c").exists()
    result = CliRunner().invoke(app, ["validate", "--out", str(tmp_path / "d"), "--model", "nonsense",
                                      "--no-progress", "-w", "1"])
    assert result.exit_code == 2 and "Traceback" not in result.output and "model = 'nonsense'" in result.output
