"""The measurements of the rigs: a pile's angle of repose (``PileAngle``), a drum's dynamic angle
(``DrumAngle``) and its bed's flow (``DrumFlow``), and a free surface's profile against a measured one
(``SurfaceProfile``). Each is a ``rollingdem.io.measurements.Measurement``; how each measures:
docs/measurements.md.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import NamedTuple

import numpy as np

from rollingdem.analysis.drum import com_angle, flowing_depth, flowing_layer, rotation_ratios, surface_angle
from rollingdem.analysis.repose import _check_exclusion, _check_n_slices, repose_angle, touching
from rollingdem.errors import Declared, ParameterError, check_finite, check_positive, check_vector
from rollingdem.io.measurements import Measurement, WallLoad, drum_frame, fixed_top, window_of


#: the drum measurements' common parameters (``Declared``)
DRUM_DECLARED = {"center": Declared("a point of the drum's axis", "m", "vector"),
                 "axis": Declared("the drum's axis (made unit length)", "-", "vector"),
                 "extent": Declared("[s0, s1]: the slice along the axis measured, from center (none: all)", "m",
                                    "pair")}


class PileAngle(Measurement):
    """The angle of repose of the free particles' pile (``rollingdem.analysis.repose.repose_angle``,
    docs/analysis.md): ``angle`` (deg, the cone fit), ``r_squared`` (the fit's), ``slice_mean`` and
    ``slice_std`` (deg, over ``n_slices`` azimuthal slices), on a floor at ``floor`` (m; default the
    top of the highest fixed particle, else 0), leaving out ``exclude_apex`` and ``exclude_toe`` of
    the pile radius. NaN where the estimator refuses the pile (``note`` says why)."""

    kind = "repose_angle"
    INTERVAL = 0.1
    QUANTITIES = {"angle": "deg", "r_squared": "1", "slice_mean": "deg", "slice_std": "deg"}
    CUMULATIVE = ("angle", "r_squared", "slice_mean", "slice_std")  # the end state's, not a mean

    declared = {**Measurement.declared,
                "floor": Declared("height of the floor the pile stands on (default the top of the fixed spheres)",
                                  "m"),
                "n_slices": Declared("azimuthal slices whose angles give the spread", kind="whole", low=1),
                "exclude_apex": Declared("fraction of the pile's radius left out about the apex", "-", low=0.0,
                                         high=0.5, high_open=True),
                "exclude_toe": Declared("fraction of the pile's radius left out at the toe", "-", low=0.0, high=0.5,
                                        high_open=True)}

    def __init__(self, name: str = "repose_angle", floor: float | None = None, n_slices: int = 8,
                 exclude_apex: float = 0.15, exclude_toe: float = 0.15, interval: float | None = None, window=None):
        super().__init__(name, interval, window)

        self.floor = None if floor is None else check_finite("repose_angle floor", floor)
        self.n_slices = _check_n_slices(n_slices)
        self.exclude_apex = _check_exclusion("exclude_apex", exclude_apex)
        self.exclude_toe = _check_exclusion("exclude_toe", exclude_toe)
        self.note = None
        self.result = None

    def describe(self):
        return (f"cone fit to the pile, exclude_apex {self.exclude_apex:g}, exclude_toe {self.exclude_toe:g}, "
                f"{self.n_slices} slices")

    def floor_of(self, sim) -> float:
        return self.floor if self.floor is not None else fixed_top(sim)

    def values(self, sim):
        free = ~sim.fixed
        try:
            a = repose_angle(sim.positions[free], sim.radii[free], floor=self.floor_of(sim), n_slices=self.n_slices,
                             exclude_apex=self.exclude_apex, exclude_toe=self.exclude_toe)
        except ParameterError as err:
            self.note, self.result = str(err), None
            return [math.nan] * 4
        self.note, self.result = None, a
        return [a.angle, a.r_squared, a.slice_mean, a.slice_std]

    def headline(self):
        return ["angle", "r_squared"]


class DrumAngle(Measurement):
    """The dynamic angle of a drum's bed, seen along the drum's ``axis`` through ``center``, in the
    viewing window ``extent`` = (s0, s1) (m along the axis from ``center``; default all of it):
    ``angle`` (deg, a line through the free surface in the middle third of its chord,
    ``rollingdem.analysis.drum.surface_angle``) and ``com_angle`` (deg, how far the bed's centre of
    mass has turned from below the axis), both as magnitudes, and ``weight_moment`` (N m, the
    magnitude of the moment of the bed's weight about the axis, |g sum m x| with x across the
    drum: the torque a drum turning steadily supplies); gravity gives "down"."""

    kind = "drum_angle"
    INTERVAL = 0.01
    QUANTITIES = {"angle": "deg", "com_angle": "deg", "weight_moment": "N m"}

    declared = {**Measurement.declared, **DRUM_DECLARED}

    def __init__(self, name: str, center, axis, extent=None, interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        self.center = np.array(check_vector("drum_angle center", center))
        self.axis = np.array(check_vector("drum_angle axis", axis, unit=True))
        self.extent = None if extent is None else window_of(extent)
        self.note = None

    def describe(self):
        where = "" if self.extent is None else f", window {self.extent[0]:g}-{self.extent[1]:g} m along it"
        return f"drum bed's angle about the axis {tuple(self.axis.tolist())} through {tuple(self.center.tolist())}{where}"

    def check(self, sim):
        if abs(float(np.asarray(sim.gravity) @ self.axis)) > 0.999 * float(np.linalg.norm(sim.gravity)):
            raise ParameterError(f"measurement {self.name!r}: axis = {tuple(self.axis.tolist())} is not allowed: it is "
                                 "along gravity; a drum's axis must be across it")

    def values(self, sim):
        across, up = drum_frame(sim, self.axis)
        rel = sim.positions - self.center
        s = rel @ self.axis
        keep = ~sim.fixed
        if self.extent is not None:
            keep &= (s >= self.extent[0]) & (s <= self.extent[1])
        frame = np.column_stack([rel @ across, rel @ up, s])[keep]  # a turn: distances kept
        r, m = sim.radii[keep], sim.masses[keep]
        try:
            angle = abs(surface_angle(frame, r, 2.0 * float(r.mean()))[0])
        except (ParameterError, ValueError) as err:
            self.note, angle = str(err), math.nan
        g = float(np.linalg.norm(sim.gravity))
        return [angle, abs(com_angle(frame, m)) if len(m) else math.nan, abs(g * float(m @ frame[:, 0]))]


class _DrumSample(NamedTuple):
    """One sample of ``DrumFlow``, across the drum: positions and velocities (across, up, along),
    the surface line (slope, a point on it), omega, the mean diameter, the largest radius and the
    flowing layer's profile (depth, downslope speed) at the chord's middle."""
    time: float
    x: np.ndarray
    v: np.ndarray
    slope: float
    point: np.ndarray
    omega: float
    diameter: float
    largest: float  # radius (m)
    profile: tuple

    def surface(self) -> tuple:
        """What ``rotation_ratios`` takes of it."""
        return self.x, self.v, self.slope, self.point


class DrumFlow(Measurement):
    """How a drum's bed flows, seen along the drum's ``axis`` through ``center`` (gravity gives
    "down"), in a drum of ``radius`` (m) turned by the wall named ``wall`` (its angular velocity
    about the axis is the drum's, omega): ``flowing_depth`` (m, where the mean downslope speed at
    the middle of the free surface's chord falls to zero, ``rollingdem.analysis.drum.flowing_depth``)
    and, below the flowing layer and in the middle third of the arc along which the bed touches the
    wall, the speed of the passive zone off the wall and of the spheres touching the wall, each over
    omega r (``passive_speed_ratio``, ``wall_layer_speed_ratio``: 1 is solid-body rotation,
    ``rollingdem.analysis.drum.rotation_ratios``).

    Each sample's values are in the series. The summary's ``value`` pools the window's samples:
    the depth from all their spheres at once, the ratios from all their spheres below that depth.
    To do so it keeps each sample's positions and velocities across the drum: give a ``window``
    for a long run."""

    kind = "drum_flow"
    INTERVAL = 0.05
    QUANTITIES = {"flowing_depth": "m", "passive_speed_ratio": "1", "wall_layer_speed_ratio": "1"}

    declared = {**Measurement.declared, **DRUM_DECLARED,
                "radius": Declared("the drum's inner radius", "m", low=0.0, low_open=True),
                "wall": Declared("name of the wall that turns the drum", kind="text")}

    def __init__(self, name: str, center, axis, radius: float, wall: str, extent=None, interval: float | None = None,
                 window=None):
        super().__init__(name, interval, window)
        self.center = np.array(check_vector("drum_flow center", center))
        self.axis = np.array(check_vector("drum_flow axis", axis, unit=True))
        self.radius = check_positive("drum_flow radius", radius, "m")
        self.wall = wall
        self.extent = None if extent is None else window_of(extent)
        self._samples: list[_DrumSample] = []  # those in the window

    def describe(self):
        return (f"drum bed's flow about the axis {tuple(self.axis.tolist())} through {tuple(self.center.tolist())}, "
                f"drum radius {self.radius:g} m turned by wall {self.wall!r}")

    measured_wall = WallLoad.measured_wall

    def check(self, sim):
        DrumAngle.check(self, sim)
        WallLoad.check(self, sim)

    def _frame(self, sim):
        """The free spheres across the drum: positions (across, up) from the axis, velocities, radii,
        the mean diameter and omega about the axis."""
        across, up = drum_frame(sim, self.axis)
        rel = sim.positions - self.center
        keep = ~sim.fixed
        if self.extent is not None:
            s = rel @ self.axis
            keep &= (s >= self.extent[0]) & (s <= self.extent[1])
        basis = np.column_stack([across, up, self.axis])  # a turn: distances kept
        wall = self.measured_wall(sim)
        omega = float(np.asarray(wall.angular_velocity, float) @ self.axis) if wall is not None else math.nan
        r = sim.radii[keep]
        return rel[keep] @ basis, sim.velocities[keep] @ basis, r, 2.0 * float(r.mean()), omega

    def observe(self, sim) -> None:
        x, v, r, d, omega = self._frame(sim)
        try:
            _, slope, xm, ym = surface_angle(x, r, d)
        except (ParameterError, ValueError):
            self._record(sim, [math.nan] * 3)
            return
        sample = _DrumSample(sim.time, x, v, slope, np.array((xm, ym)), omega, d, float(r.max()),
                             flowing_layer(x, v, slope, (xm, ym), d))
        depth = flowing_depth(*sample.profile, d)
        ratios = rotation_ratios([sample.surface()], omega, self.radius, depth, d, sample.largest)
        if self.window is None or self.window[0] - 1e-12 <= sim.time <= self.window[1] + 1e-12:
            self._samples.append(sample)
        self._record(sim, [depth, *ratios])

    def pooled(self) -> tuple[float, float, float]:
        """(flowing depth, passive and wall layer speed ratios) over the summary's window's samples."""
        if not self._rows:
            return math.nan, math.nan, math.nan
        _, (t0, t1), _ = self._inwindow_of()
        chosen = [s for s in self._samples if t0 - 1e-12 <= s.time <= t1 + 1e-12]
        if not chosen:
            return math.nan, math.nan, math.nan
        d = float(np.mean([s.diameter for s in chosen]))
        depth = flowing_depth(np.concatenate([s.profile[0] for s in chosen]),
                              np.concatenate([s.profile[1] for s in chosen]), d)
        omega = float(np.mean([s.omega for s in chosen]))
        ratios = rotation_ratios([s.surface() for s in chosen], omega, self.radius, depth, d,
                                 max(s.largest for s in chosen))
        return depth, *ratios

    def summary(self) -> dict:
        out = super().summary()
        if out["samples"]:
            for q, v in zip(self.QUANTITIES, self.pooled()):
                out[q]["value"] = out[q]["pooled"] = v
        return out

    def summary_line(self) -> str:
        s = self.summary()
        if not s["samples"]:
            return f"{self.name}: no samples in the window"
        t0, t1 = s["window"]
        return (f"{self.name} ({self.describe()}): flowing layer {s['flowing_depth']['value']:.4g} m deep, passive "
                f"zone at {s['passive_speed_ratio']['value']:.4g} and wall layer at "
                f"{s['wall_layer_speed_ratio']['value']:.4g} of omega r (the samples of {t0:.3g}-{t1:.3g} s pooled)")


def read_profile(path) -> np.ndarray:
    """A measured surface profile: a CSV of two columns of numbers (m), a header line allowed, as
    (n, 2), sorted by the first; refused in one line when it is not that."""
    path = Path(path)
    try:
        rows = np.genfromtxt(path, delimiter=",", comments="#", skip_header=0)
    except OSError:
        raise ParameterError(f"profile file = {str(path)!r} is not allowed: it cannot be read") from None
    rows = np.atleast_2d(rows)
    rows = rows[np.isfinite(rows).all(axis=1)] if rows.ndim == 2 and rows.shape[1] == 2 else None
    if rows is None or len(rows) < 2:
        raise ParameterError(f"profile file = {str(path)!r} is not allowed: must hold two columns of numbers "
                             "(m) and at least two rows")
    return rows[np.argsort(rows[:, 0])]


class SurfaceProfile(Measurement):
    """How far the free surface is from a measured profile (``points``: (n, 2), m): ``rmse`` (m,
    the root mean square of simulated minus measured heights at the measured points) and ``bias``
    (m, their mean).

    ``shape`` "heap": the points are (r, h), the distance from the pile's axis through ``center``
    (x, y; default the free particles' centre of mass) and the height above ``floor`` (default the
    top of the highest fixed particle, else 0); the simulated height at r is the median, over those
    of 8 sectors around the axis that hold a particle there, of the highest particle top within a
    mean diameter of r (the floor where none is).
    ``shape`` "drum": the points are (x, y) across and up in the drum's cross-section about its
    ``axis`` through ``center`` (gravity gives up); the simulated height at x is the top of the
    highest particle touching another within half a mean diameter of x (``DrumAngle``'s columns).
    Where no particle is, the height is the floor's (heap) or NaN (drum, left out).

    Each sample's rmse and bias are in the series. The summary's ``value`` is what a measured
    profile is compared with: a heap's end state; for a drum, the surface averaged over the window
    (each point's mean height over the samples that have one there, as a GranuDrum averages its
    images), whose misfit is free of the surface's moment-to-moment scatter."""

    kind = "profile"
    INTERVAL = 0.1
    QUANTITIES = {"rmse": "m", "bias": "m"}

    def __init__(self, name: str, points, shape: str = "heap", center=None, axis=(0.0, 0.0, 1.0), floor=None,
                 interval: float | None = None, window=None):
        super().__init__(name, interval, window)
        if shape not in ("heap", "drum"):
            raise ParameterError(f"profile shape = {shape!r} is not allowed: must be 'heap' or 'drum'")
        self.shape = shape
        self.points = np.asarray(points, float)
        if self.points.ndim != 2 or self.points.shape[1] != 2 or len(self.points) < 2:
            raise ParameterError(f"profile points of shape {self.points.shape} are not allowed: must be (n, 2), n >= 2")
        self.center = None if center is None else np.array(center, float)
        self.axis = np.array(check_vector("profile axis", axis, unit=True))
        # a heap is measured at rest: its summary is the end state's; a drum's, the mean over the window
        self.CUMULATIVE = ("rmse", "bias") if shape == "heap" else ()
        self.floor = None if floor is None else check_finite("profile floor", floor)
        self._heights: list[np.ndarray] = []  # each sample's, for a drum's mean surface

    def describe(self):
        return f"{self.shape} surface against {len(self.points)} measured points"

    def observe(self, sim) -> None:
        h = self.heights(sim)
        if self.shape == "drum":
            self._heights.append(h)
        self._record(sim, self._misfit(h))

    def mean_misfit(self) -> tuple[float, float]:
        """A drum's (rmse, bias) of its surface averaged over the summary's window; NaN for none."""
        if not self._rows:
            return math.nan, math.nan
        h = np.array(self._heights)[self._inwindow_of()[2]]
        seen = np.isfinite(h).any(axis=0)  # a point the surface never reached stays out
        mean = np.full(len(self.points), np.nan)
        mean[seen] = np.nanmean(h[:, seen], axis=0)
        rmse, bias = self._misfit(mean)
        return rmse, bias

    def summary(self) -> dict:
        out = super().summary()
        if self.shape == "drum" and out["samples"]:
            for q, v in zip(("rmse", "bias"), self.mean_misfit()):
                out[q]["value"] = out[q]["of_mean_surface"] = v
        return out

    def summary_line(self) -> str:
        if self.shape != "drum":
            return super().summary_line()
        s = self.summary()
        if not s["samples"]:
            return f"{self.name}: no samples in the window"
        t0, t1 = s["window"]
        return (f"{self.name} ({self.describe()}): rmse {s['rmse']['value']:.4g} m, bias {s['bias']['value']:.4g} m "
                f"(the surface averaged over {t0:.3g}-{t1:.3g} s; each sample's rmse {s['rmse']['mean']:.4g} m on average)")

    def heights(self, sim) -> np.ndarray:
        """The simulated surface height at each measured point's first coordinate."""
        free = ~sim.fixed
        x, r = sim.positions[free], sim.radii[free]
        if not len(x):
            return np.full(len(self.points), np.nan)
        half = float(r.mean())  # half a mean diameter
        if self.shape == "heap":
            ring = 2.0 * half  # a mean diameter each side: a ring holds a particle in most sectors
            floor = self.floor if self.floor is not None else fixed_top(sim)
            c = self.center[:2] if self.center is not None else np.average(x[:, :2], axis=0, weights=sim.masses[free])
            rho = np.hypot(x[:, 0] - c[0], x[:, 1] - c[1])
            sector = (np.floor((np.arctan2(x[:, 1] - c[1], x[:, 0] - c[0]) + math.pi) / (math.pi / 4)).astype(int)) % 8
            top = x[:, 2] + r - floor
            out = np.empty(len(self.points))
            for k, q in enumerate(self.points[:, 0]):
                near = np.abs(rho - q) <= ring
                tops = [top[near & (sector == s)].max() for s in range(8) if (near & (sector == s)).any()]
                out[k] = float(np.median(tops)) if tops else 0.0
            return out

        across, up = drum_frame(sim, self.axis)
        rel = x - (self.center if self.center is not None else np.zeros(3))
        on = touching(x, r)
        u, h = (rel @ across)[on], (rel @ up)[on] + r[on]
        return np.array([h[np.abs(u - q) <= half].max() if (np.abs(u - q) <= half).any() else np.nan
                         for q in self.points[:, 0]])

    def values(self, sim):
        return self._misfit(self.heights(sim))

    def _misfit(self, heights) -> list[float]:
        """[rmse, bias] of simulated ``heights`` minus the measured ones, where a height exists."""
        d = heights - self.points[:, 1]
        d = d[np.isfinite(d)]
        return [float(np.sqrt(np.mean(d ** 2))), float(np.mean(d))] if len(d) else [math.nan, math.nan]

    def headline(self):
        return ["rmse", "bias"]


__all__ = ["DrumAngle", "DrumFlow", "PileAngle", "SurfaceProfile", "read_profile"]
