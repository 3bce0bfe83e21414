"""A report for every run: ``report.html`` beside PNG figures, readable without ParaView.

What it shows: the run's header (particles by kind, walls, the contact law in words, dt), how each
stage ended, the end summary of every measurement (and the pile's angle), pictures of the scene
(the particles as discs and the walls as outlines, from the side and from above, gravity down) at
chosen times, each measurement's time series, and the energy: kinetic (translational and
rotational) and what the contacts dissipated, over time.
"""

from __future__ import annotations

import html
import math
from pathlib import Path

import numpy as np

from rollingdem.scene.schedule import Observer


def _pyplot():
    import matplotlib  # deferred: slow to load, figures only

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # deferred: slow to load, figures only

    return plt


def _views(gravity) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(across, along, up): ``up`` against gravity, two horizontal axes, the first near x."""
    g = np.asarray(gravity, float)
    up = -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 0.0, 1.0])
    seed = np.eye(3)[int(np.argmin(np.abs(up)))]
    across = seed - (seed @ up) * up
    across /= np.linalg.norm(across)
    return across, np.cross(up, across), up


class ScenePictures(Observer):
    """Keeps the scene (particles, walls) at each of ``times`` (s) and at every run's last step,
    for ``draw``; a run's state between pictures is not kept."""

    def __init__(self, times=()):
        super().__init__(1.0)
        self.times = sorted(float(t) for t in times)
        self.frames: list[dict] = []

    def start(self, sim):
        super().start(sim)
        self._pending = [t for t in self.times if t >= sim.time - 0.5 * sim.dt and
                         all(abs(f["time"] - t) > 0.5 * sim.dt for f in self.frames)]
        self._next = self._step_of(sim)

    def _step_of(self, sim) -> int:
        if not self._pending:
            return 2 ** 62
        return sim.step + max(int(round((self._pending[0] - sim.time) / sim.dt)), 0)

    def maybe_observe(self, sim, force: bool = False) -> None:
        if force or sim.step >= self._next:
            if not self.frames or self.frames[-1]["step"] != sim.step:
                self.observe(sim)
            while self._pending and self._pending[0] <= sim.time + 0.5 * sim.dt:
                self._pending.pop(0)
            self._next = self._step_of(sim)

    def observe(self, sim):
        walls = []
        for w in sim.walls:
            kind = type(w).__name__
            if kind == "Plane":
                walls.append(("plane", np.array(w.point), np.array(w.normal)))
            elif kind == "Cylinder":
                walls.append(("cylinder", np.array(w.point), np.array(w.axis), w.radius, w.extent))
        walls += [("mesh", m.vertices.copy(), m.triangles.copy()) for m in sim.mesh_walls().values()]
        self.frames.append({"time": sim.time, "step": sim.step, "positions": sim.positions.copy(),
                            "radii": sim.radii.copy(), "fixed": sim.fixed.copy(), "walls": walls,
                            "gravity": tuple(sim.gravity)})


def draw_frame(frame: dict, path: Path, title: str = "") -> Path:
    """The scene of one frame, from the side and from above, as a PNG."""
    from matplotlib.collections import EllipseCollection, LineCollection  # deferred: slow to load, figures only

    plt = _pyplot()
    across, along, up = _views(frame["gravity"])
    x, r, fixed = frame["positions"], frame["radii"], frame["fixed"]
    fig, axes = plt.subplots(1, 2, figsize=(11, 5))
    for ax, (h, v, label) in zip(axes, ((across, up, "side"), (across, along, "from above"))):
        lines, lo, hi = [], [], []
        for wall in frame["walls"]:
            if wall[0] == "mesh":
                tri = wall[1][wall[2]]  # (m, 3, 3)
                edges = np.concatenate([tri[:, [0, 1]], tri[:, [1, 2]], tri[:, [2, 0]]])
                lines.append(np.stack([edges @ h, edges @ v], axis=-1))
                lo.append(wall[1].min(axis=0))
                hi.append(wall[1].max(axis=0))
        if len(x):
            lo.append((x - r[:, None]).min(axis=0))
            hi.append((x + r[:, None]).max(axis=0))
        corners = np.array([[a, b, c] for a in (0, 1) for b in (0, 1) for c in (0, 1)], float)
        box = np.array([lo_ + (hi_ - lo_) * corners for lo_, hi_ in zip(lo, hi)]).reshape(-1, 3) if lo else np.zeros((1, 3))
        u, w = box @ h, box @ v
        span = max(np.ptp(u), np.ptp(w), 1e-9)
        for wall in frame["walls"]:
            if wall[0] == "plane":
                p, n = wall[1], wall[2]
                d = np.cross(n, np.cross(h, v))  # the plane's trace in this view
                if np.linalg.norm(d) > 1e-9:
                    d /= np.linalg.norm(d)
                    ends = np.array([p - 2 * span * d, p + 2 * span * d])
                    lines.append(np.stack([ends @ h, ends @ v], axis=-1)[None])
            elif wall[0] == "cylinder":
                p, a, radius, ext = wall[1], wall[2], wall[3], wall[4]
                s0, s1 = (max(ext[0], -2 * span), min(ext[1], 2 * span))
                side = np.cross(a, np.cross(h, v))
                side = side / np.linalg.norm(side) if np.linalg.norm(side) > 1e-9 else None
                if side is None:  # seen along its axis: a circle
                    t = np.linspace(0, 2 * math.pi, 97)
                    e1 = np.cross(a, h)
                    e1 /= np.linalg.norm(e1)
                    e2 = np.cross(a, e1)
                    ring = p + radius * (np.outer(np.cos(t), e1) + np.outer(np.sin(t), e2))
                    lines.append(np.stack([ring @ h, ring @ v], axis=-1)[None])
                else:
                    for sgn in (-1, 1):
                        ends = np.array([p + s0 * a + sgn * radius * side, p + s1 * a + sgn * radius * side])
                        lines.append(np.stack([ends @ h, ends @ v], axis=-1)[None])
        for seg in lines:
            ax.add_collection(LineCollection(seg, colors="0.45", linewidths=0.4, alpha=0.6))
        depth = x @ np.cross(h, v)
        order = np.argsort(depth)  # the nearer drawn last
        colors = np.where(fixed[order], "0.6", "tab:blue")
        if len(x):
            ax.add_collection(EllipseCollection(2 * r[order], 2 * r[order], np.zeros(len(x)), units="xy",
                                                offsets=np.column_stack([x[order] @ h, x[order] @ v]),
                                                offset_transform=ax.transData, facecolors=colors,
                                                edgecolors="k", linewidths=0.2))
        ax.set_xlim(u.min() - 0.05 * span, u.max() + 0.05 * span)
        ax.set_ylim(w.min() - 0.05 * span, w.max() + 0.05 * span)
        ax.set_aspect("equal")
        ax.set_title(f"{label} (m)")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


def plot_measurement(m, path: Path) -> Path:
    """Each quantity of a measurement over time, its summary's window shaded."""
    plt = _pyplot()
    df = m.series()
    quantities = list(m.QUANTITIES or ())
    n = max(len(quantities), 1)
    cols = min(n, 3)
    rows = math.ceil(n / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 2.8 * rows), squeeze=False)
    s = m.summary()
    for ax, q in zip(axes.flat, quantities):
        ax.plot(df["time"], df[q], lw=1)
        if "window" in s:
            ax.axvspan(*s["window"], color="0.9", zorder=0)
        unit = m.QUANTITIES[q]
        ax.set_ylabel(f"{q}" + (f" ({unit})" if unit not in ("", "1") else ""))
        ax.set_xlabel("time (s)")
    for ax in list(axes.flat)[len(quantities):]:
        ax.set_visible(False)
    fig.suptitle(f"{m.name}: {m.describe()}", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def plot_energy(series_csv: Path, path: Path) -> Path | None:
    """Kinetic energy (translational, rotational) and the energy the contacts dissipated
    (cumulative, by channel) over time."""
    import pandas as pd  # deferred: slow to load, tables only

    if not Path(series_csv).exists():
        return None
    df = pd.read_csv(series_csv)
    if not len(df):
        return None
    plt = _pyplot()
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 4))
    for col, label in (("kinetic_translational", "translational"), ("kinetic_rotational", "rotational")):
        a.plot(df["time"], np.maximum(df[col], 1e-300), label=label, lw=1)
    a.set_yscale("log")
    positive = df["kinetic_translational"] + df["kinetic_rotational"]
    positive = positive[positive > 0]
    if len(positive):
        a.set_ylim(max(positive.min() * 0.3, positive.max() * 1e-14), positive.max() * 3)
    a.set_title("kinetic energy (J)")
    for col in [c for c in df.columns if c.startswith("dissipated_")]:
        b.plot(df["time"], df[col], label=col.removeprefix("dissipated_").replace("_", " "), lw=1)
    b.set_title("dissipated in the contacts, cumulative (J)")
    for ax in (a, b):
        ax.set_xlabel("time (s)")
        ax.legend(fontsize=8)
        ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def _table(rows) -> str:
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>" for row in rows)
    return f"<table>{body}</table>"


def _fmt(v) -> str:
    return f"{v:.4g}" if isinstance(v, float) and math.isfinite(v) else "–" if isinstance(v, float) else str(v)


def _span(bounds) -> str:
    """"28.9–31.0°" for (low, high) in degrees; "–" without them."""
    if not bounds or len(bounds) != 2 or not all(isinstance(b, (int, float)) and math.isfinite(b) for b in bounds):
        return "–"
    return f"{bounds[0]:.1f}–{bounds[1]:.1f}°"


def write_report(outdir: Path, summary: dict, header: list[str], measurements: dict, pictures: ScenePictures | None,
                 case_name: str) -> Path:
    """``outdir/report.html`` and its figures (``outdir/report/``)."""
    folder = outdir / "report"
    folder.mkdir(exist_ok=True)
    parts = [f"<h1>{html.escape(case_name)}</h1>", "<p>" + "<br>".join(html.escape(h) for h in header) + "</p>"]
    stages = [[s["name"], s.get("ended", ""), _fmt(s.get("end_time", math.nan)), s["steps"],
               _fmt(s["wall_seconds"])] for s in summary.get("stages", [])]
    parts.append("<h2>Stages</h2>" + _table([["stage", "ended by", "at t (s)", "steps", "wall time (s)"]] + stages))
    status = summary.get("status", "")
    parts.append(f"<p>status: {html.escape(str(status))}; {summary.get('steps', 0)} steps, simulated time "
                 f"{_fmt(summary.get('time', math.nan))} s, wall time {_fmt(summary.get('wall_seconds', math.nan))} s</p>")
    if measurements:
        parts.append("<h2>Measurements</h2><p>" + "<br>".join(html.escape(m.summary_line())
                                                               for m in measurements.values()) + "</p>")
        if any("parcels of alpha" in line for line in header):
            parts.append("<p>Counts are of parcels, each standing for alpha³ real particles; masses, densities "
                         "and rates are the real material's.</p>")
        rows = [["measurement", "quantity", "final", "mean", "standard error", "unit", "window (s)"]]
        for name, m in measurements.items():
            s = m.summary()
            for q in m.QUANTITIES or ():
                if q in s:
                    e = s[q]
                    cumulative = q in m.CUMULATIVE  # its final value is the answer: no mean of a running sum
                    rows.append([name, q, _fmt(e["final"]), "–" if cumulative else _fmt(e["mean"]),
                                 "–" if cumulative else _fmt(e["standard_error"]), e["unit"],
                                 "–".join(_fmt(t) for t in s.get("window", []))])
        parts.append("<details><summary>every quantity at the end</summary>" + _table(rows)
                     + "<p>mean and standard error over the window (batch means); a rate: the least-squares slope "
                     "of its cumulative quantity; a cumulative count or mass: its final value.</p></details>")
    pile = summary.get("repose_angle")
    if pile and pile.get("angle") is not None:
        parts.append(f"<h2>The pile</h2><p>repose angle {pile['angle']:.1f}° (cone fit R² {pile['r_squared']:.2f}); "
                     f"{_span(pile.get('option_range'))} over the estimator's options; slices "
                     f"{pile['slice_mean']:.1f} ± {pile['slice_std']:.1f}°</p><img src='pile.png' width=700>")
    if pictures is not None and pictures.frames:
        parts.append("<h2>The scene</h2>")
        for k, frame in enumerate(pictures.frames):
            png = draw_frame(frame, folder / f"scene_{k:02d}.png", f"t = {frame['time']:.4g} s")
            parts.append(f"<p>t = {frame['time']:.4g} s</p><img src='report/{png.name}' width=900>")
    if measurements:
        parts.append("<h2>Measurements over time</h2>")
        for name, m in measurements.items():
            png = plot_measurement(m, folder / f"measurement_{name}.png")
            parts.append(f"<img src='report/{png.name}' width=900>")
    energy = plot_energy(outdir / "series.csv", folder / "energy.png")
    if energy is not None:
        parts.append(f"<h2>Energy</h2><img src='report/{energy.name}' width=900>")
    style = ("<style>body{font-family:sans-serif;max-width:960px;margin:auto}td{padding:2px 8px;"
             "border-bottom:1px solid #ddd}</style>")
    path = outdir / "report.html"
    path.write_text(f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>{html.escape(case_name)}</title>"
                    f"{style}</head><body>{''.join(parts)}</body></html>")
    return path


__all__ = ["ScenePictures", "draw_frame", "plot_energy", "plot_measurement", "write_report"]
