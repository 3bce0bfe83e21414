"""``rollingdem validate --experiment clumps``: clumps against rigid-body statics and dynamics, and the
rolling friction that stands in for them (docs/models.md §17).

Each check sets up a textbook situation and compares the measured number with its closed form:
the tilt at which a ring prism of n spheres tips over on a slope, and a sphere with the rolling
friction that stands for it starts to roll (tan theta = r / (r + a_n)); an asymmetric clump's
torque-free rotation (energy and angular momentum kept; the intermediate-axis flip's period,
Landau & Lifshitz §37); the mass properties of overlapping spheres (the lens's closed form); a
dimer dropped flat (its restitution); an unequal dimer at rest (the plane's reactions by statics).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd

from rollingdem.experiments.registry import Experiment
from rollingdem.experiments.results import Check, ValidationResult, pyplot
from rollingdem.experiments.single_sphere import rolling_threshold_speed, speed_down_incline
from rollingdem.physics.contact.model import ContactModel
from rollingdem.scene.clumps import Clump, onset_angle
from rollingdem.scene.materials import Material
from rollingdem.scene.rigid_bodies import matrix_quaternion
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.walls import Plane

CASE = "clumps"
G = 9.81
RADIUS = 0.001  # m, the ring prisms' spheres
PRISMS = (3, 4, 6)
#: the issue's tolerance on a simulated onset: 0.2 deg
ONSET_TOLERANCE = 0.2  # deg
TILT_STEPS, TILT_TIME, HOLD = 200, 0.2, 0.2  # gravity turned in 200 steps over 0.2 s, then held 0.2 s
TIPPED = 15.0  # deg: turned through more than this, the prism has tipped (it rests within 0.05 deg)


def material(sim, friction=1.0, restitution=0.2, **kw):
    """Glass-like spheres, soft enough for a large step (E = 1e8 Pa: overlaps of 1e-8 m under a
    prism's weight, 1e-5 of r, which leave the statics unchanged)."""
    sim.add_material(Material("g", 1e8, 0.3, 2500.0, friction=friction, restitution=restitution, **kw))


def prism_pose(n: int):
    """A ring prism of n touching spheres of ``RADIUS`` and the rotation that stands it on two
    neighbours with its axis along y (the contour lines of a slope falling along x)."""
    from scipy.spatial.transform import Rotation  # deferred: slow to load, used here only

    turn = Rotation.from_euler("x", 90, degrees=True) * Rotation.from_euler("z", -90 + 180.0 / n, degrees=True)
    return Clump.ring_prism(n, RADIUS), turn


def prism_turn(n: int, tilt_deg: float) -> float:
    """The angle (deg) a ring prism of n turns through on a plane tilted slowly to ``tilt_deg``
    (settled 0.1 s flat, gravity turned in ``TILT_STEPS`` steps over ``TILT_TIME``, held ``HOLD``);
    friction 1.0, so nothing slides."""
    clump, turn = prism_pose(n)
    sim = Simulation(contact=ContactModel("hertz"), gravity=(0, 0, -G))
    material(sim)
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    x, y, z, w = turn.as_quat()
    lowest = (clump.centres @ turn.as_matrix().T)[:, 2].min()
    sim.add_clumps(clump, [[0, 0, RADIUS - lowest]], "g", orientations=[w, x, y, z])
    sim.run(0.1)
    start = sim.clumps["orientation"][0].copy()
    theta = math.radians(tilt_deg)
    for k in range(1, TILT_STEPS + 1):
        sim.gravity = (G * math.sin(theta * k / TILT_STEPS), 0, -G * math.cos(theta * k / TILT_STEPS))
        sim.run(TILT_TIME / TILT_STEPS)
    sim.run(HOLD)
    return 2 * math.degrees(math.acos(min(1.0, abs(float(np.dot(start, sim.clumps["orientation"][0]))))))


def bisect_onset(tips, low: float, high: float, width: float) -> tuple[float, float]:
    """The bracket [low, high] (deg) narrowed by halving to ``width``, ``tips(angle)`` true above the
    onset: (the last angle found holding, the first found tipping). ``tips`` must hold at ``low``
    and tip at ``high``; else NaN."""
    if tips(low) or not tips(high):
        return math.nan, math.nan
    while high - low > width:
        mid = 0.5 * (low + high)
        if tips(mid):
            high = mid
        else:
            low = mid
    return low, high


def sphere_rolls(model: str, mu_r: float, tilt_deg: float) -> bool:
    """Whether a Table-1 sphere with rolling friction ``mu_r`` rolls down a wall tilted slowly to
    ``tilt_deg`` (the seed report's case 0, ``single_sphere.speed_down_incline``): its mean speed
    over the last 0.1 s above the threshold for a margin of 0.1 % in tan theta."""
    return speed_down_incline(model, mu_r, tilt_deg) > rolling_threshold_speed(tilt_deg, 1e-3)


def free_rotation(steps: int):
    """An asymmetric clump (spheres of 2, 1.5 and 1 mm, two overlapping) spun about a tilted axis, no
    gravity, ``steps`` steps: (relative energy change, relative change of |L|, |omega| dt)."""
    sim = Simulation(gravity=(0, 0, 0), dt=5e-6)
    material(sim)
    clump = Clump([[0, 0, 0], [0.003, 0, 0], [0, 0.002, 0.001]], [0.002, 0.0015, 0.001])
    sim.add_clumps(clump, [[0, 0, 0]], "g", angular_velocity=[3.0, 20.0, 0.5], orientations=[0.9, 0.1, -0.3, 0.2])
    energy, momentum = sum(sim.kinetic_energy()), np.linalg.norm(sim.clumps["angular_momentum"][0])
    sim.run(steps=steps)
    omega = np.linalg.norm(sim.clumps["angular_velocity"][0])
    return (abs(sum(sim.kinetic_energy()) / energy - 1.0),
            abs(np.linalg.norm(sim.clumps["angular_momentum"][0]) / momentum - 1.0), omega * sim.dt)


def flip_theory(moments, omega_body) -> float:
    """The period (s) of the body-frame angular velocity of a torque-free rigid body (Landau &
    Lifshitz, Mechanics, §37): with I_1 < I_2 < I_3, energy E and L^2 > 2 E I_2, omega_2 goes as
    sn(tau, k), tau = t sqrt((I_3 - I_2)(L^2 - 2 E I_1) / (I_1 I_2 I_3)), k^2 = (I_2 - I_1)(2 E I_3
    - L^2) / ((I_3 - I_2)(L^2 - 2 E I_1)), period 4 K(k) in tau; for L^2 < 2 E I_2 axes 1 and 3
    exchange their parts."""
    from scipy.special import ellipk  # deferred: slow to load, used here only

    i1, i2, i3 = moments
    w = np.asarray(omega_body, float)
    energy = 0.5 * float(np.sum(moments * w ** 2))
    l2 = float(np.sum((moments * w) ** 2))
    if l2 > 2 * energy * i2:
        rate = math.sqrt((i3 - i2) * (l2 - 2 * energy * i1) / (i1 * i2 * i3))
        m = (i2 - i1) * (2 * energy * i3 - l2) / ((i3 - i2) * (l2 - 2 * energy * i1))
    else:
        rate = math.sqrt((i2 - i1) * (2 * energy * i3 - l2) / (i1 * i2 * i3))
        m = (i3 - i2) * (l2 - 2 * energy * i1) / ((i2 - i1) * (2 * energy * i3 - l2))
    return 4.0 * ellipk(m) / rate


def crossings_period(times, signal) -> float:
    """The mean period (s) of ``signal`` from its upward zero crossings (linear between samples);
    NaN with fewer than two."""
    s = np.asarray(signal)
    k = np.nonzero((s[:-1] < 0.0) & (s[1:] >= 0.0))[0]
    if len(k) < 2:
        return math.nan
    t = times[k] + (times[k + 1] - times[k]) * (-s[k]) / (s[k + 1] - s[k])
    return float((t[-1] - t[0]) / (len(t) - 1))


def intermediate_axis_flip(periods: int = 3):
    """A clump spun at 100 rad/s about its intermediate axis, nudged by 1 and 2 rad/s about the
    others, in the engine: (the measured period of omega_2 from its zero crossings over ``periods``
    periods, the theory's)."""
    # a lone body: no contact can form, so the contact time-step limits do not apply
    sim = Simulation(gravity=(0, 0, 0), dt=5e-6, check_timestep=False)  # omega dt = 5e-4
    material(sim)
    clump = Clump([[0, 0, 0], [0.003, 0, 0], [0, 0.002, 0.001]], [0.002, 0.0015, 0.001])
    props = clump.mass_properties(2500.0)
    body = np.array([1.0, 100.0, 2.0])
    # the principal frame turned into the template's frame gives the template orientation whose
    # principal frame is the space frame: the body's omega is then the space one

    q_axes = matrix_quaternion(props.principal_axes)
    q = np.array([q_axes[0], -q_axes[1], -q_axes[2], -q_axes[3]])
    sim.add_clumps(clump, [[0, 0, 0]], "g", orientations=q, angular_velocity=body)
    period = flip_theory(props.principal_moments, body)
    every = 100  # steps: ~1500 samples a period
    samples = int((periods + 0.5) * period / sim.dt / every) + 1
    times, w2 = np.zeros(samples), np.zeros(samples)
    for k in range(samples):
        turn = sim.clumps["axes"][0]
        times[k], w2[k] = sim.time, float(turn[:, 1] @ sim.clumps["angular_velocity"][0])
        sim.run(steps=every)
    return crossings_period(times, w2), period


def flat_drop(restitution: float) -> float:
    """A dimer of touching 2 mm spheres dropped flat on a plane at 1 m/s (Hertz, no gravity): its
    rebound speed over its impact speed."""
    sim = Simulation(contact=ContactModel("hertz"), gravity=(0, 0, 0), dt=2e-7)
    material(sim, friction=0.5, restitution=restitution)
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    sim.add_clumps(Clump.dimer(0.002), [[0, 0, 0.00202]], "g", velocity=[0, 0, -1.0])
    sim.run(steps=30_000)
    return float(sim.clumps["velocity"][0, 2])


def dimer_loads():
    """Spheres of 2 and 1 mm, centres 2.5 mm apart, at rest on a plane on both (settled 0.2 s): the
    measured reactions (N1, N2), statics' (the union's centre of mass between them), the clump's
    weight M g and the simulation."""
    sim = Simulation(contact=ContactModel("hertz"), gravity=(0, 0, -G))
    material(sim, friction=0.5, restitution=0.3)
    sim.add_wall(Plane(point=(0, 0, 0), normal=(0, 0, 1)))
    r1, r2, d = 0.002, 0.001, 0.0025
    clump = Clump([[0, 0, 0], [d, 0, 0]], [r1, r2])
    tilt = math.asin((r1 - r2) / d)
    q = [math.cos(tilt / 2), 0, math.sin(tilt / 2), 0]
    placed = clump.placed([0, 0, 0], q)
    sim.add_clumps(clump, [[0, 0, -min(placed[0, 2] - r1, placed[1, 2] - r2) + 1e-7]], "g", orientations=q)
    sim.run(0.2)
    x, mass, centre = sim.positions, sim.clumps["mass"][0], sim.clumps["centre"][0]
    n1 = mass * G * (x[1, 0] - centre[0]) / (x[1, 0] - x[0, 0])
    return sim.forces[:, 2].copy(), np.array([n1, mass * G - n1]), mass * G, sim


def lens_volume(radius: float, distance: float) -> float:
    """The volume of two spheres of ``radius`` whose centres are ``distance`` apart, their lens
    pi (4R + d)(2R - d)^2 / 12 taken once."""
    return 2 * 4.0 / 3.0 * math.pi * radius ** 3 - math.pi * (4 * radius + distance) * (2 * radius - distance) ** 2 / 12


def clumps(quick=False, outdir=None, progress=None) -> ValidationResult:
    """The clump checks; ``quick``: the onsets bracketed at +-0.2 deg only, the sphere stand-ins for
    n = 3 with EPSD, 10^4 free steps and two flips."""
    start = time.perf_counter()
    checks, rows = [], []

    def check(model, quantity, measured, reference, tolerance, relative=True, source="", bound="two-sided"):
        checks.append(Check(CASE, model, quantity, float(measured), float(reference), tolerance, relative=relative,
                            bound=bound, source=source))
        rows.append({"what": model, "quantity": quantity, "measured": float(measured), "reference": float(reference)})
        if progress:
            progress()

    onsets = {}
    for n in PRISMS:
        clump, turn = prism_pose(n)
        theory = math.degrees(onset_angle(clump, turn.as_matrix()))
        if quick:
            held = prism_turn(n, theory - ONSET_TOLERANCE) < TIPPED
            tipped = prism_turn(n, theory + ONSET_TOLERANCE) >= TIPPED
            onsets[n] = (theory, math.nan)
            check(f"ring prism of {n}", f"holds {ONSET_TOLERANCE} deg below the onset and tips {ONSET_TOLERANCE} deg "
                  "above it (1 = yes)", float(held and tipped), 1.0, 0.0, relative=False,
                  source="tan theta = r / (r + a_n) (statics)")
        else:
            low, high = bisect_onset(lambda a: prism_turn(n, a) >= TIPPED, theory - 1.0, theory + 1.0, 0.05)
            onsets[n] = (theory, 0.5 * (low + high))
            check(f"ring prism of {n}", "onset of tipping (deg), bisected to 0.05 deg", onsets[n][1], theory,
                  ONSET_TOLERANCE, relative=False, source="tan theta = r / (r + a_n) (statics)")
        for model in ("epsd", "cdt") if not quick else ("epsd",) if n == 3 else ():
            mu_r = math.tan(math.radians(theory))
            ok = (not sphere_rolls(model, mu_r, theory - ONSET_TOLERANCE)) and sphere_rolls(model, mu_r,
                                                                                          theory + ONSET_TOLERANCE)
            check(f"sphere, {model}, mu_r = {mu_r:.3f}", f"holds at {theory - ONSET_TOLERANCE:.2f} deg and rolls at "
                  f"{theory + ONSET_TOLERANCE:.2f} deg (1 = yes)", float(ok), 1.0, 0.0, relative=False,
                  source="mu_r = tan theta: the sphere that stands in for the prism")
    energy, momentum, turn_per_step = free_rotation(10_000 if quick else 100_000)
    steps = "1e4" if quick else "1e5"
    check("asymmetric clump", f"relative energy change over {steps} free steps", energy, 1e-6, 0.0, bound="upper",
          source=f"symplectic splitting, |omega| dt = {turn_per_step:.1e}")
    check("asymmetric clump", f"relative change of |L| over {steps} free steps", momentum, 1e-6, 0.0, bound="upper",
          source="no torque")
    measured, theory = intermediate_axis_flip(2 if quick else 4)
    check("asymmetric clump", "intermediate-axis flip period (s)", measured, theory, 0.01,
          source="4 K(k) / rate, Landau & Lifshitz §37")
    for d in (0.0015, 0.001):
        exact = Clump([[0, 0, 0], [d, 0, 0]], [0.001, 0.001]).mass_properties(1.0, method="exact").volume
        grid = Clump([[0, 0, 0], [d, 0, 0]], [0.001, 0.001]).mass_properties(1.0, method="quadrature").volume
        check(f"dimer, centres {d * 1e3:g} mm apart", "volume, exact (m^3)", exact, lens_volume(0.001, d), 1e-12,
              source="two spheres less their lens, pi (4R + d)(2R - d)^2 / 12")
        check(f"dimer, centres {d * 1e3:g} mm apart", "volume, quadrature (m^3)", grid, lens_volume(0.001, d), 2e-3,
              source="the quadrature's stated accuracy")
    for e in ((0.6,) if quick else (0.3, 0.6, 0.9)):
        check("dimer dropped flat", f"rebound / impact speed at e = {e}", flat_drop(e), e, 1e-3,
              source="each member a sphere of half the mass on its own contact")
    measured_loads, statics, weight, _ = dimer_loads()
    for k in range(2):
        check("unequal dimer at rest", f"reaction under sphere {k + 1} (N)", measured_loads[k], statics[k],
              1e-5 * weight, relative=False, source="statics: N1 + N2 = M g, moments about the centre of mass")
    result = ValidationResult(CASE, "Clumps: rigid-body statics and dynamics, and the mu_r that stands in",
                              pd.DataFrame(rows), checks)
    if outdir is not None:
        plt = pyplot()
        fig, ax = plt.subplots(figsize=(5.5, 4))
        n = np.array(PRISMS)
        ax.plot(n, [onsets[k][0] for k in PRISMS], "ks", mfc="none", ms=10, label="statics, tan θ = r / (r + a_n)")
        ax.plot(n, [onsets[k][1] for k in PRISMS], "o", label="simulated (bisection)")
        ax.set_xlabel("spheres in the ring prism, n")
        ax.set_ylabel("onset of tipping (deg)")
        ax.legend()
        ax.set_title("Ring prisms tipping on a slope")
        result.add_figure(fig, outdir, "clump_onset.png")
    result.wall_time = time.perf_counter() - start
    return result


class Clumps(Experiment):
    """Clumps against rigid-body theory."""

    name = "clumps"
    description = "clumps: onset of tipping, torque-free rotation, mass properties, impact and static loads"

    def validate(self, quick=False, outdir=None, progress=None, runner=map, models=None) -> ValidationResult:
        return clumps(quick=quick, outdir=outdir, progress=progress)
