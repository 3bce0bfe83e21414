"""``simple-shear``: steady simple shear of a polydisperse sphere packing between Lees-Edwards
boundaries at a constant normal stress, and what it gives: the friction mu = tau / P and the solid
fraction phi against the inertial number I = gamma_dot d / sqrt(P / rho) (GDR MiDi 2004; da Cruz et
al. 2005), with and without rolling resistance.

The scene: ``count`` spheres, radii uniform in R (1 +- ``polydispersity``), gravity off, in a box
periodic along x, y and z and sheared along x, its gradient along z (``rollingdem.LeesEdwards``).
It is made by a random insertion at a solid fraction of 0.3 and an isotropic compression to the
pressure P (the three lengths scaled together by a servo, ``BoxServo``), then sheared at
gamma_dot = I d / sqrt(P / rho) from the affine velocity profile, the gradient's length servoed to
hold sigma_zz = P (the pressure-controlled shear of da Cruz et al. 2005). Past a transient strain
the samples give mu = -sigma_xz / sigma_zz, phi and the I they were taken at (the stress: the
contacts' virial and the kinetic stress about the affine profile, over the box's volume,
``rollingdem.analysis.rheology.box_stress``).
"""

from __future__ import annotations

import math
import time
import warnings

import numpy as np
import pandas as pd

from rollingdem.analysis.rheology import box_stress, fit_mu_of_i, fit_phi_of_i, mu_of_i
from rollingdem.errors import ParameterError
from rollingdem.experiments.registry import BedExperiment, Parameter, resolve_rolling
from rollingdem.experiments.results import Check, ValidationResult, pyplot, run_points
from rollingdem.experiments.single_sphere import CREEPING
from rollingdem.io.box_measurements import BoxServo, box_volume, effective_modulus, stress_now
from rollingdem.io.measurements import batch_standard_error
from rollingdem.physics.contact.model import ContactModel
from rollingdem.scene.materials import Material
from rollingdem.scene.periodic import LeesEdwards
from rollingdem.scene.regions import BoxRegion
from rollingdem.scene.simulation import Simulation
from rollingdem.scene.size_distributions import Uniform

#: the solid fraction the spheres are inserted at, before the compression
INSERTED_FRACTION = 0.3
#: steps between two moves of the servo while compressing; while shearing, samples of the stress
#: (each a move of the servo) per unit of strain, at most one per step and at least one per ``CHUNK``
CHUNK, SAMPLES_PER_STRAIN = 100, 1000
#: the inertial numbers of a validation's mu(I) and phi(I) curves, and the rolling friction of its series
INERTIAL_NUMBERS = (0.001, 0.003, 0.01, 0.03, 0.1, 0.3)
ROLLING_FRICTIONS = (0.0, 0.1, 0.25, 0.5)
#: the frictionless spheres' point also run STIFFER times stiffer (its phi extrapolated to rigid spheres)
RIGID_POINT, STIFFER = 0.003, 10.0
#: references: frictionless spheres (Peyneau & Roux 2008, homogeneous shear: an internal friction of
#: about 0.1 and the solid fraction of random close packing, 0.639 in Agnolin & Roux 2007); glass
#: beads on inclined planes (GDR MiDi 2004; Jop, Forterre & Pouliquen 2006: mu_s = tan 20.9 deg)
FRICTIONLESS_MU_S, RCP_FRACTION, GLASS_MU_S = 0.10, 0.639, math.tan(math.radians(20.9))
#: the compression ends when the pressure is within this of P and the kinetic energy per sphere
#: below ``REST_ENERGY`` P d^3 (the packing is at rest under P)
PRESSURE_WITHIN, REST_ENERGY = 0.02, 1e-6


def plane_traction(contacts, positions, plane: float, length: float, area: float) -> np.ndarray:
    """The contact traction (Pa) across the plane z = ``plane`` of a box ``length`` long along z (the
    plane and its images k ``length`` away): the force the contacts straddling it exert on their lower
    member, over the plane's ``area`` (the method of planes; Todd, Evans & Daivis 1995). In steady
    homogeneous shear its x component is the shear stress tau = -sigma_xz, its z component the normal
    stress sigma_zz, less their kinetic parts (the momentum particles carry across)."""
    i, force, branch = contacts["i"], contacts["force"], contacts["branch"]
    zi = positions[i, 2]  # the pair: i at z_i, its partner's nearest image at z_i - b_z
    zj = zi - branch[:, 2]
    low, high = np.minimum(zi, zj), np.maximum(zi, zj)
    k = np.floor((high - plane) / length)  # the image of the plane at or just below the higher member
    across = low < plane + k * length
    on_lower = np.where((zi < zj)[:, None], force, -force)  # the force on i, or on its partner
    return on_lower[across].sum(axis=0) / area


def rigid_limit_offset(soft: float, stiff: float, ratio: float) -> float:
    """How much the solid fraction ``soft`` of spheres exceeds rigid ones', from ``stiff``, the same
    at a Young's modulus ``ratio`` times larger: under a pressure P a Hertz packing's contacts are
    compressed in proportion to (P / E*)^(2/3), so phi = phi_rigid + c (P / E*)^(2/3) and the two give
    phi_rigid = (k stiff - soft) / (k - 1), k = ratio^(2/3)."""
    k = ratio ** (2.0 / 3.0)
    return soft - (k * stiff - soft) / (k - 1.0)


def run_quietly(sim: Simulation, *args, **kwargs) -> None:
    """``sim.run``, without the warning that the flow's speeds lowered the automatic dt a little."""
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message=".*dt is lowered")
        sim.run(*args, **kwargs)


def shear_scene(p: dict) -> tuple[Simulation, float]:
    """The packing of ``p``'s spheres compressed isotropically to P at rest: (simulation, mean
    diameter)."""
    d = 2.0 * p["radius"]
    solid = p["count"] * math.pi / 6.0 * d ** 3 * (1.0 + p["polydispersity"] ** 2)  # <r^3> of the uniform radii
    side = (solid / INSERTED_FRACTION) ** (1.0 / 3.0)
    rate = p["inertial_number"] * math.sqrt(p["pressure"] / p["density"]) / d
    sim = Simulation(contact=ContactModel("hertz", rolling=resolve_rolling(p["model"])), gravity=(0.0, 0.0, 0.0),
                     periodic={a: (0.0, side) for a in "xyz"},
                     lees_edwards=LeesEdwards(shear_rate=0.0, gradient="z"))
    sim.add_material(Material("spheres", youngs_modulus=p["youngs_modulus"], poisson_ratio=p["poisson_ratio"],
                              density=p["density"], friction=p["mu"], rolling_friction=p["mur"], restitution=p["e"],
                              rolling_damping=p["eta_r"]))
    radius = Uniform(p["radius"] * (1.0 - p["polydispersity"]), p["radius"] * (1.0 + p["polydispersity"]))
    sim.insert(BoxRegion((0.0, 0.0, 0.0), (side, side, side)), p["count"], radius, "spheres", seed=p["seed"],
               max_attempts=2000)
    if sim.n_particles < p["count"]:
        raise ParameterError(f"count = {p['count']} is not allowed: only {sim.n_particles} spheres found room at a "
                             f"solid fraction of {INSERTED_FRACTION}")
    servo = BoxServo(p["pressure"], "xyz", effective_modulus(sim))
    rest = REST_ENERGY * p["pressure"] * d ** 3
    for _ in range(p["max_moves"]):
        run_quietly(sim, steps=CHUNK)
        pressure = servo.move(sim, stress_now(sim))
        if abs(pressure - p["pressure"]) < PRESSURE_WITHIN * p["pressure"] and \
                sum(sim.kinetic_energy()) < rest * sim.n_particles:
            break
    sim.shear.shear_rate = rate
    return sim, d


def shear_run(p: dict) -> dict:
    """The compressed packing sheared at the shear rate of ``inertial_number`` to ``strain``, the
    first ``transient`` of it left out: mu, phi, I (means over the samples) and their standard errors."""
    start = time.perf_counter()
    sim, d = shear_scene(p)
    rate = sim.shear.shear_rate
    x = sim.positions
    lo, hi = sim.periodic["z"]
    v = sim.velocities
    v[:, 0] = rate * (x[:, 2] - 0.5 * (lo + hi))  # the affine profile: steady shear from the start
    sim.set_velocities(np.arange(sim.n_particles), velocity=v)
    z_servo = BoxServo(p["pressure"], "z", effective_modulus(sim))
    solid = float(np.sum(4.0 / 3.0 * math.pi * sim.radii ** 3))
    chunk = int(np.clip(round(1.0 / (rate * sim.dt * SAMPLES_PER_STRAIN)), 1, CHUNK))
    moves = max(1, int(round(p["strain"] / (rate * sim.dt * chunk))))
    first = int(round(p["transient"] / p["strain"] * moves))
    rows = []
    for k in range(moves):
        run_quietly(sim, steps=chunk)
        contacts = sim.contact_forces()
        sigma = stress_now(sim, contacts)
        if k >= first:
            (lo, hi), volume = sim.periodic["z"], box_volume(sim)
            end = plane_traction(contacts, sim.positions, lo, hi - lo, volume / (hi - lo))
            contact_part = box_stress(contacts["force"], contacts["branch"], [], [], volume)
            rows.append((-sigma[0, 2] / sigma[2, 2], solid / volume, sigma[2, 2], end[0], -contact_part[0, 2]))
        z_servo.move(sim, sigma)
    mu, phi, normal, end_tau, tau = (np.array(c) for c in zip(*rows))
    inertial = rate * d / np.sqrt(np.maximum(normal, 1e-300) / p["density"])
    return {"friction": float(mu.mean()), "friction_error": batch_standard_error(mu),
            "solid_fraction": float(phi.mean()), "solid_fraction_error": batch_standard_error(phi),
            "inertial_number": float(inertial.mean()), "normal_stress": float(normal.mean()),
            "end_traction_ratio": float(end_tau.mean() / tau.mean()),
            "end_traction_error": batch_standard_error(end_tau / tau.mean()),
            "shear_rate": rate, "samples": len(rows), "steps": moves * chunk, "wall_time": time.perf_counter() - start}


def flow_parameters() -> tuple[Parameter, ...]:
    """The rolling model and the contact coefficients of the rheology rigs (mu may be 0: frictionless)."""
    return (Parameter("model", "epsd", "rolling resistance model", choice="rolling"),
            Parameter("mu", 0.5, "sliding friction coefficient", low=0.0, calibration_range=(0.0, 1.0)),
            Parameter("mur", 0.0, "rolling friction coefficient", low=0.0, calibration_range=(0.0, 0.6)),
            Parameter("eta_r", 0.3, "rolling viscous damping ratio", low=0.0, high=1.0),
            Parameter("e", 0.5, "coefficient of restitution", low=0.0, high=1.0, low_open=True))


class SimpleShear(BedExperiment):
    """Steady simple shear at a constant normal stress between Lees-Edwards boundaries."""

    name = "simple-shear"
    description = ("steady simple shear of a polydisperse sphere packing between Lees-Edwards boundaries at a constant "
                   "normal stress: the friction mu = tau / P and the solid fraction against the inertial number")
    parameters = flow_parameters() + (
                  Parameter("inertial_number", 0.01, "the inertial number I the shear rate is set by: "
                                                     "gamma_dot = I d / sqrt(P / rho)", low=0.0, low_open=True, high=1.0),
                  Parameter("pressure", 1000.0, "the normal stress P held on the shear plane", "Pa", low=0.0,
                            low_open=True),
                  Parameter("count", 500, "spheres", low=50, integer=True),
                  Parameter("radius", 5e-4, "mean sphere radius R", "m", low=0.0, low_open=True),
                  Parameter("polydispersity", 0.2, "radii uniform in R (1 +- p)", low=0.0, high=0.5),
                  Parameter("youngs_modulus", 1e7, "Young's modulus", "Pa", low=0.0, low_open=True),
                  Parameter("poisson_ratio", 0.25, "Poisson's ratio", low=0.0, high=0.5),
                  Parameter("density", 2500.0, "the spheres' density rho", "kg/m^3", low=0.0, low_open=True),
                  Parameter("strain", 3.0, "shear strain run", low=0.0, low_open=True),
                  Parameter("transient", 1.0, "shear strain left out before the samples", low=0.0),
                  Parameter("max_moves", 3000, "most servo moves of the compression", low=1, integer=True),
                  Parameter("seed", 1, "random seed (insertion)", low=0, integer=True))
    observables = {"friction": "-: tau / P, the macroscopic friction in steady shear",
                   "solid_fraction": "-: the packing's solid fraction in steady shear",
                   "inertial_number": "-: I = gamma_dot d / sqrt(P / rho) at the measured normal stress"}
    default_observable = "friction"
    targets = {"friction": (0.0, 2.0), "solid_fraction": (0.3, 0.74)}

    def check(self, params: dict) -> None:
        if params["transient"] >= params["strain"]:
            raise ParameterError(f"transient = {params['transient']!r} is not allowed: must be below strain = "
                                 f"{params['strain']!r}")

    def observe(self, params: dict) -> dict:
        self.check(params)
        return shear_run(params)

    sizes = {"quick": {"count": 500, "strain": 2.0, "transient": 1.0},
             "full": {"count": 2000, "strain": 5.0, "transient": 2.0}}

    def validate(self, quick=False, outdir=None, progress=None, runner=map, model="epsd") -> ValidationResult:
        """mu(I) and phi(I) at the ``INERTIAL_NUMBERS`` for frictionless spheres and for mu = 0.5 at each
        of the ``ROLLING_FRICTIONS`` (``model``), each series fitted (``fit_mu_of_i``, ``fit_phi_of_i``
        over I <= 0.1). Checks: the frictionless series' mu_s and phi_max against Peyneau & Roux's; the
        frictional one's mu_s against glass beads'; mu_s rises and phi_max falls with mu_r (for a model
        that holds a moment at rest: a ``CREEPING`` one's are reported); the contacts' traction across the
        sheared end equals the box's mean shear stress within 2 % (I <= 0.03)."""
        tic = time.perf_counter()
        base = {"model": model, **self.sizes["quick" if quick else "full"]}
        series = [dict(base, mu=0.0, mur=0.0)] + [dict(base, mu=0.5, mur=m) for m in ROLLING_FRICTIONS]
        points = [self.resolve(dict(s, inertial_number=i)) for s in series for i in INERTIAL_NUMBERS]
        # frictionless spheres STIFFER times stiffer at one slow point: phi extrapolated to rigid ones
        points.append(self.resolve(dict(series[0], inertial_number=RIGID_POINT,
                                        youngs_modulus=STIFFER * self.by_name["youngs_modulus"].default)))
        every = run_points(self, points, [1], runner, progress)
        # the I each point was run at (the observable of the same name is the I measured)
        every["target_inertial_number"] = [p["inertial_number"] for p in points]
        stiff = every["youngs_modulus"] > self.by_name["youngs_modulus"].default
        runs = every[~stiff]
        fits, rows = {}, []
        for (mu, mur), grp in runs.groupby(["mu", "mur"], sort=True):
            dense = grp[grp["target_inertial_number"] <= 0.1 + 1e-12]
            f, g = fit_mu_of_i(grp["inertial_number"], grp["friction"]), fit_phi_of_i(dense["inertial_number"],
                                                                                  dense["solid_fraction"])
            fits[(mu, mur)] = (f, g)
            rows.append({"mu": mu, "mur": mur, "mu_s": f["mu_s"], "mu_s error": f["mu_s_error"], "mu_2": f["mu_2"],
                         "I_0": f["i_0"], "phi_max": g["phi_max"], "phi_max error": g["phi_max_error"], "a": g["a"],
                         "wall_time": float(grp["wall_time"].sum())})
        table = pd.DataFrame(rows)
        fl, fr = fits[(0.0, 0.0)], fits[(0.5, 0.0)]
        name = self.name
        soft = runs[(runs["mu"] == 0.0) & (runs["target_inertial_number"] == RIGID_POINT)]
        rigid_offset = rigid_limit_offset(float(soft["solid_fraction"].iloc[0]),
                                          float(every[stiff]["solid_fraction"].iloc[0]), STIFFER)
        table["phi_max rigid"] = np.where(table["mu"] == 0.0, table["phi_max"] - rigid_offset, np.nan)
        checks = [Check(name, model, "frictionless spheres: mu_s", fl[0]["mu_s"], FRICTIONLESS_MU_S, 0.03, relative=False,
                        source="Peyneau & Roux 2008 (frictionless beads in homogeneous shear: internal friction "
                               "about 0.1); tolerance: the extrapolation to I -> 0"),
                  Check(name, model, f"frictionless spheres: phi_max of rigid spheres (phi_max {fl[1]['phi_max']:.4f} "
                        f"less {rigid_offset:.4f}, from a run {STIFFER:g} x stiffer at I = {RIGID_POINT:g})",
                        fl[1]["phi_max"] - rigid_offset, RCP_FRACTION, 0.01,
                        relative=False, source="random close packing, 0.639 (Agnolin & Roux 2007); Peyneau & Roux "
                                               "2008: slow shear keeps it; tolerance: polydispersity raises it "
                                               "(Desmond & Weeks 2014), the fit's and extrapolation's errors"),
                  Check(name, model, "mu = 0.5, mu_r = 0: mu_s", fr[0]["mu_s"], GLASS_MU_S, 0.05, relative=False,
                        source="glass beads, tan 20.9 deg (GDR MiDi 2004; Jop et al. 2006); tolerance: bead friction "
                               "and shape differ")]
        with_rolling = table[np.isclose(table["mu"], 0.5)].sort_values("mur")
        notes = []
        for quantity, sign in (("mu_s", 1.0), ("phi_max", -1.0)):
            steps = sign * np.diff(with_rolling[quantity].to_numpy())
            if model in CREEPING:
                notes.append(f"{quantity} against mu_r ({', '.join(f'{m:g}' for m in with_rolling['mur'])}): "
                             f"{', '.join(f'{v:.3f}' for v in with_rolling[quantity])}. {model} cannot hold a moment "
                             "at rest (docs/models.md §11.6): in slow flow its rolling resistance fades, so neither "
                             "need change monotonically with mu_r; reported, not checked.")
                continue
            checks.append(Check(name, model, f"smallest {'rise' if sign > 0 else 'fall'} of {quantity} between "
                                f"successive mu_r ({', '.join(f'{m:g}' for m in with_rolling['mur'])})",
                                float(steps.min()), 0.0, 0.0, bound="lower",
                                source="rolling resistance adds to the sliding friction's resistance to flow and "
                                       "holds looser packings (Estrada et al. 2011: the bulk friction rises with it)"))
        dense = runs[runs["target_inertial_number"] <= 0.03 + 1e-12]
        weights = 1.0 / np.maximum(dense["end_traction_error"].to_numpy(), 1e-6) ** 2
        ratio = float(np.sum(weights * dense["end_traction_ratio"]) / np.sum(weights))
        checks.append(Check(name, model, "contact traction across the sheared end / the box's mean contact shear "
                            f"stress (I <= 0.03, {len(dense)} runs, +-{1.0 / math.sqrt(weights.sum()):.3f})",
                            ratio, 1.0, 0.02, source="momentum balance: in steady homogeneous shear every plane "
                                                     "carries the same traction, the sheared end included"))
        result = ValidationResult(name, f"Simple shear ({model}{', quick' if quick else ''})", table, checks,
                                  notes=notes + [f"{base['count']} spheres (R = 0.5 mm +- 20 %, E = 10 MPa, e = 0.5) at "
                                         "P = 1 kPa ((E*/P)^(2/3) = 305), sheared to a strain of "
                                         f"{base['strain']:g}, the first {base['transient']:g} left out; mu = tau / "
                                         "sigma_zz and phi averaged over the rest. docs/studies.md, \"Simple shear\"."])
        if outdir is not None:
            every.to_csv(f"{outdir}/simple-shear-runs.csv", index=False)  # each run's point and observables
            self.figure(result, runs, fits, outdir)
        result.wall_time = time.perf_counter() - tic
        return result

    @staticmethod
    def figure(result, runs, fits, outdir) -> None:
        """mu(I) and phi(I) of each series with its fits."""
        plt = pyplot()
        fig, axes = plt.subplots(1, 2, figsize=(10, 4))
        grid = np.logspace(-3, math.log10(0.3), 60)
        for (mu, mur), grp in runs.groupby(["mu", "mur"], sort=True):
            label = "frictionless" if mu == 0.0 else f"mu = {mu:g}, mu_r = {mur:g}"
            f, g = fits[(mu, mur)]
            line = axes[0].errorbar(grp["inertial_number"], grp["friction"], yerr=2 * grp["friction_error"], fmt="o",
                                    capsize=2, label=label)[0]
            axes[0].plot(grid, mu_of_i(grid, f["mu_s"], f["mu_2"], f["i_0"]), "-", color=line.get_color())
            axes[1].plot(grp["inertial_number"], grp["solid_fraction"], "o", color=line.get_color(), label=label)
            axes[1].plot(grid, g["phi_max"] - g["a"] * grid, "-", color=line.get_color())
        for ax, what in ((axes[0], "mu = tau / P"), (axes[1], "solid fraction")):
            ax.set_xscale("log")
            ax.set_xlabel("inertial number I")
            ax.set_ylabel(what)
        axes[0].legend(fontsize=7)
        result.add_figure(fig, outdir, "simple_shear.png")
