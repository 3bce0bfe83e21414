"""Cases as functions ``run(params) -> observables``: what sweeps and calibration call.

Each case (``rolling-flat``, ``inclined-wall``, ``angle-of-repose``) takes a flat mapping of named
parameters, each with a default, a check and, where calibration may vary it, a default range, and
returns a flat mapping of named observables. The cases, their observables and their theory:
docs/studies.md, "Cases as functions of parameters"."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from rollingdem.errors import ParameterError, check_choice, check_finite

__all__ = ["CASES", "SweepCase", "Parameter", "get_case", "resolve_rolling"]


@dataclass(frozen=True)
class Parameter:
    """A named case parameter: default, allowed interval (``low``/``high``, open or closed) or
    choices, unit, and the range calibration searches by default."""

    name: str
    default: Any
    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    integer: bool = False
    choice: str = ""  # "rolling", "twisting" or "cohesion": a model name
    calibration_range: tuple[float, float] | None = None

    def check(self, value: Any) -> Any:
        """The value as the case uses it, or ParameterError naming the parameter and what is allowed."""
        if self.choice:
            if not isinstance(value, str):
                raise ParameterError(f"{self.name} = {value!r} is not allowed: must be a {self.choice} model name")
            if self.choice == "rolling":
                resolve_rolling(value, self.name)
            else:
                from rollingdem.physics.contact.base import _REGISTRIES, make_submodel

                check_choice(self.name, value, _REGISTRIES[self.choice])
                try:
                    make_submodel(self.choice, value)
                except ParameterError as err:  # a model that needs parameters of its own (sds)
                    raise ParameterError(f"{self.name} = {value!r} is not allowed: {err}") from None
            return value
        if self.integer:
            if isinstance(value, bool) or not isinstance(value, (int, float)) or float(value) != int(value):
                raise ParameterError(f"{self.name} = {value!r} is not allowed: must be an integer")
            value = int(value)
        else:
            if isinstance(value, bool):
                raise ParameterError(f"{self.name} = {value!r} is not a number")
            value = check_finite(self.name, value)
        bad_low = self.low is not None and (value <= self.low if self.low_open else value < self.low)
        bad_high = self.high is not None and value > self.high
        if bad_low or bad_high:
            lo = "-inf" if self.low is None else f"{self.low:g}"
            hi = "inf" if self.high is None else f"{self.high:g}"
            unit = f" {self.unit}" if self.unit else ""
            raise ParameterError(f"{self.name} = {value!r} is not allowed: must lie in "
                                 f"{'(' if self.low_open or self.low is None else '['}{lo}, {hi}"
                                 f"{']' if self.high is not None else ')'}{unit}")
        return value


@dataclass(frozen=True)
class SweepCase:
    """A case as a function of named parameters: ``run(params) -> {observable: value}``."""

    name: str
    run: Callable[[dict], dict]
    parameters: tuple[Parameter, ...]
    observables: dict[str, str]  # name -> unit and meaning
    default_observable: str
    stochastic: bool  # does the seed change the result?
    description: str = ""
    targets: dict = field(default_factory=dict)  # observable -> (low, high) it can reach: what calibration may match
    by_name: dict = field(default=None, compare=False, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "by_name", {p.name: p for p in self.parameters})

    def resolve(self, params: dict) -> dict:
        """Defaults filled in and every value checked; unknown names refused."""
        unknown = [k for k in params if k not in self.by_name]
        if unknown:
            raise ParameterError(f"parameter = {unknown[0]!r} is not known for case {self.name!r}: allowed are "
                                 f"{', '.join(self.by_name)}")
        return {p.name: p.check(params[p.name]) if p.name in params else p.default for p in self.parameters}


def resolve_rolling(name: str, what: str = "model"):
    """A rolling model by name: a key of ``rollingdem.physics.contact.ROLLING_MODELS`` ("epsd", "cdt", ...)
    or a label of the validation tables ("epsd (liggghts)", "cdt (limiter 0.08)", ...)."""
    from rollingdem.physics.contact import ROLLING_MODELS
    from rollingdem.experiments.single_sphere import validation_models

    labels = validation_models()
    if name in labels:
        return labels[name]
    check_choice(what, name, set(ROLLING_MODELS) | set(labels))
    return name


def _material(p: dict) -> dict:
    return {"friction": p["mu"], "rolling_friction": p["mur"], "rolling_damping": p["eta_r"], "restitution": p["e"]}


# --- rolling-flat ----------------------------------------------------------------------------------
def rolling_flat(params: dict) -> dict:
    """Case 1 as a function: stop distance (m) and time (s) of a sphere launched at v0."""
    from rollingdem.experiments.single_sphere import analytic_flat, rolling_flat_run, stop_time

    p = CASES["rolling-flat"].resolve(params)
    # record until 1.3x the analytic stop (at least 0.3 s after it): the sphere must be seen to stop
    t_stop = analytic_flat(p["v0"], p["mu"], p["mur"])[2]
    traj = rolling_flat_run(resolve_rolling(p["model"]), duration=1.3 * t_stop + 0.3, v0=p["v0"],
                            material=_material(p))
    return {"distance": float(traj.x[-1]), "stop_time": stop_time(traj)}


# --- inclined-wall ---------------------------------------------------------------------------------
def inclined_wall(params: dict) -> dict:
    """The inclination (deg) at which the sphere starts to roll, by bisection over beta in
    [beta_low, beta_high] to a relative width ``rel_tol`` in tan(beta); NaN when it holds at
    beta_high or rolls at beta_low."""
    from rollingdem.experiments.single_sphere import rolling_threshold_speed, speed_down_incline

    p = CASES["inclined-wall"].resolve(params)
    if p["beta_low"] >= p["beta_high"]:
        raise ParameterError(f"beta_low = {p['beta_low']} is not allowed: must be below beta_high = {p['beta_high']}")
    model, material = resolve_rolling(p["model"]), _material(p)

    def rolls(beta):
        # the threshold of a quarter of rel_tol above critical keeps the classification bias below the bracket
        return (speed_down_incline(model, p["mur"], beta, material=material)
                > rolling_threshold_speed(beta, 0.25 * p["rel_tol"]))

    lo, hi = p["beta_low"], p["beta_high"]
    if rolls(lo) or not rolls(hi):
        return {"critical_angle": math.nan}
    while math.tan(math.radians(hi)) - math.tan(math.radians(lo)) > p["rel_tol"] * math.tan(math.radians(lo)):
        mid = 0.5 * (lo + hi)
        if rolls(mid):
            hi = mid
        else:
            lo = mid
    return {"critical_angle": 0.5 * (lo + hi)}


# --- angle-of-repose -------------------------------------------------------------------------------
def angle_of_repose(params: dict) -> dict:
    """A pile from a lifted tube and its measured angle (NaN with a note when it cannot be fitted)."""
    from rollingdem.experiments.repose import Collapse, PileSetup, pile_run

    p = CASES["angle-of-repose"].resolve(params)
    material = _pile_material(p)
    collapse = Collapse(max_time=p["max_collapse"], sample=0.02, lift_speed=p["lift_speed"] or None)
    run = pile_run(resolve_rolling(p["model"]), p["twisting"], count=p["count"], seed=p["seed"], material=material,
                   collapse=collapse, polydispersity=p["polydispersity"], dt=p["dt"],
                   setup=PileSetup(base="rough" if p["rough_base"] else "plate"))
    a = run.angle
    return {"angle": a.angle if a else math.nan, "slice_std": a.slice_std if a else math.nan,
            "r_squared": a.r_squared if a else math.nan, "settled_at": run.settled_at,
            "note": run.angle_error[:200]}


# --- rotating-drum ---------------------------------------------------------------------------------
def rotating_drum(params: dict) -> dict:
    """A periodic slice of a drum turning in the rolling regime: its dynamic angle and the rest."""
    from rollingdem.analysis.intervals import confidence_interval
    from rollingdem.experiments.drum import BLOCKS, DrumSetup, drum_run

    p = CASES["rotating-drum"].resolve(params)
    material = _pile_material(p)
    setup = DrumSetup(drum_diameters=p["drum_diameters"], slice_diameters=p["slice_diameters"], fill=p["fill"],
                      froude=p["froude"], gravity=p["gravity"], wall_friction=p["wall_friction"],
                      wall_rolling_friction=p["wall_rolling_friction"],
                      spin_up=p["spin_up"], measure=p["measure"], samples=p["samples"])
    run = drum_run(resolve_rolling(p["model"]), p["twisting"], material, setup, radius=p["radius"],
                   polydispersity=p["polydispersity"], seed=p["seed"], dt=p["dt"])
    # successive samples are correlated: the 95 % interval is over the means of BLOCKS blocks
    blocks = [b.mean() for b in np.array_split(run.angle, min(BLOCKS, len(run.angle)))]
    return {"angle": float(run.angle.mean()), "angle_ci": confidence_interval(blocks)[1],
            "angle_std": float(run.angle.std(ddof=1)) if len(run.angle) > 1 else math.nan,
            "com_angle": float(run.com_angle.mean()), "torque": float(run.torque.mean()),
            "flowing_depth": run.flowing_depth, "passive_speed_ratio": run.passive_speed_ratio,
            "wall_layer_speed_ratio": run.wall_layer_speed_ratio,
            "omega": run.omega, "particles": run.particles}


# --- silo-discharge --------------------------------------------------------------------------------
def silo_discharge(params: dict) -> dict:
    """A flat-bottomed silo discharging at a steady head: the mass flow rate and the rest."""
    from rollingdem.experiments.silo import BLOCKS, SiloSetup, discharge_rate, silo_run

    p = CASES["silo-discharge"].resolve(params)
    material = _pile_material(p)
    setup = SiloSetup(orifice_diameters=p["orifice_diameters"], silo_diameters=p["silo_diameters"] or None,
                      fill_diameters=p["fill_diameters"] or None, gravity=p["gravity"], transient=p["transient"],
                      measured=p["measured"], max_time=p["max_time"], clog_time=p["clog_time"])
    run = silo_run(resolve_rolling(p["model"]), p["twisting"], material, setup, radius=p["radius"],
                   polydispersity=p["polydispersity"], seed=p["seed"], dt=p["dt"])
    lo, hi = run.window
    w, half = discharge_rate(run.t, run.discharged, run.window, blocks=BLOCKS)
    return {"flow_rate": w, "flow_rate_ci": half,
            "flow_rate_first": discharge_rate(run.t, run.discharged, (lo, 0.5 * (lo + hi)))[0],
            "flow_rate_second": discharge_rate(run.t, run.discharged, (0.5 * (lo + hi), hi))[0],
            "bulk_density": run.bulk_density, "orifice_density": run.orifice_density, "clogged": int(run.clogged),
            "orifice": run.orifice, "particles": run.particles}


# --- repose-rough-base -----------------------------------------------------------------------------
def repose_rough_base(params: dict) -> dict:
    """The lifted-cylinder pile on a rough base of fixed spheres, every protocol choice a parameter."""
    from rollingdem.experiments.repose import Collapse, PileSetup, pile_run

    p = CASES["repose-rough-base"].resolve(params)
    material = _pile_material(p)
    base_radius = p["base_radius"] or p["radius"]
    setup = PileSetup(base="rough", radius=p["radius"], tube_radius=p["tube_radius"] or None,
                      base_radius=base_radius, base_spacing=p["base_spacing"] * base_radius,
                      base_jitter=p["base_jitter"] * base_radius, clearance=2.0 * p["radius"] * p["clearance"])
    collapse = Collapse(max_time=p["max_collapse"], sample=0.02, lift_speed=p["lift_speed"] or None)
    run = pile_run(resolve_rolling(p["model"]), p["twisting"], count=p["count"], seed=p["seed"], material=material,
                   collapse=collapse, polydispersity=p["polydispersity"], dt=p["dt"], setup=setup)
    a = run.angle
    return {"angle": a.angle if a else math.nan, "slice_std": a.slice_std if a else math.nan,
            "r_squared": a.r_squared if a else math.nan, "settled_at": run.settled_at,
            "note": run.angle_error[:200]}


def _common(mu=0.8, mur=0.2, mur_range=(0.02, 1.0), mur_low_open=False):
    return (Parameter("model", "epsd", "rolling resistance model (rollingdem.physics.contact.ROLLING_MODELS or a "
                                       "validation label such as 'epsd (liggghts)')", choice="rolling"),
            Parameter("mu", mu, "sliding friction coefficient", low=0.0, low_open=True, calibration_range=(0.1, 1.0)),
            Parameter("mur", mur, "rolling friction coefficient", low=0.0, low_open=mur_low_open,
                      calibration_range=mur_range),
            Parameter("eta_r", 0.3, "rolling viscous damping ratio", low=0.0, high=1.0, calibration_range=(0.0, 1.0)),
            Parameter("e", 0.5, "coefficient of restitution", low=0.0, high=1.0, low_open=True,
                      calibration_range=(0.1, 0.9)),
            Parameter("seed", 1, "random seed (insertion)", low=0, integer=True))


def _cohesion():
    """The cohesion law and its two material parameters (docs/models.md §1.6), which calibration can
    fit as it fits mu_r."""
    return (Parameter("cohesion", "none", "cohesion law (rollingdem.physics.contact.COHESION_MODELS): none, sjkr, jkr",
                      choice="cohesion"),
            Parameter("surface_energy", 0.0, "work of adhesion w of the spheres (cohesion jkr)", "J/m^2", low=0.0,
                      calibration_range=(0.0, 0.5)),
            Parameter("cohesion_energy_density", 0.0, "cohesion energy density k_c of the spheres (cohesion sjkr)",
                      "J/m^3", low=0.0, calibration_range=(0.0, 2e5)))


def _granular():
    """The parameters of an experiment with a bed of spheres: _common's, the twisting model, the
    spheres' size and stiffness, the time step."""
    return (_common(mu=0.5, mur=0.2, mur_range=(0.0, 0.6))
            + (Parameter("twisting", "none", "twisting model (rollingdem.physics.contact.TWISTING_MODELS)", choice="twisting"),
               Parameter("radius", 0.005, "mean sphere radius R", "m", low=0.0, low_open=True),
               Parameter("polydispersity", 0.2, "radii uniform in R (1 +- p)", low=0.0, high=0.9),
               Parameter("youngs_modulus", 5e6, "Young's modulus", "Pa", low=0.0, low_open=True),
               Parameter("dt", 2.5e-5, "time step", "s", low=0.0, low_open=True))
            + _cohesion())


def _pile_material(p: dict):
    """The spheres' material of an experiment's parameters (Table 1's Poisson ratio and density
    unless given)."""
    from rollingdem.experiments.repose import PileMaterial

    extra = {k: p[k] for k in ("poisson_ratio", "density", "cohesion", "surface_energy", "cohesion_energy_density")
             if k in p}
    return PileMaterial(friction=p["mu"], rolling_friction=p["mur"], youngs_modulus=p["youngs_modulus"],
                        restitution=p["e"], rolling_damping=p["eta_r"], **extra)


CASES: dict[str, SweepCase] = {
    "rolling-flat": SweepCase(
        "rolling-flat", rolling_flat,
        _common(mur_range=(0.05, 0.6), mur_low_open=True)
        + (Parameter("v0", 1.0, "launch speed", "m/s", low=0.0, low_open=True, high=10.0),),
        {"distance": "m, from launch to rest", "stop_time": "s, first sample below 1 mm/s"}, "distance",
        stochastic=False, description="one Table-1 sphere launched at v0 on a flat (report case 1)",
        targets={"distance": (0.0, math.inf), "stop_time": (0.0, math.inf)}),
    "inclined-wall": SweepCase(
        "inclined-wall", inclined_wall,
        _common(mur_range=(0.05, 0.7), mur_low_open=True)
        + (Parameter("beta_low", 0.5, "lower end of the bisection bracket", "deg", low=0.0, low_open=True, high=89.0),
           Parameter("beta_high", 45.0, "upper end of the bisection bracket", "deg", low=0.0, low_open=True,
                     high=89.0),
           Parameter("rel_tol", 2e-3, "bisection width, relative in tan(beta)", low=1e-5, high=0.1)),
        {"critical_angle": "deg, theory atan(mu_r)"}, "critical_angle", stochastic=False,
        description="critical inclination for a given mu_r (report case 0)", targets={"critical_angle": (0.0, 90.0)}),
    "angle-of-repose": SweepCase(
        "angle-of-repose", angle_of_repose,
        _common(mu=0.5, mur=0.2, mur_range=(0.05, 0.6))
        + (Parameter("twisting", "none", "twisting model (rollingdem.physics.contact.TWISTING_MODELS)", choice="twisting"),
           Parameter("count", 2000, "spheres", low=50, integer=True),
           Parameter("lift_speed", 0.2, "tube lift speed (0: removed at once)", "m/s", low=0.0),
           Parameter("youngs_modulus", 5e6, "Young's modulus", "Pa", low=0.0, low_open=True),
           Parameter("dt", 2.5e-5, "time step", "s", low=0.0, low_open=True),
           Parameter("max_collapse", 3.0, "longest collapse before the pile counts as unsettled", "s", low=0.0,
                     low_open=True),
           Parameter("polydispersity", 0.2, "radii uniform in R (1 +- p), R = 5 mm", low=0.0, high=0.9),
           Parameter("rough_base", 0, "1: the pile stands on a base of fixed spheres (rollingdem.rough_base) on "
                                      "the plate; 0: on the bare plate", low=0, high=1, integer=True))
        + _cohesion(),
        {"angle": "deg, cone fit (rollingdem.analysis.repose.repose_angle)", "slice_std": "deg, spread over azimuthal slices",
         "r_squared": "cone fit R²", "settled_at": "s after the tube is removed", "note": "why no angle"},
        "angle", stochastic=True,
        description="pile from a lifted tube, repose angle by cone fit (report case 3 / PFC study)",
        targets={"angle": (0.0, 90.0)}),
    "rotating-drum": SweepCase(
        "rotating-drum", rotating_drum,
        _granular()
        + (Parameter("drum_diameters", 15.0, "drum radius in mean sphere diameters", low=4.0),
           Parameter("slice_diameters", 5.0, "length of the periodic slice along the axis, in mean diameters",
                     low=2.0),
           Parameter("fill", 0.3, "the bed's share of the drum's cross-section (at solid fraction 0.6)", low=0.05,
                     high=0.6),
           Parameter("froude", 5e-3, "Froude number omega^2 R / g (rolling regime: 1e-4 to 1e-2)", low=0.0,
                     low_open=True, high=1.0),
           Parameter("gravity", 9.81, "gravitational acceleration g", "m/s^2", low=0.0, low_open=True),
           Parameter("wall_friction", 1.0, "sliding friction of the spheres on the drum wall", low=0.0),
           Parameter("wall_rolling_friction", 1.0, "rolling friction of the spheres on the drum wall", low=0.0),
           Parameter("spin_up", 90.0, "drum rotation before the first sample", "deg", low=0.0),
           Parameter("measure", 90.0, "drum rotation over which the samples are taken", "deg", low=0.0,
                     low_open=True),
           Parameter("samples", 20, "samples of the bed", low=4, integer=True)),
        {"angle": "deg, dynamic angle of repose: line fit of the free surface's middle third (mean over samples)",
         "angle_ci": "deg, 95 % Student-t half-width over blocks of samples",
         "angle_std": "deg, fluctuation of the angle from sample to sample",
         "com_angle": "deg, angle of the bed's centre of mass from below the axis",
         "torque": "N m/m, driving torque per metre of drum length",
         "flowing_depth": "m, depth at the chord's middle where the downslope speed falls to zero",
         "passive_speed_ratio": "speed of the passive zone over omega r (1: solid-body rotation)",
         "wall_layer_speed_ratio": "speed of the spheres touching the wall, below the flowing layer, over omega r",
         "omega": "rad/s, the drum's angular velocity", "particles": "spheres in the slice"},
        "angle", stochastic=True,
        description="a periodic slice of a drum turning in the rolling regime (docs/studies.md)",
        targets={"angle": (0.0, 90.0), "com_angle": (0.0, 90.0), "torque": (0.0, math.inf),
                 "flowing_depth": (0.0, math.inf)}),
    "silo-discharge": SweepCase(
        "silo-discharge", silo_discharge,
        _granular()
        + (Parameter("orifice_diameters", 6.0, "orifice diameter D0 in mean sphere diameters d", low=1.0),
           Parameter("silo_diameters", 0.0, "silo diameter in d (0: max(2.5 D0, D0 + 30 d))", low=0.0),
           Parameter("fill_diameters", 0.0, "settled fill height in d, held during the discharge (0: 20 d, at "
                                            "least 2 D0)", low=0.0),
           Parameter("gravity", 9.81, "gravitational acceleration g", "m/s^2", low=0.0, low_open=True),
           Parameter("transient", 200, "spheres out after the opening before W is measured", low=0, integer=True),
           Parameter("measured", 1000, "spheres out over which W is measured", low=10, integer=True),
           Parameter("max_time", 60.0, "longest discharge", "s", low=0.0, low_open=True),
           Parameter("clog_time", 1.0, "time without a particle out that counts as clogged", "s", low=0.0,
                     low_open=True)),
        {"flow_rate": "kg/s, steady mass flow rate W: slope of the discharged mass over the measured spheres",
         "flow_rate_ci": "kg/s, 95 % Student-t half-width over 5 sub-windows",
         "flow_rate_first": "kg/s, W over the first half of the measured spheres",
         "flow_rate_second": "kg/s, W over the second half",
         "bulk_density": "kg/m^3, of the settled bed before the orifice opens",
         "orifice_density": "kg/m^3, in the cylinder D0 wide and D0/2 high above the orifice, while W is measured",
         "clogged": "1 when the orifice clogged", "orifice": "m, the orifice diameter D0",
         "particles": "spheres in the silo"},
        "flow_rate", stochastic=True,
        description="a flat-bottomed silo discharging through a circular orifice at a steady head (docs/studies.md)",
        targets={"flow_rate": (0.0, math.inf), "bulk_density": (0.0, math.inf)}),
    "repose-rough-base": SweepCase(
        "repose-rough-base", repose_rough_base,
        _common(mu=0.6, mur=0.1, mur_range=(0.0, 0.6))
        + (Parameter("twisting", "none", "twisting model (rollingdem.physics.contact.TWISTING_MODELS)", choice="twisting"),
           Parameter("count", 2000, "spheres in the column", low=50, integer=True),
           Parameter("radius", 0.005, "mean sphere radius R", "m", low=0.0, low_open=True),
           Parameter("polydispersity", 0.2, "radii uniform in R (1 +- p)", low=0.0, high=0.9),
           Parameter("tube_radius", 0.0, "cylinder radius (0: sized so that the column is one diameter high at "
                                         "solid fraction 0.6; 6 d for 2,000 spheres)", "m", low=0.0),
           Parameter("lift_speed", 0.1, "cylinder lift speed (0: removed at once)", "m/s", low=0.0),
           Parameter("clearance", 1.0, "how far the lifted cylinder's lower edge rises above the column's top "
                                       "before it is removed, in mean diameters", low=0.0),
           Parameter("base_radius", 0.0, "radius of the base's fixed spheres (0: R)", "m", low=0.0),
           Parameter("base_spacing", 2.2, "spacing of the base's spheres, in base radii", low=2.0),
           Parameter("base_jitter", 0.1, "random shift of each base sphere in the plane, at most, in base radii",
                     low=0.0),
           Parameter("youngs_modulus", 5e6, "Young's modulus", "Pa", low=0.0, low_open=True),
           Parameter("poisson_ratio", 0.49, "Poisson's ratio", low=0.0, high=0.5),
           Parameter("density", 1056.0, "particle density", "kg/m^3", low=0.0, low_open=True),
           Parameter("dt", 2.5e-5, "time step", "s", low=0.0, low_open=True),
           Parameter("max_collapse", 3.0, "longest collapse before the pile counts as unsettled", "s", low=0.0,
                     low_open=True))
        + _cohesion(),
        {"angle": "deg, cone fit (rollingdem.analysis.repose.repose_angle)", "slice_std": "deg, spread over azimuthal slices",
         "r_squared": "cone fit R²", "settled_at": "s after the cylinder starts to lift", "note": "why no angle"},
        "angle", stochastic=True,
        description="the lifted-cylinder pile on a rough base of fixed spheres (PFC and LIGGGHTS protocol)",
        targets={"angle": (0.0, 90.0)}),
}


def get_case(name: str) -> SweepCase:
    """The sweepable case ``name``, or ParameterError listing the known ones."""
    if name not in CASES:
        raise ParameterError(f"case = {name!r} is not known: allowed are {', '.join(CASES)}")
    return CASES[name]
