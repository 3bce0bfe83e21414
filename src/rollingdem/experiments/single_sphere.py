"""The seed report's single-sphere test cases 0-2 (docs/models.md §13 T2-T4), run by the package.

A sphere of the report's Table 1 material on a flat wall whose inclination is set by tilting
gravity: :func:`inclined_wall` (case 0, the critical mu_r by bisection), :func:`rolling_flat`
(case 1) and :func:`rolling_slope` (case 2, up a 10 deg slope). Settings and analytic answers:
docs/models.md §13."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numba
import numpy as np

from rollingdem.physics.contact import ROLLING_MODELS
from rollingdem.physics.contact.model import ContactModel
from rollingdem.scene.materials import Material
from rollingdem.scene.schedule import Callback
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.walls import Plane

G = 9.81
RADIUS = 0.005
TABLE1 = dict(youngs_modulus=40e6, poisson_ratio=0.49, density=1056.0, friction=0.8, rolling_friction=0.2,
              restitution=0.5, rolling_damping=0.3)
DT = 1e-5
# Zhou-type viscous coefficient c_v (s) giving a rolling decay time tau = 1.4 R / (c_v g) = 0.25 s
VISCOUS_TAU = 0.25
VISCOUS_COEFFICIENT = 1.4 * RADIUS / (VISCOUS_TAU * G)


def single_thread(func):
    """Run ``func`` on one Numba thread: for one sphere the parallel loop only adds overhead
    (150k steps: 0.64 s on one thread, 1.81 s on two)."""
    @functools.wraps(func)
    def wrapper(*args, **kwargs):
        before = numba.get_num_threads()
        numba.set_num_threads(1)
        try:
            return func(*args, **kwargs)
        finally:
            numba.set_num_threads(before)
    return wrapper


#: the settings the single-sphere experiments give a rolling model, over its own ``validation_presets``
CASE_SETTINGS = {"sds": {"rolling_stiffness": 2e3}, "displacement_damping": {"damping": 0.3},
                 "viscous": {"coefficient": VISCOUS_COEFFICIENT}}


def validation_models() -> dict:
    """Every registered rolling model by the label the validation tables use: each model's
    ``validation_presets`` (parity presets included), with ``CASE_SETTINGS``; the name itself
    where nothing is set."""
    models = {}
    for name, cls in ROLLING_MODELS.items():
        if name == "none":
            continue
        for label, settings in cls.validation_presets.items():
            settings = {**settings, **CASE_SETTINGS.get(name, {})}
            models[label] = cls(**settings) if settings else name
    return models


#: models without a static threshold (a viscous moment vanishes at rest): no critical mu_r
NO_THRESHOLD = ("viscous",)
#: models that cannot hold a sphere at rest on a slope below the threshold (docs/models.md §11.6)
CREEPING = ("cdt", "cdt (liggghts)", "cdt (limiter 0.08)", "force_proportional", "viscous")


def sphere_on_wall(rolling, settle=0.2, material=None, gravity=(0.0, 0.0, -G), wall=None, at=(0.0, 0.0)) -> Simulation:
    """One Table-1 sphere settled on a horizontal wall at z = 0 for ``settle`` seconds, at (x, y) =
    ``at``. ``wall``: the wall's surface, a function of the material's name giving a Wall whose
    top is the plane z = 0 (a ``MeshWall`` of a tessellated plane, say); default a ``Plane``."""
    sim = Simulation(contact=ContactModel("hertz", rolling=rolling), gravity=gravity, dt=DT, track_energy=True)
    sim.add_material(Material("table1", **dict(TABLE1, **(material or {}))))
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1), material="table1") if wall is None else wall("table1"))
    alpha = (material or {}).get("coarse_graining", 1.0)  # a parcel of alpha R rests at alpha R
    sim.add_particles([[at[0], at[1], alpha * RADIUS]], RADIUS, "table1")
    sim.run(settle)
    return sim


@dataclass
class Trajectory:
    """Samples of a single-sphere run after launch: time (s), x (m), v_x (m/s), total torque M_y (N m)."""

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray
    torque: np.ndarray
    rolling_dissipation: np.ndarray = field(default_factory=lambda: np.zeros(0))


def launch(sim: Simulation, duration: float, v0=1.0, sample_steps=10) -> Trajectory:
    """Give the sphere v_x = v0, omega = 0 and record x, v_x and M_y every ``sample_steps`` steps."""
    sim.set_velocities([0], velocity=(v0, 0, 0), angular_velocity=(0, 0, 0))
    x0, t0, step0 = sim.positions[0, 0], sim.time, sim.step
    n = int(round(duration / (sample_steps * sim.dt)))
    out = []

    def sample(s):
        if s.step > step0:  # not the call at the start of the run
            out.append((s.time - t0, s.positions[0, 0] - x0, s.velocities[0, 0], s.torques[0, 1],
                        s.dissipated_energy()["rolling"]))

    # one run, sampled by an observer: the step loop stops every sample_steps steps all the same, but a
    # run's own checks are made once (a run per sample cost 40 % of the experiment)
    sim.run(steps=n * sample_steps, observers=[Callback(sample, sample_steps * sim.dt)])
    out = np.array(out).reshape(-1, 5)
    return Trajectory(out[:, 0], out[:, 1], out[:, 2], out[:, 3], out[:, 4])


# --- case 1: rolling on a flat ---------------------------------------------------------------------
def analytic_flat(v0=1.0, mu=TABLE1["friction"], mu_r=TABLE1["rolling_friction"]):
    """(t1, v1, t_stop, distance): slip ends at t1 = v0 / (g (3.5 mu - 2.5 mu_r)) with
    v1 = 2.5 v0 (mu - mu_r) / (3.5 mu - 2.5 mu_r); then rolling deceleration (5/7) mu_r g (docs/models.md §13 T2)."""
    t1 = v0 / (G * (3.5 * mu - 2.5 * mu_r))
    v1 = 2.5 * v0 * (mu - mu_r) / (3.5 * mu - 2.5 * mu_r)
    t_stop = t1 + 7 * v1 / (5 * mu_r * G)
    s = v0 * t1 - 0.5 * mu * G * t1 ** 2 + 7 * v1 ** 2 / (10 * mu_r * G)
    return t1, v1, t_stop, s


def analytic_flat_curve(t, v0=1.0, mu=TABLE1["friction"], mu_r=TABLE1["rolling_friction"]):
    """x(t) of the analytic T2 solution (for the figure)."""
    t1, v1, t_stop, s = analytic_flat(v0, mu, mu_r)
    a = 5 / 7 * mu_r * G
    t = np.asarray(t, dtype=float)
    slip = v0 * t - 0.5 * mu * G * t ** 2
    x1 = v0 * t1 - 0.5 * mu * G * t1 ** 2
    tr = np.clip(t, t1, t_stop) - t1
    return np.where(t < t1, slip, x1 + v1 * tr - 0.5 * a * tr ** 2)


def rolling_flat_run(rolling, duration=0.8, v0=1.0, material=None, wall=None) -> Trajectory:
    """Case 1 for one model: settle 0.2 s, launch at v0 with omega = 0, record ``duration`` seconds."""
    return launch(sphere_on_wall(rolling, material=material, wall=wall), duration, v0)


def stop_time(traj: Trajectory, speed=1e-3) -> float:
    """First sample with v_x below ``speed`` (m/s); NaN if it never stops. 1 mm/s is 0.7 ms of
    rolling deceleration (1.40 m/s^2) before rest."""
    below = np.nonzero(traj.v < speed)[0]
    return float(traj.t[below[0]]) if len(below) else math.nan


def viscous_decay_time(traj: Trajectory, t_from: float, t_to: float) -> float:
    """tau of v = v1 exp(-(t - t1) / tau), fitted (log-linear least squares) over [t_from, t_to]."""
    sel = (traj.t >= t_from) & (traj.t <= t_to) & (traj.v > 0)
    slope = np.polyfit(traj.t[sel], np.log(traj.v[sel]), 1)[0]
    return -1.0 / slope


# --- case 2: rolling up a slope ------------------------------------------------------------------
SLOPE = math.radians(10.0)


def analytic_slope(v0=1.0, theta=SLOPE, mu=TABLE1["friction"], mu_r=TABLE1["rolling_friction"]):
    """(x_max, t_max): slip until t1 = v0 / (g [sin + mu cos + 2.5 (mu - mu_r) cos]), then rolling
    deceleration (5/7) g (sin + mu_r cos) to rest (docs/models.md §13 T4)."""
    s, c = math.sin(theta), math.cos(theta)
    t1 = v0 / (G * (s + mu * c + 2.5 * (mu - mu_r) * c))
    v1 = v0 - G * (s + mu * c) * t1
    a = 5 / 7 * G * (s + mu_r * c)
    return v0 * t1 - 0.5 * G * (s + mu * c) * t1 ** 2 + v1 ** 2 / (2 * a), t1 + v1 / a


def rolling_slope_run(rolling, duration=2.2, v0=1.0, theta=SLOPE, wall=None) -> Trajectory:
    """Case 2 for one model: settle 0.2 s on the flat, tilt gravity by theta (the slope rises
    towards +x, as in the report), launch uphill; record ``duration`` seconds."""
    sim = sphere_on_wall(rolling, wall=wall)
    sim.gravity = (-G * math.sin(theta), 0.0, -G * math.cos(theta))
    return launch(sim, duration, v0, sample_steps=100)


def creep_speed(traj: Trajectory, last=1.0) -> float:
    """Mean x-velocity (m/s) over the last ``last`` seconds: (x(end) - x(end - last)) / last."""
    k = np.searchsorted(traj.t, traj.t[-1] - last)
    return float((traj.x[-1] - traj.x[k]) / (traj.t[-1] - traj.t[k]))


# --- case 0: inclined wall -------------------------------------------------------------------------
def speed_down_incline(rolling, mu_r, beta_deg, tilt_time=0.3, hold=0.3, material=None, wall=None) -> float:
    """Mean speed (m/s) down a wall tilted to beta, over the last 0.1 s.

    Gravity is tilted to beta over ``tilt_time`` in 1000 small steps (a sudden tilt makes an
    undamped rolling spring overshoot to twice the static moment and slip), then held ``hold`` s.
    ``material`` overrides Table 1 entries (``mu_r`` wins over its rolling_friction).
    """
    sim = sphere_on_wall(rolling, settle=0.05, material=dict(material or {}, rolling_friction=mu_r), wall=wall)
    steps = max(int(round(tilt_time / DT / 1000)), 1)
    tilts = iter(range(1, 1001))

    def tilt(s):  # at the start of the run and every ``steps`` steps: the next of the 1000 tilts
        k = next(tilts, None)
        if k is not None:
            b = math.radians(beta_deg) * k / 1000
            s.gravity = (G * math.sin(b), 0.0, -G * math.cos(b))

    sim.run(steps=1000 * steps, observers=[Callback(tilt, steps * sim.dt)])
    sim.run(hold - 0.1)
    x0 = sim.positions[0, 0]
    sim.run(0.1)
    return (sim.positions[0, 0] - x0) / 0.1


def rolling_threshold_speed(beta_deg, margin=0.005) -> float:
    """Speed (m/s) that separates rolling from holding in :func:`speed_down_incline`.

    ``margin`` below the critical mu_r the sphere rolls from the end of the tilt at
    a = (5/7) g margin sin(beta), i.e. about a x 0.25 s over the last 0.1 s; half of that.
    A held sphere moves less: springs not at all, CDT's chatter creep ~4e-5 m/s at 10 deg.
    """
    return 0.5 * 5 / 7 * G * margin * math.sin(math.radians(beta_deg)) * 0.25


def critical_rolling_friction(rolling, beta_deg, rel_tol=1e-3, bracket=0.05, wall=None, material=None,
                              time_scale=1.0) -> float:
    """mu_r at which the sphere starts to roll down a wall inclined by beta, by bisection in
    [tan b (1 - bracket), tan b (1 + bracket)] to a relative width ``rel_tol``. Returns the middle
    of the final bracket, or NaN when the bracket does not contain the threshold. ``material``
    overrides Table 1 entries (a parcel's ``coarse_graining``); ``time_scale`` makes the tilt and
    the hold that many times longer (a parcel of alpha: its contact's times are alpha times longer,
    and the tilt must stay as slow beside them, docs/models.md §18)."""
    tan_b = math.tan(math.radians(beta_deg))
    lo, hi = tan_b * (1 - bracket), tan_b * (1 + bracket)
    threshold = rolling_threshold_speed(beta_deg, rel_tol)

    def rolls(mu_r):
        return speed_down_incline(rolling, mu_r, beta_deg, tilt_time=0.3 * time_scale, hold=0.3 * time_scale,
                                  material=material, wall=wall) > threshold

    if not rolls(lo) or rolls(hi):
        return math.nan
    while hi - lo > rel_tol * tan_b:
        mid = 0.5 * (lo + hi)
        if rolls(mid):
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)
