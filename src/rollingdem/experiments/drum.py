"""The rotating drum: a slice of a long drum turning in the rolling regime, and what is measured on it.

:func:`drum_case` sizes the shipped case file ``cases/drum-slice.yaml`` (``rollingdem experiments
show drum-slice``): a drum (an analytic cylinder, its axis along z, gravity along -y) filled to a
fraction of its cross-section; the bed settles and the drum turns at the angular velocity of a
Froude number Fr = omega^2 R / g. The drum is a periodic slice along its axis: no end caps, so
the angle is that of the middle of a long drum, free of the end walls' friction, which raises the
angle near the caps of a short drum (docs/studies.md, "The rotating drum"). After a spin-up angle
its measurements sample the bed's cross-section: the free surface's angle (a line through the
surface in the middle third of its chord) and the angle of the bed's centre of mass
(``rollingdem.DrumAngle``), the driving torque (``rollingdem.WallLoad``), the flowing layer's
depth and the passive zone's speed against the drum's (``rollingdem.DrumFlow``). :func:`drum_run`
runs it as ``rollingdem run`` does.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rollingdem.analysis.intervals import confidence_interval
from rollingdem.errors import ParameterError
from rollingdem.experiments.case_file import run_case_data
from rollingdem.experiments.pile import PileMaterial
from rollingdem.experiments.registry import UNBOUNDED, BedExperiment, Parameter, granular_parameters, resolve_rolling
from rollingdem.experiments.repose import SharedSettling
from rollingdem.experiments.results import Check, ValidationResult, mean_ci, pyplot, rises, run_points
from rollingdem.experiments.single_sphere import RADIUS
from rollingdem.io.mapping_file import read_mapping

BLOCKS = 4  # the samples' blocks whose means give the 95 % intervals


@dataclass(frozen=True)
class DrumSetup:
    """The drum and how it turns. Lengths in mean particle diameters d: the drum's radius
    (``drum_diameters``) and the periodic slice's length along the axis (``slice_diameters``);
    ``fill``, the bed's share of the cross-section (at the bed's bulk solid fraction 0.6);
    ``froude`` = omega^2 R / g and ``gravity`` g (m/s^2); ``wall_friction`` and
    ``wall_rolling_friction``, the sliding and rolling friction of the spheres on the drum's wall
    (high, so that the bed neither slides nor rolls on it, as on a drum lined with glued grains);
    ``spin_up`` degrees of turning before the first sample and ``measure`` degrees over
    which ``samples`` samples are taken; with ``angle_within`` > 0 (deg) the measuring turn ends as
    soon as the mean surface angle is known to +- that at 95 % (``rollingdem.Known``), ``measure``
    then the longest it may last."""

    drum_diameters: float = 15.0
    slice_diameters: float = 5.0
    fill: float = 0.3
    froude: float = 5e-3
    gravity: float = 9.81
    wall_friction: float = 1.0
    wall_rolling_friction: float = 1.0
    spin_up: float = 90.0
    measure: float = 90.0
    samples: int = 20
    angle_within: float = 0.0


@dataclass
class DrumRun:
    """A drum's samples (one value per sample) and the flow pooled over them."""

    omega: float
    drum_radius: float
    slice_length: float
    particles: int
    angle: np.ndarray  # deg, surface line fit
    com_angle: np.ndarray  # deg, centre of mass
    torque: np.ndarray  # N m per m of drum length
    weight_moment: np.ndarray  # N m per m: the moment of the bed's weight about the axis
    flowing_depth: float  # m, from the profile of every sample
    passive_speed_ratio: float
    wall_layer_speed_ratio: float
    wall_time: float = math.nan
    measured_turn: float = math.nan  # deg turned from the window's start to the last sample
    settle_seconds_saved: float = 0.0  # wall time of a shared settling the run started from


SHIPPED = Path(__file__).parent / "cases" / "drum-slice.yaml"
"""The drum's case file (``rollingdem experiments show drum-slice``): what :func:`drum_case` sizes."""


def drum_case(rolling="epsd", twisting="none", material: PileMaterial = PileMaterial(), setup: DrumSetup = DrumSetup(),
              radius: float = RADIUS, polydispersity: float = 0.2, seed: int = 1, dt: float | None = None) -> dict:
    """The shipped drum-slice case file, sized and turned as ``setup`` says.

    Spheres of radius uniform in ``radius`` (1 +- ``polydispersity``) of ``material`` fill
    ``setup.fill`` of a drum of ``setup.drum_diameters`` d radius (at a bulk solid fraction of 0.6),
    a periodic slice ``setup.slice_diameters`` d long; they fall across the drum and settle for as
    long again, plus 0.2 s. The drum turns about +z (its bottom moves towards +x); after
    ``setup.spin_up`` degrees its measurements take ``setup.samples`` samples over ``setup.measure``
    degrees."""
    for what, value, kind in (("material", material, PileMaterial), ("setup", setup, DrumSetup)):
        if not isinstance(value, kind):
            raise ParameterError(f"{what} = {value!r} is not allowed: must be a rollingdem.experiments.drum.{kind.__name__}")
    d = 2.0 * radius
    big_r = setup.drum_diameters * d
    length = setup.slice_diameters * d
    g = setup.gravity
    omega = math.sqrt(setup.froude * g / big_r)
    r_max = radius * (1.0 + polydispersity)
    # solid volume of the bed: fill x cross-section x length at solid fraction 0.6;
    # <r^3> = R^3 (1 + p^2) for radii uniform in R (1 +- p)
    count = int(round(setup.fill * math.pi * big_r ** 2 * length * 0.6
                      / (4.0 / 3.0 * math.pi * radius ** 3 * (1.0 + polydispersity ** 2))))
    data, _ = read_mapping(SHIPPED)
    data["dt"] = dt
    data["gravity"] = [0.0, -g, 0.0]
    data["materials"] = [material.as_material("beads").to_dict(), material.wall_material("lining").to_dict()]
    data["pairs"] = [{"materials": ["beads", "lining"], "friction": setup.wall_friction,
                      "rolling_friction": setup.wall_rolling_friction}]
    if material.cohesion != "none":  # cohesive spheres, not cohesive to the drum
        data["pairs"][0].update(surface_energy=0.0, cohesion_energy_density=0.0)
    data["contact"] = {"normal": "hertz", "rolling": rolling, "twisting": twisting, "cohesion": material.cohesion}
    data["periodic"] = {"z": [0.0, length]}
    data["walls"][0]["radius"] = big_r
    insert = data["particles"][0]
    insert.update(insert={"type": "cylinder", "radius": big_r - r_max, "z_min": r_max, "z_max": length - r_max},
                  count=count, seed=seed,
                  radius={"distribution": "uniform", "low": radius * (1.0 - polydispersity), "high": r_max}
                  if polydispersity else radius)
    settle = 2.0 * math.sqrt(4.0 * big_r / g) + 0.2  # fall across the drum, then as long again to settle
    spin_up, measure = math.radians(setup.spin_up) / omega, math.radians(setup.measure) / omega
    window = [settle + spin_up, settle + spin_up + measure]
    for m in data["measurements"]:
        m.update(interval=measure / setup.samples, window=window)
    flow = next(m for m in data["measurements"] if m["type"] == "drum_flow")
    flow["radius"] = big_r
    settling, turning, measuring = data["stages"]
    settling["duration"], turning["duration"], measuring["duration"] = settle, spin_up, measure
    if setup.angle_within > 0:
        del measuring["duration"]
        measuring.update(until={"measurement": "bed.angle", "known_within": setup.angle_within, "every": measure
                                / setup.samples}, max_duration=measure)
    turning["wall_motion"][0]["rotate"]["angular_velocity"] = omega
    return data


def drum_run(rolling="epsd", twisting="none", material: PileMaterial = PileMaterial(), setup: DrumSetup = DrumSetup(),
             radius: float = RADIUS, polydispersity: float = 0.2, seed: int = 1, dt: float | None = None,
             shared: tuple | None = None) -> DrumRun:
    """The case of :func:`drum_case`, run as ``rollingdem run`` runs it (in a folder removed
    afterwards), and read: each sample's angles, driving torque and weight moment per metre of
    drum, and the flow pooled over the samples. With ``shared`` = (a folder, a reference
    ``PileMaterial``), the bed settles once per reference material, kept in the folder, and every
    run starts turning it with its own material (``run_case_data``)."""
    tic = time.perf_counter()

    def case(m: PileMaterial) -> dict:  # numbers, not pictures: a 10 d drum spent 9 s of 22 writing those
        data = drum_case(rolling, twisting, m, setup, radius, polydispersity, seed, dt)
        data["output"] = {**data["output"], "snapshots": None, "report": None, "plot": False}
        return data

    data = case(material)
    omega = data["stages"][1]["wall_motion"][0]["rotate"]["angular_velocity"]
    if shared is not None:
        folder, reference = shared
        shared = (folder, case(reference))
    summary, read = run_case_data(data, ("bed", "drive"), "drum", shared)
    t0, t1 = data["measurements"][0]["window"]
    rows = {k: v[(v["time"] >= t0 - 1e-9) & (v["time"] <= t1 + 1e-9)] for k, v in read.items()}
    length = data["periodic"]["z"][1]
    flow = summary["measurements"]["flow"]
    return DrumRun(data["stages"][1]["wall_motion"][0]["rotate"]["angular_velocity"], data["walls"][0]["radius"],
                   length, int(data["particles"][0]["count"]), rows["bed"]["angle"].to_numpy(),
                   rows["bed"]["com_angle"].to_numpy(), -rows["drive"]["tz"].to_numpy() / length,
                   rows["bed"]["weight_moment"].to_numpy() / length, flow["flowing_depth"]["value"],
                   flow["passive_speed_ratio"]["value"], flow["wall_layer_speed_ratio"]["value"],
                   time.perf_counter() - tic, math.degrees(omega * (float(rows["bed"]["time"].max()) - t0)),
                   (summary.get("prepared") or {}).get("seconds_saved", 0.0))


class RotatingDrum(SharedSettling, BedExperiment):
    """A periodic slice of a drum turning in the rolling regime (docs/studies.md, "The rotating drum")."""

    name = "rotating-drum"
    description = "a periodic slice of a drum turning in the rolling regime: the case file drum-slice, sized (docs/studies.md)"
    parameters = (granular_parameters()
                  + (Parameter("drum_diameters", 15.0, "drum radius in mean sphere diameters", low=4.0),
                     Parameter("slice_diameters", 5.0, "length of the periodic slice along the axis, in mean "
                                                       "diameters", low=2.0),
                     Parameter("fill", 0.3, "the bed's share of the drum's cross-section (at solid fraction 0.6)",
                               low=0.05, high=0.6),
                     Parameter("froude", 5e-3, "Froude number omega^2 R / g (rolling regime: 1e-4 to 1e-2)", low=0.0,
                               low_open=True, high=1.0),
                     Parameter("gravity", 9.81, "gravitational acceleration g", "m/s^2", low=0.0, low_open=True),
                     Parameter("wall_friction", 1.0, "sliding friction of the spheres on the drum wall", low=0.0),
                     Parameter("wall_rolling_friction", 1.0, "rolling friction of the spheres on the drum wall",
                               low=0.0),
                     Parameter("spin_up", 90.0, "drum rotation before the first sample", "deg", low=0.0),
                     Parameter("measure", 90.0, "drum rotation over which the samples are taken", "deg", low=0.0,
                               low_open=True),
                     Parameter("samples", 20, "samples of the bed over the measuring turn", low=4, integer=True),
                     Parameter("angle_within", 0.0, "end the measuring turn once the mean surface angle is known to "
                                                    "+- this at 95 % (batch means; 0: measure the whole turn)", "deg",
                               low=0.0)))
    observables = {
        "angle": "deg, dynamic angle of repose: line fit of the free surface's middle third (mean over samples)",
        "angle_ci": "deg, 95 % Student-t half-width over blocks of samples",
        "angle_std": "deg, fluctuation of the angle from sample to sample",
        "com_angle": "deg, angle of the bed's centre of mass from below the axis",
        "torque": "N m/m, driving torque per metre of drum length",
        "flowing_depth": "m, depth at the chord's middle where the downslope speed falls to zero",
        "passive_speed_ratio": "speed of the passive zone over omega r (1: solid-body rotation)",
        "wall_layer_speed_ratio": "speed of the spheres touching the wall, below the flowing layer, over omega r",
        "omega": "rad/s, the drum's angular velocity", "particles": "spheres in the slice",
        "measured_turn": "deg, drum rotation from the first sample's window to the last sample",
        "settle_seconds_saved": "s, wall time of the shared settled bed the run started from (share_settling)"}
    default_observable = "angle"
    targets = {"angle": (0.0, 90.0), "com_angle": (0.0, 90.0), "torque": UNBOUNDED, "flowing_depth": UNBOUNDED}
    #: the cheap runs of a multi-fidelity calibration: a drum of 10 diameters instead of 15, with
    #: (10/15)^2 of the spheres turning the same angles in (10/15)^0.5 of the time at the same Froude number
    cheap = {"drum_diameters": 10.0}
    #: what ``validate`` changes of the defaults: a quick run takes fewer samples over less rotation
    sizes = {"quick": {"samples": 12, "spin_up": 60.0, "measure": 60.0}, "full": {}}

    def drum_arguments(self, params: dict) -> dict:
        """The arguments of :func:`drum_case` and :func:`drum_run` for ``params``."""
        p = self.resolve(params)
        setup = DrumSetup(drum_diameters=p["drum_diameters"], slice_diameters=p["slice_diameters"], fill=p["fill"],
                          froude=p["froude"], gravity=p["gravity"], wall_friction=p["wall_friction"],
                          wall_rolling_friction=p["wall_rolling_friction"],
                          spin_up=p["spin_up"], measure=p["measure"], samples=p["samples"],
                          angle_within=p["angle_within"])
        return dict(rolling=resolve_rolling(p["model"]), twisting=p["twisting"],
                    material=PileMaterial.from_parameters(p), setup=setup, radius=p["radius"],
                    polydispersity=p["polydispersity"], seed=p["seed"], dt=p["dt"])

    def observe(self, params: dict) -> dict:
        """A periodic slice of a drum turning in the rolling regime: its dynamic angle and the rest."""
        run = drum_run(**self.drum_arguments(params), shared=self.reference_material(params))
        # successive samples are correlated: the 95 % interval is over the means of BLOCKS blocks
        blocks = [b.mean() for b in np.array_split(run.angle, min(BLOCKS, len(run.angle)))]
        return {"angle": float(run.angle.mean()), "angle_ci": confidence_interval(blocks)[1],
                "angle_std": float(run.angle.std(ddof=1)) if len(run.angle) > 1 else math.nan,
                "com_angle": float(run.com_angle.mean()), "torque": float(run.torque.mean()),
                "flowing_depth": run.flowing_depth, "passive_speed_ratio": run.passive_speed_ratio,
                "wall_layer_speed_ratio": run.wall_layer_speed_ratio,
                "omega": run.omega, "particles": run.particles, "measured_turn": run.measured_turn,
                "settle_seconds_saved": run.settle_seconds_saved}

    def validate(self, quick=False, outdir=None, progress=None, runner=map, model="epsd") -> ValidationResult:
        """The drum at mu_r = 0.05, 0.2, 0.4 (mu = 0.5) and mu = 0.3, 0.5, 0.8 (mu_r = 0.2), and at the
        base point with g four times larger at the same Froude number; 1 seed quick (a shorter run), 3
        full. Checks: the angle rises with mu_r and with mu; at one Froude number the angle does not
        change with g (within the 95 % interval of the difference); below the flowing layer, in the
        middle third of the arc along which the bed touches the wall, the spheres touching the wall
        move at omega r within 2 %."""
        tic = time.perf_counter()
        base = {"model": model, "mu": 0.5, "mur": 0.2, "gravity": 9.81, **self.sizes["quick" if quick else "full"]}
        points = [dict(base, mur=m) for m in (0.05, 0.2, 0.4)] + [dict(base, mu=m) for m in (0.3, 0.8)]
        points.append(dict(base, gravity=4 * 9.81))
        seeds = [1] if quick else [1, 2, 3]
        runs = run_points(self, points, seeds, runner, progress)
        keys = ["mu", "mur", "gravity"]
        table = mean_ci(runs, keys, "angle", within="angle_ci")
        for col in ("com_angle", "torque", "flowing_depth", "passive_speed_ratio", "wall_layer_speed_ratio", "omega"):
            table[col] = runs.groupby(keys, sort=True)[col].mean().to_numpy()
        g0 = table[np.isclose(table["gravity"], 9.81)]
        checks = [rises("rotating-drum", model, g0, "mur", {"mu": 0.5}),
                  rises("rotating-drum", model, g0, "mu", {"mur": 0.2})]
        at = table[np.isclose(table["mu"], 0.5) & np.isclose(table["mur"], 0.2)].set_index("gravity")
        low, high = at.loc[at.index.min()], at.loc[at.index.max()]
        checks.append(Check("rotating-drum", model, "angle(4 g) - angle(g) at the same Froude number (deg)",
                            high["angle mean"] - low["angle mean"], 0.0,
                            math.hypot(high["angle 95% CI"], low["angle 95% CI"]), relative=False,
                            source="Froude scaling: in the rolling regime the angle depends on g only through Fr; "
                                   "tolerance: the 95 % interval of the difference"))
        checks.append(Check("rotating-drum", model, "wall layer's speed / omega r below the flowing layer, middle third "
                            "of the arc", low["wall_layer_speed_ratio"], 1.0, 0.02,
                            source="the passive zone turns with the drum where it touches the wall (off the arc's ends "
                                   "and the wall, the thin bed creeps: docs/studies.md)"))
        result = ValidationResult("rotating-drum", f"Rotating drum ({model}, {len(seeds)} seed{'s' * (len(seeds) > 1)}"
                            f"{', quick' if quick else ''})", table, checks,
                            notes=[f"A periodic slice of a drum 15 d in radius, 30 % full, at Fr = 5e-3 "
                                   f"({int(runs['particles'].iloc[0])} spheres, R = 5 mm ± 20 %, E = 5 MPa); the angle "
                                   "is the line fit of the free surface's middle third, its interval over seeds (one "
                                   "seed: over blocks of samples). docs/studies.md, \"The rotating drum\"."])
        if outdir is not None:
            plt = pyplot()
            fig, axes = plt.subplots(1, 2, figsize=(10, 4))
            for ax, key, fixed in ((axes[0], "mur", ("mu", 0.5)), (axes[1], "mu", ("mur", 0.2))):
                ax.set_prop_cycle(color=plt.get_cmap("tab10").colors)
                sel = g0[np.isclose(g0[fixed[0]], fixed[1])].sort_values(key)
                ax.errorbar(sel[key], sel["angle mean"], yerr=sel["angle 95% CI"], fmt="o-", capsize=3, label="surface")
                ax.plot(sel[key], sel["com_angle"], "s--", label="centre of mass")
                ax.set_xlabel(key)
                ax.set_ylabel("dynamic angle of repose (deg)")
                ax.set_title(f"{fixed[0]} = {fixed[1]}")
                ax.legend(fontsize=8)
            result.add_figure(fig, outdir, "rotating_drum.png")
        result.wall_time = time.perf_counter() - tic
        return result
