"""``inclined-plane``: steady flow of a layer of spheres down a rough incline, periodic along the
flow and across it (the GDR MiDi 2004 inclined-plane rig; Silbert et al. 2001), and what it shows
of the local rheology: Bagnold's velocity profile, a uniform solid fraction, and the friction
tan(theta) at the flow's inertial number, which the simple-shear rig's mu(I) must give too.

The scene: a plane at z = 0 with a rough base of fixed spheres on it (``rollingdem.rough_base``),
``count`` spheres (radii uniform in R (1 +- ``polydispersity``)) poured onto it to a depth of
``depth`` mean diameters d, gravity tilted by ``angle`` theta about y. The layer flows for
``duration``; a ``fields`` measurement (Lucy kernel of width 0.6 d) averages the profile along z
over its second half. Read from the profile, between 3 d above the base and 3 d below the surface
(the bulk): the flow's depth h (where the solid fraction falls to half its bulk value), the
velocity u(z) against Bagnold's u_b + A (h^(3/2) - (h - z)^(3/2)), the solid fraction's spread, the
stress ratio -sigma_xz / sigma_zz (tan theta in steady flow) and sigma_zz against the weight of
the material above (rho g cos(theta) times the integral of phi), the inertial number I = (du/dz) d
/ sqrt(sigma_zz / rho).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pandas as pd
from scipy.integrate import trapezoid

from rollingdem.errors import ParameterError
from rollingdem.experiments.registry import BedExperiment, Parameter, resolve_rolling
from rollingdem.experiments.results import Check, ValidationResult, pyplot, run_points
from rollingdem.experiments.simple_shear import SimpleShear, flow_parameters, run_quietly
from rollingdem.io.field_measurements import ContinuumFields
from rollingdem.physics.contact.model import ContactModel
from rollingdem.scene.insertion import rough_base
from rollingdem.scene.materials import Material
from rollingdem.scene.regions import BoxRegion
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.size_distributions import Uniform
from rollingdem.scene.walls import Plane

G = 9.81
#: the layer is poured at this solid fraction (its height then settles by about a half)
POURED_FRACTION = 0.3
#: diameters left out of the bulk at the base and under the surface
EDGE = 3.0
#: a layer has stopped when its spheres' mean speed is below this times sqrt(g d)
STOPPED = 1e-2
#: the stop angle's search: from 23 deg down in steps of 0.5 deg, 0.5 s each
STOP_START, STOP_STEP, STOP_SETTLE = 23.0, 0.5, 0.5
#: the fields' kernel width in mean diameters, and their samples over the run
KERNEL_WIDTH, SAMPLES = 0.6, 300


def chute_scene(p: dict) -> Simulation:
    """The base and the layer of ``p``, poured, gravity at ``p``'s angle."""
    R, d = p["radius"], 2.0 * p["radius"]
    length, width = p["length"] * d, p["width"] * d
    theta = math.radians(p["angle"])
    sim = Simulation(contact=ContactModel("hertz", rolling=resolve_rolling(p["model"])),
                     gravity=(G * math.sin(theta), 0.0, -G * math.cos(theta)),
                     periodic={"x": (0.0, length), "y": (0.0, width)})
    sim.add_material(Material("spheres", youngs_modulus=p["youngs_modulus"], poisson_ratio=0.25, density=p["density"],
                              friction=p["mu"], rolling_friction=p["mur"], restitution=p["e"], rolling_damping=p["eta_r"]))
    sim.add_wall(Plane(point=(0.0, 0.0, 0.0), normal=(0.0, 0.0, 1.0), material="spheres"))
    sim.add_particles(rough_base(R, ((0.0, length), (0.0, width)), seed=p["seed"]), R, "spheres", fixed=True)
    count = int(round(p["depth"] * d * length * width * 0.58 / (math.pi / 6.0 * d ** 3)))
    poured = p["depth"] * d * 0.58 / POURED_FRACTION
    sim.insert(BoxRegion((0.0, 0.0, 2.0 * R), (length, width, 2.0 * R + poured)), count,
               Uniform(R * (1.0 - p["polydispersity"]), R * (1.0 + p["polydispersity"])), "spheres", seed=p["seed"],
               max_attempts=2000)
    return sim


def tilt(sim, angle: float) -> None:
    """Gravity at ``angle`` (deg) to -z, about y: the incline's slope."""
    theta = math.radians(angle)
    sim.gravity = (G * math.sin(theta), 0.0, -G * math.cos(theta))


def stop_angle(p: dict, start: float, step: float, settle: float) -> tuple[float, float]:
    """(the lowest angle at which ``p``'s layer still flowed, the angle at which it stopped): the
    layer flows at ``start`` deg for ``settle`` s, then the slope is lowered by ``step`` deg after
    each ``settle`` s until the spheres' mean speed falls below STOPPED sqrt(g d) (Pouliquen 1999's
    theta_stop(h), found by lowering the slope)."""
    sim = chute_scene(dict(p, angle=start))
    speed_scale = math.sqrt(G * 2.0 * p["radius"])
    angle = start
    free = ~sim.fixed
    while angle > 0.0:
        tilt(sim, angle)
        run_quietly(sim, settle)
        if np.linalg.norm(sim.velocities[free], axis=1).mean() < STOPPED * speed_scale:
            return angle + step, angle
        angle -= step
    return step, 0.0


def chute_run(p: dict) -> dict:
    """One layer flowing at ``p``'s angle: the profile's measures (see the module) and the profile."""
    start = time.perf_counter()
    sim = chute_scene(p)
    d, theta = 2.0 * p["radius"], math.radians(p["angle"])
    fields = ContinuumFields("profile", width=KERNEL_WIDTH * d, axis="z", interval=p["duration"] / SAMPLES,
                             window=(0.5 * p["duration"], p["duration"]), vtk=False)
    run_quietly(sim, p["duration"], observers=[fields])
    return dict(profile_measures(fields.mean_profile(), d, d, p["density"], theta),
                count=int((~sim.fixed).sum()), wall_time=time.perf_counter() - start)


def profile_measures(profile: dict, base: float, d: float, density: float, theta: float) -> dict:
    """The layer's measures from its window-averaged ``profile`` (a fields profile along z, the
    base's top at ``base``)."""
    z, phi, u = profile["z (m)"], profile["solid_fraction (1)"], profile["velocity_x (m/s)"]
    szz, sxz = profile["stress_zz (Pa)"], profile["stress_xz (Pa)"]
    inside = z > base
    core = inside & (phi > 0.0)
    level = 0.5 * np.median(phi[core][len(phi[core]) // 4: 3 * len(phi[core]) // 4])
    above = np.flatnonzero(inside & (z > base + EDGE * d) & (phi < level))
    if not len(above):
        raise ParameterError("the layer has no free surface on the profile's grid: it is deeper than the grid")
    k = above[0]
    top = z[k - 1] + (z[k] - z[k - 1]) * (phi[k - 1] - level) / (phi[k - 1] - phi[k])
    h = top - base
    bulk = (z >= base + EDGE * d) & (z <= top - EDGE * d)
    if bulk.sum() < 3:
        raise ParameterError(f"the layer's depth {h / d:.3g} d leaves no bulk between {EDGE:g} d from the base and "
                             f"{EDGE:g} d from the surface: pour it deeper")
    zeta = z[bulk] - base
    shape = h ** 1.5 - np.clip(h - zeta, 0.0, None) ** 1.5
    design = np.column_stack([np.ones_like(shape), shape])
    (slip, amplitude), *_ = np.linalg.lstsq(design, u[bulk], rcond=None)
    surface_speed = slip + amplitude * h ** 1.5
    bagnold = float(np.max(np.abs(u[bulk] - design @ (slip, amplitude))) / surface_speed)
    weight = np.array([density * G * math.cos(theta) * trapezoid(phi[(z >= zk)], z[(z >= zk)]) for zk in z])
    rate = np.gradient(u, z)
    inertial = rate[bulk] * d / np.sqrt(szz[bulk] / density)
    return {"depth": h / d, "surface_speed": float(surface_speed), "slip_speed": float(slip),
            "bagnold_deviation": bagnold, "bulk_solid_fraction": float(phi[bulk].mean()),
            "solid_fraction_spread": float(np.max(np.abs(phi[bulk] - phi[bulk].mean()))),
            "stress_ratio": float(-sxz[bulk].sum() / szz[bulk].sum()),
            "weight_ratio": float(szz[bulk].sum() / weight[bulk].sum()),
            "inertial_number": float(inertial.mean()),
            "inertial_spread": float(np.max(np.abs(inertial - inertial.mean())) / inertial.mean()),
            "froude": float(trapezoid(u[inside & (z <= top)] * phi[inside & (z <= top)], z[inside & (z <= top)])
                            / trapezoid(phi[inside & (z <= top)], z[inside & (z <= top)])
                            / math.sqrt(G * h * math.cos(theta)))}


class InclinedPlane(BedExperiment):
    """A layer of spheres in steady flow down a rough incline, periodic along and across the flow."""

    name = "inclined-plane"
    description = ("a layer of spheres flowing steadily down a rough incline, periodic along and across the flow "
                   "(GDR MiDi 2004): Bagnold's profile, the solid fraction, tan(theta) against mu(I)")
    parameters = flow_parameters() + (
                  Parameter("angle", 25.0, "the incline's angle theta", "deg", low=0.0, low_open=True, high=60.0),
                  Parameter("depth", 10.0, "the layer's depth, in mean diameters", low=2.0 * EDGE),
                  Parameter("length", 10.0, "the periodic length along the flow, in mean diameters", low=5.0),
                  Parameter("width", 5.0, "the periodic width across the flow, in mean diameters", low=5.0),
                  Parameter("radius", 5e-4, "mean sphere radius R", "m", low=0.0, low_open=True),
                  Parameter("polydispersity", 0.2, "radii uniform in R (1 +- p)", low=0.0, high=0.5),
                  Parameter("youngs_modulus", 1e7, "Young's modulus", "Pa", low=0.0, low_open=True),
                  Parameter("density", 2500.0, "the spheres' density rho", "kg/m^3", low=0.0, low_open=True),
                  Parameter("duration", 3.0, "flow time; the profile is averaged over its second half", "s",
                            low=0.0, low_open=True),
                  Parameter("seed", 1, "random seed (base, pouring)", low=0, integer=True))
    observables = {"surface_speed": "m/s: the fitted Bagnold profile's speed at the surface",
                   "froude": "-: the depth-averaged speed over sqrt(g h cos theta)",
                   "bulk_solid_fraction": "-: the mean solid fraction between 3 d from the base and the surface",
                   "inertial_number": "-: the bulk's mean I = (du/dz) d / sqrt(sigma_zz / rho)",
                   "stress_ratio": "-: -sigma_xz / sigma_zz in the bulk (tan theta when steady)"}
    default_observable = "froude"
    sizes = {"quick": {"depth": 10.0, "length": 10.0, "width": 5.0, "duration": 3.0},
             "full": {"depth": 15.0, "length": 20.0, "width": 10.0, "duration": 5.0}}

    def observe(self, params: dict) -> dict:
        return chute_run(params)

    def validate(self, quick=False, outdir=None, progress=None, runner=map, model="epsd") -> ValidationResult:
        """The layer at 23, 25 and 27 deg (mu = 0.5, mu_r = 0); the simple-shear rig at each run's bulk
        I. Checks (each angle): Bagnold's profile within 5 % of the surface speed in the bulk; the
        inertial number uniform within 10 % (what tells Bagnold's profile from a straight one over the
        bulk); the solid fraction uniform within 0.01; steady flow: -sigma_xz / sigma_zz = tan(theta)
        within 2 %; mu(I) of the shear rig at the layer's I = tan(theta) within 2 of its standard errors
        and 0.02 (the layer's I spread). The slope lowered from 23 deg by 0.5 deg every 0.5 s until the
        layer stops: the shear rig's mu at I = 0.001 lies below the tangent of the angle where it last
        flowed (an upper bound, two standard errors): a thin layer stops above it. sigma_zz against
        the weight above is reported: the profile's kinetic stress is about each sample's mean
        velocity, so a layer that breathes adds the mean flow's vertical momentum flux, which the
        window's average does not hold."""
        tic = time.perf_counter()
        base = {"model": model, **self.sizes["quick" if quick else "full"]}
        angles = (23.0, 25.0, 27.0)
        runs = run_points(self, [self.resolve(dict(base, angle=a)) for a in angles], [1], runner, progress)
        shear = SimpleShear()
        size = shear.sizes["quick" if quick else "full"]
        points = [shear.resolve(dict(size, model=model, mu=0.5, mur=0.0, inertial_number=min(max(i, 1e-3), 0.9)))
                  for i in runs["inertial_number"]]
        points.append(shear.resolve(dict(size, model=model, mu=0.5, mur=0.0, inertial_number=1e-3)))
        sheared = run_points(shear, points, [1], runner, progress)
        runs["shear_friction"] = sheared["friction"].to_numpy()[:-1]
        runs["shear_friction_error"] = sheared["friction_error"].to_numpy()[:-1]
        slow, slow_error = float(sheared["friction"].iloc[-1]), float(sheared["friction_error"].iloc[-1])
        flowed, stopped = stop_angle(self.resolve(base), STOP_START, STOP_STEP, STOP_SETTLE)
        runs["tan_theta"] = np.tan(np.radians(runs["angle"]))
        checks = []
        name = self.name
        for _, r in runs.iterrows():
            at = f"theta = {r['angle']:g} deg"
            checks += [
                Check(name, model, f"{at}: Bagnold profile, largest deviation in the bulk / surface speed",
                      r["bagnold_deviation"], 0.05, 0.0, bound="upper",
                      source="Bagnold's u ~ h^(3/2) - (h - z)^(3/2) (GDR MiDi 2004; Silbert et al. 2001)"),
                Check(name, model, f"{at}: largest deviation of I from its bulk mean / the mean",
                      r["inertial_spread"], 0.1, 0.0, bound="upper",
                      source="Bagnold's profile is a uniform I (du/dz ~ sqrt(h - z), sigma_zz ~ h - z): what tells it "
                             "from a straight profile over the bulk"),
                Check(name, model, f"{at}: largest deviation of the solid fraction from its bulk mean",
                      r["solid_fraction_spread"], 0.01, 0.0, bound="upper",
                      source="steady chute flow: phi uniform in the bulk (Silbert et al. 2001)"),
                Check(name, model, f"{at}: -sigma_xz / sigma_zz in the bulk", r["stress_ratio"], r["tan_theta"], 0.02,
                      source="momentum balance of a steady uniform layer: tau / sigma_zz = tan theta"),
                Check(name, model, f"{at}: mu(I) of the simple-shear rig at the layer's I = {r['inertial_number']:.3f} "
                      f"(+-{r['shear_friction_error']:.3f})", r["shear_friction"], r["tan_theta"],
                      2.0 * r["shear_friction_error"] + 0.02, relative=False,
                      source="one rheology, two rigs (GDR MiDi 2004; Jop et al. 2006); tolerance: the shear point's "
                             "two standard errors and 0.02 for I's spread over the layer")]
        checks.append(Check(name, model, f"the simple-shear rig's mu at I = 0.001 (+-{slow_error:.3f}) against "
                            f"tan of the last slope the layer flowed at ({flowed:g} deg; it stopped at {stopped:g} deg, "
                            "lowered from 23 deg)", slow, math.tan(math.radians(flowed)) + 2.0 * slow_error, 0.0,
                            bound="upper", source="a layer flows only where tan theta exceeds its quasi-static "
                                                  "friction, and a thin one stops above it (h_stop: Pouliquen 1999); "
                                                  "bound: two standard errors"))
        runs["stop_angle"], runs["quasi_static_friction"] = stopped, slow
        table = runs[["angle", "depth", "surface_speed", "slip_speed", "froude", "bulk_solid_fraction", "inertial_number",
                      "stress_ratio", "tan_theta", "shear_friction", "weight_ratio", "bagnold_deviation",
                      "solid_fraction_spread", "inertial_spread", "stop_angle", "quasi_static_friction",
                      "wall_time"]]
        result = ValidationResult(name, f"Inclined plane ({model}{', quick' if quick else ''})", pd.DataFrame(table),
                                  checks, notes=[f"A layer {base['depth']:g} d deep on a rough base of fixed spheres, "
                                                 f"periodic over {base['length']:g} d x {base['width']:g} d, mu = 0.5, "
                                                 "R = 0.5 mm +- 20 %, E = 10 MPa, e = 0.5; profile averaged over the "
                                                 f"second half of {base['duration']:g} s. docs/studies.md, "
                                                 "\"The inclined plane\"."])
        if outdir is not None:
            plt = pyplot()
            fig, ax = plt.subplots(figsize=(5, 4))
            ax.plot(runs["inertial_number"], runs["tan_theta"], "o", label="incline: tan theta at the layer's I")
            ax.errorbar(runs["inertial_number"], runs["shear_friction"], yerr=2 * runs["shear_friction_error"], fmt="s",
                        capsize=3, label="simple shear at that I")
            ax.set_xlabel("inertial number I")
            ax.set_ylabel("mu")
            ax.legend(fontsize=8)
            result.add_figure(fig, outdir, "inclined_plane.png")
        result.wall_time = time.perf_counter() - tic
        return result
