"""The time-step policy of a scene: the limits of docs/models.md §2 on the spheres in place and
those an inflow will insert (``rollingdem.physics.timestep`` holds the criteria), the largest dt
they allow, and the checks a run makes before its first step."""

from __future__ import annotations

import math
import warnings

import numpy as np

from rollingdem.errors import ParameterError
from rollingdem.physics.timestep import SPRING_FRACTION
from rollingdem.scene.particles import SOLID_SPHERE, sphere_mass


class TimeStepPolicy:
    """The time step of a scene: its limits, the largest stable step, and the run's checks, on the
    engine state, contact law, materials, walls, inflows and bonds it is given; the settings the
    checks weigh (dt, whether it is automatic, the pair table, the clock, skin) are handed to each
    call. ``passed``: (scene key, fastest speeds) when dt last passed ``check``."""

    def __init__(self, state, contact, materials, wall_set, boundaries, bond_set):
        self.state = state
        self.contact = contact
        self.materials = materials
        self.wall_set = wall_set
        self.boundaries = boundaries
        self.bond_set = bond_set
        self.passed = None

    def limits(self, wall_speed: float | None = None) -> list[tuple[str, float]]:
        """``Simulation.time_step_limits``; with ``wall_speed`` (m/s), as if the fastest wall surface
        moved that fast (a stage's wall motion before it is set)."""
        st, contact, materials, inflows = self.state, self.contact, self.materials, self.boundaries.inflows
        if st.n == 0 and not inflows:
            return []
        limits = []
        normal = contact.normal
        # a sphere meets a wall at its own speed plus the wall surface's there
        walls = max((w.peak_speed(st.x) for w in self.wall_set.in_place()), default=0.0) if wall_speed is None \
            else wall_speed
        for k, mat in enumerate(materials.materials):
            sel = st.mat == k
            # the spheres an inflow will insert count as if they were there
            coming = [(i.radius.min_radius, float(np.linalg.norm(i.velocity))) for i in inflows
                      if materials.index(i.material) == k]
            if not sel.any() and not coming:
                continue
            rmin = min(([float(st.radius[sel].min())] if sel.any() else []) + [r for r, _ in coming])
            mmin = min(([float(st.mass[sel].min())] if sel.any() else [])
                       + [sphere_mass(mat.density, r) for r, _ in coming])
            pair = materials.pair(k, k)
            speed = np.sqrt((st.v[sel] ** 2).sum(axis=1))
            fastest = max([float(speed[np.isfinite(speed)].max(initial=0.0))] + [v for _, v in coming])
            impact = max(2.0 * fastest, fastest + walls)  # a non-finite v is reported apart
            limits += normal.time_step_limits(mat, pair, rmin, mmin, impact)
            limits += contact.cohesion.time_step_limits(mat, pair, rmin, mmin)
            r_eff = 0.5 * rmin
            kn, kt, overlap = normal.reference_stiffness(pair, r_eff, 0.5 * mmin, rmin)
            inertia = SOLID_SPHERE * mmin * rmin ** 2
            for sub in (contact.rolling, contact.twisting):
                k_rot = sub.rotational_stiffness(kn, kt, r_eff, overlap, kn * overlap, pair)
                if k_rot > 0:
                    # worst case, centres held: omega^2 = k_rot (1/I_i + 1/I_j)
                    per = 2.0 * math.pi / math.sqrt(k_rot * 2.0 / inertia)
                    limits.append((f"{sub.slot} spring ({sub.name}) period {per:.4g} s / 10", SPRING_FRACTION * per))
        limits += self.bond_set.time_step_limits()
        return limits

    def stable(self) -> float:
        """The largest dt all criteria allow (s)."""
        limits = self.limits()
        if not limits:
            raise ParameterError("dt cannot be chosen automatically before particles are added: give dt")
        return min(v for _, v in limits)

    def check(self, dt: float, automatic: bool, pair_table, time: float, hint: str) -> float:
        """The dt to step with: ``dt``, or a smaller one where an ``automatic`` dt is above a stable
        limit now (with a warning at the clock's ``time``); a given dt above one is refused (``hint``:
        how the user turns the check off). ``pair_table``: the pair parameters dt was checked with."""
        # Between runs of an unchanged scene only the speeds change, and the one limit that depends
        # on them (the Hertz time at the impact speed) falls as they rise: while no material's
        # fastest sphere is faster than when dt last passed, it still passes, and a loop of short
        # runs (a trajectory sampled every 10 steps) skips the full check.
        speeds = self.fastest_per_material()
        key = (dt, self.state.n, len(self.boundaries.inflows), pair_table)
        seen = self.passed
        if seen is not None and seen[0][:3] == key[:3] and seen[0][3] is key[3] and (speeds <= seen[1]).all():
            return dt
        for label, limit in self.limits():
            if dt > limit * (1 + 1e-12) and automatic:
                # an automatic dt follows the scene: the speeds have grown since it was chosen
                old, dt = dt, self.stable()
                warnings.warn(f"at t = {time:.6g} s dt is lowered from {old:.4g} s to {dt:.4g} s, the stable "
                              f"limit now ({label}): the speeds have grown since it was chosen", RuntimeWarning,
                              stacklevel=5)
                key = (dt,) + key[1:]
                break
            if dt > limit * (1 + 1e-12):
                raise ParameterError(f"dt = {dt:.4g} s exceeds the stable limit {limit:.4g} s "
                                     f"({label}): choose dt <= {limit:.4g} s, or {hint} to run anyway")
        self.passed = (key, speeds)
        return dt

    def check_contact_reach(self, skin: float) -> None:
        """A cohesion law whose contacts last past touching (``jkr``) needs the neighbor list to
        reach that far: refuse a ``skin`` shorter than the largest pair's separation limit. A cohesion
        law whose parameter is 0 for every material pair is refused too: it would do nothing."""
        cohesion, materials = self.contact.cohesion, self.materials
        st = self.state
        n = len(materials.materials)
        if cohesion.name != "none" and n and not any(
                any(v != 0.0 for v in cohesion.pair_values(materials.pair(a, b))) for a in range(n) for b in range(n)):
            what = "surface_energy (J/m^2)" if cohesion.name == "jkr" else "cohesion_energy_density (J/m^3)"
            raise ParameterError(f"cohesion = {cohesion.name!r} is not allowed here: every material pair's "
                                 f"{what.split(' ')[0]} is 0, so it would do nothing; give the materials (or a pair) "
                                 f"a {what}, or use cohesion 'none'")
        if cohesion.detach_slot is None or st.n == 0:
            return
        r_eff = 0.5 * float(st.radius.max())
        reach = max(cohesion.separation_limit(materials.pair(a, b), r_eff) for a in range(n) for b in range(n))
        if reach > skin:
            raise ParameterError(f"skin = {skin:.4g} m is not allowed with cohesion {cohesion.name!r}: its "
                                 f"contacts last until the spheres are {reach:.4g} m apart, and the neighbor list "
                                 f"must reach that far; give skin >= {reach:.4g} m")

    def fastest_per_material(self) -> np.ndarray:
        """Each material's largest finite particle speed squared (0 without particles of it)."""
        st = self.state
        out = np.zeros(len(self.materials.materials))
        if st.n and len(out):
            speed2 = np.einsum("ij,ij->i", st.v, st.v)
            fastest = speed2.max()
            if len(out) == 1 and math.isfinite(fastest):
                out[0] = fastest
            else:
                np.maximum.at(out, st.mat, np.where(np.isfinite(speed2), speed2, 0.0))
        return out
