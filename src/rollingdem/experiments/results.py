"""What an experiment's validation returns: its table, its checks against references, its figures."""

from __future__ import annotations

import hashlib
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd

from rollingdem.analysis.intervals import confidence_interval


@dataclass
class Check:
    """One measured value against its reference: passes when |measured - reference| <= tolerance
    (absolute, in the quantity's unit) or, for ``relative``, <= tolerance |reference|; a one-sided
    bound uses ``bound`` = "upper" (measured <= reference) or "lower" (measured >= reference)."""

    case: str  # the experiment's name, under this key in results.json and cases/NAME.json
    model: str
    quantity: str
    measured: float
    reference: float
    tolerance: float
    relative: bool = True
    bound: str = "two-sided"
    source: str = ""

    @property
    def passed(self) -> bool:
        if not math.isfinite(self.measured):
            return False
        if self.bound == "upper":
            return self.measured <= self.reference
        if self.bound == "lower":
            return self.measured >= self.reference
        allowed = self.tolerance * abs(self.reference) if self.relative else self.tolerance
        return abs(self.measured - self.reference) <= allowed

    def as_dict(self) -> dict:
        return {"case": self.case, "model": self.model, "quantity": self.quantity, "measured": float(self.measured),
                "reference": float(self.reference), "tolerance": float(self.tolerance),
                "tolerance_kind": f"{self.bound} bound" if self.bound in ("upper", "lower") else
                ("relative" if self.relative else "absolute"),
                "source": self.source, "pass": bool(self.passed)}


@dataclass
class ValidationResult:
    """A validation's outcome: ``table`` (one row per model or run), ``checks``, ``figures``
    (PNG paths) and free-form ``notes`` for the report."""

    name: str
    title: str
    table: pd.DataFrame
    checks: list[Check] = field(default_factory=list)
    figures: list[Path] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    wall_time: float = 0.0

    @property
    def passed(self) -> bool:
        return all(c.passed for c in self.checks)

    def add_figure(self, fig, outdir, name: str) -> Path:
        """Save ``fig`` as ``outdir/name`` (PNG, 120 dpi), close it and list it in the report."""
        import matplotlib.pyplot as plt  # deferred: slow to load, figures only

        path = Path(outdir) / name
        fig.tight_layout()
        fig.savefig(path, dpi=120)
        plt.close(fig)
        self.figures.append(path)
        return path


#: the contact laws' revision a kept run (``kept_run``) was made with: raised when a law changes what
#: the studies give, so that the runs of the laws before are run again (2: the history spring's cap, §1.2)
LAWS_REVISION = 2


def kept_run(folder: Path | None, key: list, compute, record: dict) -> dict:
    """``compute``'s observables, kept in ``folder`` as ``<sha1 of key>.json`` (with ``record``, the
    key and the result) once it returns, and read from there instead of computed when it exists:
    a long study stopped goes on from the runs it has. ``compute`` takes the path a run in progress
    may save itself to (``folder/<name>.partial``; None without ``folder``)."""
    if folder is None:
        return compute(None)
    folder = Path(folder)
    path = folder / (hashlib.sha1(json.dumps(key, sort_keys=True, default=str).encode()).hexdigest()[:16] + ".json")
    if path.exists():
        return json.loads(path.read_text())["result"]
    folder.mkdir(parents=True, exist_ok=True)
    res = compute(path.with_suffix(".partial"))
    path.write_text(json.dumps({**record, "size": key, "result": res},
                               default=lambda v: v.item() if hasattr(v, "item") else str(v)))
    return res


def pyplot():
    """matplotlib.pyplot on the Agg backend (no display needed), with a 20-colour cycle so that
    the twelve models of a figure stay distinguishable."""
    import matplotlib  # deferred: slow to load, figures only
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: slow to load, figures only
    plt.rcParams["axes.prop_cycle"] = plt.cycler(color=plt.get_cmap("tab20").colors)
    return plt


# --- what several experiments' validations share ----------------------------------------------
def run_points(experiment, points: list[dict], seeds, runner, progress) -> pd.DataFrame:
    """Every point at every seed through ``runner``: one row per run (parameters and observables)."""
    items = [dict(p, seed=s) for p in points for s in seeds]
    run = experiment.observe
    rows = []
    for params, observables in zip(items, runner(run, items)):
        rows.append({**params, **observables})
        if progress:
            progress()
    return pd.DataFrame(rows)


def mean_ci(runs: pd.DataFrame, keys: list[str], value: str, within: str | None = None) -> pd.DataFrame:
    """Mean of ``value`` over seeds per point with its 95 % Student-t half-width; with one seed,
    the run's own interval ``within`` (if given)."""
    rows = []

    for point, grp in runs.groupby(keys, sort=True):
        point = point if isinstance(point, tuple) else (point,)
        mean, half = confidence_interval(grp[value])
        if len(grp) == 1 and within is not None:
            half = float(grp[within].iloc[0])
        rows.append({**dict(zip(keys, point)), f"{value} mean": mean, f"{value} 95% CI": half, "runs": len(grp)})
    return pd.DataFrame(rows)


def rises(experiment, label, table, key, fixed, value="angle") -> Check:
    """Check that ``value`` grows along ``key`` with the other parameters at ``fixed``: the smallest
    step between successive means must be positive."""
    sel = table
    for k, v in fixed.items():
        sel = sel[np.isclose(sel[k], v)]
    sel = sel.sort_values(key)
    steps = np.diff(sel[f"{value} mean"].to_numpy())
    where = ", ".join(f"{k} = {v:g}" for k, v in fixed.items())
    return Check(experiment, label, f"smallest rise of the {value} between successive {key} "
                 f"({', '.join(f'{x:g}' for x in sel[key])}) at {where} (deg)",
                 float(steps.min()) if len(steps) else math.nan, 0.0, 0.0, bound="lower",
                 source=f"physics: more {key}, more resistance to flow, a steeper surface")
