"""Mutation check: does the test suite catch a wrong physics factor?

Each mutation below is a one-line error put into a copy of the package (``src/`` and ``tests/``
copied to a temporary folder); the tests named with it are run there against the copy. A
mutation is *caught* when at least one of them fails. The unmutated copy is run first and must
pass, or the table means nothing.

    python tests/mutations.py                 # every mutation; a table at the end
    python tests/mutations.py --list          # the mutations, not run
    python tests/mutations.py --only epsd     # those whose name contains 'epsd' (repeatable)

Exit status 0 when every mutation is caught, 1 otherwise, 2 for bad arguments. Not part of the
default suite (each mutation recompiles what it touches: 20 s to 2 min each on 2 cores).
"""

from __future__ import annotations

import argparse
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


@dataclass(frozen=True)
class Mutation:
    name: str
    file: str        # relative to the repository root
    original: str    # must occur exactly once in the file
    replacement: str
    tests: tuple     # pytest node ids or files, relative to the repository root


M = Mutation
C = "src/rollingdem/physics/contact/"
K = ("tests/physics/test_submodel_kernels.py", "tests/physics/test_rolling_kernel.py")  # the kernels called on their own
HERTZ = K + ("tests/physics/test_hertz_damping.py",)
TWIST = K + ("tests/physics/test_twisting.py",)
A = "src/rollingdem/analysis/repose.py"
PILES = ("tests/analysis/test_analysis.py",)
WB = ("tests/physics/test_walton_braun.py",)
WT = ("tests/physics/test_walton_tangential.py",)
COH = ("tests/physics/test_cohesion.py",)
BOND = ("tests/scene/test_bonds.py",)
GPU = ("tests/engine/test_cuda.py::test_the_simulated_gpu_steps_bit_for_bit_as_the_cpu_engine",)
CLUMP = ("tests/scene/test_clump_motion.py",)
CG = ("tests/experiments/test_coarse_graining.py",)
MUTATIONS = [
    # --- normal (contact/normal.py) and the material pair ------------------------------------------
    M("hertz k_n = 4/3 E* a -> E* a", C + "normal.py", "kn = (4.0 / 3.0) * p[P_YOUNG] * a", "kn = 1.0 * p[P_YOUNG] * a", HERTZ),
    M("hertz S_t = 8 G* a -> 4 G* a", C + "normal.py", "st = 8.0 * p[P_SHEAR] * a", "st = 4.0 * p[P_SHEAR] * a", HERTZ),
    M("hertz S_n = 2 E* a -> E* a", C + "normal.py", "sn = 2.0 * p[P_YOUNG] * a", "sn = 1.0 * p[P_YOUNG] * a", HERTZ),
    M("hertz tangential dashpot halved", C + "normal.py", "gamma_n * p[params_at + HERTZ_PARAMETERS.tangential_damping_ratio]",
      "0.5 * gamma_n * p[params_at + HERTZ_PARAMETERS.tangential_damping_ratio]", HERTZ),
    M("hertz damping factor sqrt(5/6) -> sqrt(2/3)", C + "normal.py", "math.sqrt(5.0 / 6.0) * restitution_beta(e)",
      "math.sqrt(2.0 / 3.0) * restitution_beta(e)", HERTZ),
    M("hooke stiffness 16/15 -> 4/3", C + "normal.py", "(16.0 / 15.0) * sr * young", "(4.0 / 3.0) * sr * young", K),
    M("hooke tangential dashpot halved", C + "normal.py",
      "HOOKE_PARAMETERS.tangential_stiffness_ratio] * kn,\n            gamma_n, 0.0)",
      "HOOKE_PARAMETERS.tangential_stiffness_ratio] * kn,\n            0.5 * gamma_n, 0.0)", K),
    M("linear shear dashpot from k_n", C + "normal.py", "shear_damping_factor] * math.sqrt(m_eff * ks)",
      "shear_damping_factor] * math.sqrt(m_eff * kn)", K),
    M("effective shear modulus: factor 2 lost", "src/rollingdem/scene/materials.py", "inv = (2.0 * (2.0 - a.poisson_ratio)",
      "inv = ((2.0 - a.poisson_ratio)", K),
    M("walton_braun k2 = k1/e^2 -> k1/e", C + "normal.py", "ratio = 1.0 / pair.restitution ** 2",
      "ratio = 1.0 / pair.restitution", WB),
    M("walton_braun keeps the clipped force", C + "normal.py",
      "hist[k, history_at + WALTON_BRAUN_HISTORY.force_unclipped] = f\n",
      "hist[k, history_at + WALTON_BRAUN_HISTORY.force_unclipped] = max(f, 0.0)\n", WB),
    M("walton_braun hysteresis with the end-of-step force", C + "normal.py", "0.5 * (f_old + f_el) * step",
      "f_el * step", WB),
    M("walton_braun equivalent stiffness 16/15 -> 4/3", C + "normal.py", "(16.0 / 15.0) * sr * young",
      "(4.0 / 3.0) * sr * young", WB),
    M("jkr adhesion sqrt(8 pi w E* a^3) -> sqrt(6 ...)", C + "cohesion.py", "- 2.0 * young * c * a * x -",
      "- 1.5 * young * c * a * x -", COH),
    M("jkr separation 3 a_f^2 / R* -> 4", C + "cohesion.py", "JKR_HISTORY.separation_limit] = 3.0 * x_f ** 4",
      "JKR_HISTORY.separation_limit] = 4.0 * x_f ** 4", COH),
    M("jkr energy without the surface term", C + "cohesion.py", "+ math.pi * surface_energy * a2)", "+ 0.0 * a2)",
      COH),
    M("sjkr circle 4 d^2 -> 2 d^2", C + "cohesion.py", "/ (4.0 * d * d)", "/ (2.0 * d * d)", COH),
    M("sjkr wall circle 2 R -> R", C + "cohesion.py", "overlap * (2.0 * ri - overlap)", "overlap * (ri - overlap)",
      COH),
    M("bond bending stiffness from k_s", "src/rollingdem/scene/bonds.py", "kn * area, ks * area, kn * bending",
      "kn * area, ks * area, ks * bending", BOND),
    M("bond compression weakens in shear", "src/rollingdem/physics/bonds.py", "p[BOND_PARAMETERS.cohesion] - fn / area",
      "p[BOND_PARAMETERS.cohesion] + fn / area", BOND),
    M("bond shear not carried with the frame", "src/rollingdem/physics/bonds.py",
      "    carry_with_frame(state, b, BOND_STATE.shear_x, frame)\n", "", BOND),
    M("bond normal dashpot with the wrong sign", "src/rollingdem/physics/bonds.py", "fn_total = fn + cn * vcn",
      "fn_total = fn - cn * vcn", BOND),
    M("bond moment factor left out of the tensile stress", "src/rollingdem/physics/bonds.py",
      "sigma = fn / area + beta *", "sigma = fn / area + 0.0 *", BOND),
    M("rolling resistance on a parallel-bonded contact", "src/rollingdem/engine/template/contact.py",
      "return contact_of(hist, k, g, p, dt, False)", "return contact_of(hist, k, g, p, dt, True)", BOND),
    M("a parallel bond taken for an exclusive one", "src/rollingdem/engine/template/pairs.py",
      "apart = bonded(uint64(i), uint64(j), particles, True)", "apart = bonded(uint64(i), uint64(j), particles, False)",
      BOND),
    # --- tangential (contact/tangential.py) ------------------------------------------------------
    M("walton shrinking branch normalised by mu N - T*", C + "tangential.py",
      "room = 1.0 - (turning - t) / (mu_n + turning)", "room = 1.0 - (turning - t) / (mu_n - turning)", WT),
    M("walton turning point not taken", C + "tangential.py", "turning = t  # a turning point",
      "turning = turning  # a turning point", WT),
    M("walton T* keeps its sign through zero", C + "tangential.py", "        turning = -turning\n",
      "        turning = turning\n", WT),
    M("walton force not scaled with N", C + "tangential.py", "scale = n_force / n_before", "scale = 1.0", WT),
    M("coulomb limit on abs(F_n) instead of max(F_n, 0)", C + "tangential.py", "limit = p[P_FRICTION] * max(normal_force, 0.0)",
      "limit = p[P_FRICTION] * abs(normal_force)", K),
    M("tangential history not carried with the frame", C + "tangential.py",
      "    gamma_t = normal[NR.tangential_damping]\n    carry_with_frame(hist, k, history_at, frame)\n",
      "    gamma_t = normal[NR.tangential_damping]\n", K),
    M("tangential spring backed out without the dashpot", C + "tangential.py", "xx = -(fx + gamma_t * vtx) / kt",
      "xx = -fx / kt", K),
    M("tangential spring backed out through a dashpot above the cap", C + "tangential.py",
      "if kt > 0.0 and gamma_t * gamma_t * (vtx * vtx + vty * vty + vtz * vtz) < limit * limit:", "if kt > 0.0:", K),
    M("tangential dissipation ignores the stored energy", C + "tangential.py", "stored_before = 0.5 * kt *",
      "stored_before = 0.0 * kt *", K),
    M("frame spin rotated the wrong way", C + "frame.py", "hx = rx * cs + cx * sn + nx * nd * (1.0 - cs)",
      "hx = rx * cs - cx * sn + nx * nd * (1.0 - cs)", K),
    # --- rolling (contact/rolling.py) ------------------------------------------------------------
    M("epsd stiffness prefactor 2.25 -> 2.0", C + "rolling.py",
      "    def stiffness_coefficient(self):\n        return 2.25", "    def stiffness_coefficient(self):\n        return 2.0", K),
    M("spring rolling k_r: mu_r^2 -> mu_r", C + "rolling.py", "k_r = coefficient * kn * mu_r * mu_r * r_eff * r_eff",
      "k_r = coefficient * kn * mu_r * r_eff * r_eff", K),
    M("rolling dashpot 2 sqrt(I k) -> sqrt(I k)", C + "rolling.py", "c_r = eta * 2.0 * math.sqrt(inertia_r * k_r)",
      "c_r = eta * math.sqrt(inertia_r * k_r)", K),
    M("sds rolling damping R*^2 -> R*", C + "rolling.py", "c_r = damping * r_eff * r_eff", "c_r = damping * r_eff", K),
    M("rolling limit on abs(F_n,el) instead of max(F_n,el, 0)", C + "rolling.py", "f_lim = max(force_elastic, 0.0)",
      "f_lim = abs(force_elastic)", K),
    M("rolling history not carried with the frame", C + "rolling.py",
      "        carry_with_frame(hist, k, history_at, frame)\n    elif", "        pass\n    elif", K),
    M("recommended slip damping 1 -> 0", C + "rolling.py", "None: (CAP_TOTAL, FORCE_ELASTIC, HISTORY_FRAME, 0, 1.0)",
      "None: (CAP_TOTAL, FORCE_ELASTIC, HISTORY_FRAME, 0, 0.0)", K),
    M("spring at the cap not backed out of the dashpot", C + "rolling.py",
      "            sx = mx - slip_damping * c_r * rx\n", "            sx = mx\n", K),
    M("rolling dissipation ignores the released spring energy", C + "rolling.py",
      "        dissipated += 0.5 * ((trial_x", "        dissipated += 0.0 * ((trial_x", K),
    M("epsd without the pair's rolling damping", C + "rolling.py",
      "    def damping_value(self, pair):\n        return -1.0 if self.damping_ratio is None else self.damping_ratio\n\n"
      "    def settings(self):\n        return {\"damping_ratio\"",
      "    def damping_value(self, pair):\n        return 0.0 if self.damping_ratio is None else self.damping_ratio\n\n"
      "    def settings(self):\n        return {\"damping_ratio\"", K),
    M("displacement damping mobilised on abs(F_total)", C + "rolling.py", "k_r = moment_max / coefficient",
      "k_r = mu_r * r_eff * abs(force_total) / coefficient", K),
    M("lammps parity on the elastic force", C + "rolling.py", "\"lammps\": (CAP_TOTAL, FORCE_ABS_TOTAL, HISTORY_PROJECT, 0, 1.0)",
      "\"lammps\": (CAP_TOTAL, FORCE_ELASTIC, HISTORY_PROJECT, 0, 1.0)", K),
    M("liggghts parity with slip damping", C + "rolling.py", "\"liggghts\": (CAP_SPRING, FORCE_ABS_TOTAL, HISTORY_GLOBAL, 1, 0.0)",
      "\"liggghts\": (CAP_SPRING, FORCE_ABS_TOTAL, HISTORY_GLOBAL, 1, 1.0)", K),
    M("cdt on abs(F_total)", C + "rolling.py", "moment = p[P_ROLLING_FRICTION] * r_eff * max(force_elastic, 0.0) * rate / norm",
      "moment = p[P_ROLLING_FRICTION] * r_eff * abs(force_total) * rate / norm", K),
    M("viscous kratos form without its R*", C + "rolling.py", "        s *= r_eff\n", "        s *= 1.0\n", K),
    M("force proportional: levers swapped", C + "rolling.py", "si = f * lever_i / a", "si = f * lever_j / a", K),
    # --- twisting (contact/twisting.py) ----------------------------------------------------------
    M("marshall limit 2/3 a -> a/2", C + "twisting.py", "limit = (2.0 / 3.0) * math.sqrt(a2)", "limit = 0.5 * math.sqrt(a2)", TWIST),
    M("marshall k_tw = k_t a^2/2 -> k_t a^2", C + "twisting.py", "k_tw = 0.5 * kt * a2", "k_tw = kt * a2", TWIST),
    M("marshall gamma_tw = gamma_t a^2/2 -> gamma_t a^2", C + "twisting.py", "g_tw = 0.5 * gamma_t * a2", "g_tw = gamma_t * a2", TWIST),
    M("marshall limit with mu_r instead of mu", C + "twisting.py", "math.sqrt(a2) * p[P_FRICTION]", "math.sqrt(a2) * p[3]", TWIST),
    M("twisting sds limit on abs(F_n,el)", C + "twisting.py", "twisting_friction] * max(force_elastic, 0.0)",
      "twisting_friction] * abs(force_elastic)", TWIST),
    M("twist rate: n_z dropped", C + "twisting.py", "spin = dwx * nx + dwy * ny + dwz * nz", "spin = dwx * nx + dwy * ny + dwz", TWIST),
    # --- the repose-angle estimator (analysis.py) -----------------------------------------------
    M("repose slope biased by 1.5 %", A, "angle = math.degrees(math.atan(p[1]))",
      "angle = math.degrees(math.atan(1.015 * p[1]))", PILES),
    M("repose cone fit without its robust loss", A, 'loss="soft_l1"', 'loss="linear"', PILES),
    M("repose fit without the toe clearance", A,
      "r_hi = min(r_hi, (p_prev[0] - floor - TOE_CLEARANCE * d_mean) / p_prev[1])", "r_hi = r_hi", PILES),
    M("repose surface without the first-layer cut", A, " & (x[cand, 2] - floor >= 2.0 * a[cand])", "", PILES),
    M("repose fit without the outlier (MAD) cut", A, "inl = np.abs(r - med) <= 3.0 * sigma",
      "inl = np.abs(r - med) <= np.inf * sigma", PILES),
    M("pile radius: largest sector instead of the median", A, "return float(np.median(ext))",
      "return float(np.max(ext))", PILES),
    # --- cases, bench, walls ---------------------------------------------------------------------
    M("repose case: the angle check compares EPSD2 with itself", "src/rollingdem/experiments/repose.py",
      'for m in ("epsd2", "epsd")]', 'for m in ("epsd2", "epsd2")]',
      ("tests/experiments/test_pile_cases.py::test_angle_check_of_case_3_on_stand_in_piles",)),
    M("repose column 10 % too narrow", "src/rollingdem/experiments/pile.py",
      "tube = (solid / (PACKING * math.pi * 2.0 * aspect)) ** (1.0 / 3.0)",
      "tube = 0.9 * (solid / (PACKING * math.pi * 2.0 * aspect)) ** (1.0 / 3.0)",
      ("tests/engine/test_parallel.py::test_column_size_holds_the_spheres",)),
    M("bench counts each contact once", "src/rollingdem/bench.py",
      'return (2 * stats["pair_contacts"] + stats["wall_contacts"]) / n',
      'return (stats["pair_contacts"] + stats["wall_contacts"]) / n', ("tests/test_bench.py",)),
    M("bench rate over half the wall time", "src/rollingdem/bench.py", "particle_steps_per_s=n * steps / wall,",
      "particle_steps_per_s=n * steps / (0.5 * wall),", ("tests/test_bench.py",)),
    M("cylinder wall overlap off by 20 nm", "src/rollingdem/physics/walls.py", "overlap = r + ri - R",
      "overlap = r + ri - R + 2e-8", ("tests/engine/test_engine.py::test_cylinder_wall_holds_particles",)),
    M("cylinder's outer face pulls as the inner one", "src/rollingdem/physics/walls.py", "overlap = R + ri - r",
      "overlap = r + ri - R", ("tests/engine/test_engine.py::test_cylinder_wall_outer_face_and_rim",)),
    M("cylinder's rim left out", "src/rollingdem/physics/walls.py", "if d < ri and d > 0.0:",
      "if d < 0.0:", ("tests/engine/test_engine.py::test_cylinder_wall_outer_face_and_rim",)),
    M("cylinder's rim normal without its radial part", "src/rollingdem/physics/walls.py",
      "nx = (ds * ux + dr * qx / r) / d", "nx = (ds * ux) / d",
      ("tests/engine/test_engine.py::test_cylinder_wall_outer_face_and_rim",)),
    # --- the GPU's neighbor-list rebuild, on the simulator (gpu_neighbors.py) ------------------------
    M("GPU rebuild drops the carried history", "src/rollingdem/engine/cuda/neighbors.py",
      "lists.pool[q, s] = rebuild.carry[c, s]", "lists.pool[q, s] = 0.0", GPU),
    M("GPU transposed index left in the atomics' order", "src/rollingdem/engine/cuda/neighbors.py",
      "self.counting_sort(lists.j, lists.tr_start, lists.tr_k, entries, n, True)",
      "self.counting_sort(lists.j, lists.tr_start, lists.tr_k, entries, n, False)", GPU),
    M("GPU bench phases timed on the run's own arrays", "src/rollingdem/engine/cuda/step_loop.py",
      "self._upload(host, m.HISTORY_SIZE, copy=True)", "self._upload(host, m.HISTORY_SIZE, copy=False)", GPU),
    M("mass flow counts a crossing back as forward", "src/rollingdem/io/measurements.py",
      "sign = np.where(new[crossed] >= 0.0, 1, -1)", "sign = np.ones(int(crossed.sum()), dtype=int)",
      ("tests/io/test_measurements.py",)),
    M("mass flow disk radius doubled", "src/rollingdem/io/measurements.py",
      "crossed &= np.einsum(\"ij,ij->i\", lateral, lateral) <= self.radius ** 2",
      "crossed &= np.einsum(\"ij,ij->i\", lateral, lateral) <= 4 * self.radius ** 2", ("tests/io/test_measurements.py",)),
    M("probe solid fraction with diameters", "src/rollingdem/io/measurements.py",
      "float((4.0 / 3.0 * math.pi * r ** 3).sum()) / volume", "float((4.0 / 3.0 * math.pi * (2 * r) ** 3).sum()) / volume",
      ("tests/io/test_measurements.py",)),
    M("probe kinetic energy without rotation", "src/rollingdem/io/measurements.py",
      "+ inertia * np.einsum(\"ij,ij->i\", w, w))", ")", ("tests/io/test_measurements.py",)),
    M("probe counts a clump's members as spheres", "src/rollingdem/io/measurements.py",
      "each[member] = m[member] / bodies[\"mass\"][clump[member]] * body[clump[member]]", "pass",
      ("tests/scene/test_clump_motion.py::test_a_probe_counts_a_clump_s_kinetic_energy_as_a_body_s",)),
    M("wall power with the wrong sign", "src/rollingdem/io/measurements.py",
      "power = -(f @ velocity + t @ angular_velocity)", "power = (f @ velocity + t @ angular_velocity)",
      ("tests/io/test_measurements.py",)),
    M("settled threshold ten times higher", "src/rollingdem/scene/conditions.py",
      "return 1e-6 * float(sim.masses[free].mean())", "return 1e-5 * float(sim.masses[free].mean())",
      ("tests/io/test_measurements.py",)),
    M("settled without its hold time", "src/rollingdem/scene/conditions.py",
      "return sim.time - self._below_since >= self.hold - 0.5 * sim.dt", "return True",
      ("tests/io/test_measurements.py",)),
    M("resume keeps the rows written after the checkpoint", "src/rollingdem/io/runner.py",
      "if int(line.split(b\",\", 2)[1]) > step or not line.endswith(b\"\\n\"):", "if not line.endswith(b\"\\n\"):",
      ("tests/scene/test_resume.py",)),
    M("rpm read as rad/s", "src/rollingdem/io/casefile.py", "check_finite(\"motion rotate rpm\", r.rpm) * 2.0 * np.pi / 60.0",
      "check_finite(\"motion rotate rpm\", r.rpm)", ("tests/experiments/test_case_experiment.py",)),
    M("profile bias with the wrong sign", "src/rollingdem/io/rig_measurements.py",
      "d = heights - self.points[:, 1]", "d = self.points[:, 1] - heights",
      ("tests/io/test_measurements.py",)),
    M("profile minimum at the parabola's top", "src/rollingdem/studies/calibration.py",
      "    if a <= 0:\n        return best", "    if a >= 0:\n        return best", ("tests/experiments/test_case_experiment.py",)),
    M("minimum interval held to the first five points", "src/rollingdem/studies/calibration.py",
      "draws = [local_minimum(x, means + errors * rng.standard_normal(len(x))) for _ in range(replicates)]",
      "near = _around_lowest(means)\n    draws = [parabola_minimum(x[near], means[near] + errors[near] * rng.standard_normal(5))"
      " for _ in range(replicates)]", ("tests/experiments/test_case_experiment.py",)),
    M("drum profile summary: each sample's misfit, not the averaged surface's", "src/rollingdem/io/rig_measurements.py",
      "out[q][\"value\"] = out[q][\"of_mean_surface\"] = v", "out[q][\"of_mean_surface\"] = v",
      ("tests/io/test_measurements.py", "tests/experiments/test_case_experiment.py")),
    M("mesh region: a ray's crossings counted, not their parity", "src/rollingdem/physics/mesh.py",
      "out[p] = crossings % 2 == 1", "out[p] = crossings >= 1", ("tests/io/test_measurements.py", "tests/scene/test_insertion.py")),
    M("mesh region: a point on a shared edge inside both triangles", "src/rollingdem/physics/mesh.py",
      "    return dy > 0.0 or (dy == 0.0 and bx < ax)", "    return True", ("tests/scene/test_insertion.py",)),
    M("refill puts every sphere back as the first material", "src/rollingdem/scene/boundaries.py",
      "self.waiting_material = np.concatenate([self.waiting_material, st.mat[spheres].astype(np.int64)])",
      "self.waiting_material = np.concatenate([self.waiting_material, 0 * st.mat[spheres].astype(np.int64)])",
      ("tests/scene/test_outlets_inflows.py",)),
    M("refill puts back a sphere of the mean radius", "src/rollingdem/scene/boundaries.py",
      "self.waiting_radius = np.concatenate([self.waiting_radius, st.radius[spheres]])",
      "self.waiting_radius = np.concatenate([self.waiting_radius, 0 * st.radius[spheres] + st.radius.mean()])",
      ("tests/scene/test_outlets_inflows.py",)),
    M("drum flow reads the drum's turn about the wrong sense", "src/rollingdem/io/rig_measurements.py",
      "omega = float(np.asarray(wall.angular_velocity, float) @ self.axis) if wall is not None else math.nan",
      "omega = -float(np.asarray(wall.angular_velocity, float) @ self.axis) if wall is not None else math.nan",
      ("tests/experiments/test_drum.py",)),
    M("drum flow's frame leaves the up direction out", "src/rollingdem/io/rig_measurements.py",
      "basis = np.column_stack([across, up, self.axis])  # a turn: distances kept",
      "basis = np.column_stack([across, across, self.axis])  # a turn: distances kept", ("tests/experiments/test_drum.py",)),
    M("drum weight moment without g", "src/rollingdem/io/rig_measurements.py",
      "abs(g * float(m @ frame[:, 0]))]", "abs(float(m @ frame[:, 0]))]", ("tests/experiments/test_drum.py",)),
    M("mesh file read without welding", "src/rollingdem/scene/mesh.py",
      "    if tolerance <= 0.0 or len(unique) < 2:", "    if True:", ("tests/scene/test_mesh.py",)),
    M("cylinder drawn at its diameter", "src/rollingdem/io/observers.py",
      "ring = wall.radius * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))",
      "ring = 2.0 * wall.radius * (np.outer(np.cos(phi), u) + np.outer(np.sin(phi), v))", ("tests/io/test_outputs.py",)),
    M("cohesion that does nothing let through", "src/rollingdem/scene/timestep.py",
      'if cohesion.name != "none" and n and not any(', 'if False and not any(', ("tests/test_bad_input.py",)),
    M("oscillation without its 2 pi", "src/rollingdem/scene/motion.py",
      "row[MO.omega] = 2.0 * math.pi * self.frequency", "row[MO.omega] = self.frequency", ("tests/scene/test_wall_motion.py",)),
    M("a programmed plane's contacts see its steady velocity", "src/rollingdem/engine/integrator.py",
      "walls.velocity[wl, 0], walls.velocity[wl, 1], walls.velocity[wl, 2] = mo[MO.tvx], mo[MO.tvy], mo[MO.tvz]",
      "walls.velocity[wl, 0], walls.velocity[wl, 1], walls.velocity[wl, 2] = mo[MO.vx], mo[MO.vy], mo[MO.vz]",
      ("tests/scene/test_wall_motion.py",)),
    M("a programmed mesh's contacts see its steady velocity", "src/rollingdem/engine/mesh_passes.py",
      "return mo[m, MO.tvx] + (wy * rz - wz * ry), mo[m, MO.tvy] + (wz * rx - wx * rz), mo[m, MO.tvz] + (wx * ry - wy * rx)",
      "return mo[m, MO.vx] + (wy * rz - wz * ry), mo[m, MO.vy] + (wz * rx - wx * rz), mo[m, MO.vz] + (wx * ry - wy * rx)",
      ("tests/scene/test_wall_motion.py",)),
    M("servo load of the wrong sign", "src/rollingdem/engine/wall_motion.py",
      "load = -(fx * mo[MO.ax] + fy * mo[MO.ay] + fz * mo[MO.az])", "load = fx * mo[MO.ax] + fy * mo[MO.ay] + fz * mo[MO.az]",
      ("tests/scene/test_wall_motion.py",)),
    M("servo speed not limited", "src/rollingdem/engine/wall_motion.py",
      "speed = min(max(mo[MO.gain] * (mo[MO.target] - load), -mo[MO.max_speed]), mo[MO.max_speed])",
      "speed = mo[MO.gain] * (mo[MO.target] - load)", ("tests/scene/test_wall_motion.py",)),
    M("a table's angle column read as its first", "src/rollingdem/engine/wall_motion.py",
      "out3 = table[k, TR.angle] + frac * (table[k + 1, TR.angle] - table[k, TR.angle]) - table[first, TR.angle]",
      "out3 = table[k, TR.dx] + frac * (table[k + 1, TR.dx] - table[k, TR.dx]) - table[first, TR.dx]",
      ("tests/scene/test_wall_motion.py",)),
    M("a mesh's program turn dropped", "src/rollingdem/engine/mesh_passes.py",
      "angle = (wx * ux + wy * uy + wz * uz) * tau + turned", "angle = (wx * ux + wy * uy + wz * uz) * tau",
      ("tests/scene/test_wall_motion.py",)),
    M("clump cap: the disk's x^2 moment doubled", "src/rollingdem/scene/clumps.py",
      "across = np.polynomial.Polynomial([r2, 0.0, -1.0]) ** 2 * (math.pi / 4.0)",
      "across = np.polynomial.Polynomial([r2, 0.0, -1.0]) ** 2 * (math.pi / 2.0)", ("tests/scene/test_clumps.py",)),
    M("clump lens: the circle's plane at the middle", "src/rollingdem/scene/clumps.py",
      "plane = (d * d + ri * ri - rj * rj) / (2.0 * d)", "plane = d / 2.0", ("tests/scene/test_clumps.py",)),
    M("clump: three overlapping members not noticed", "src/rollingdem/scene/clumps.py",
      "return any(partners.get(j, set()) & partners.get(i, set()) for i, j in pairs)", "return False",
      ("tests/scene/test_clumps.py",)),
    M("rigid body: the middle turn half as long", "src/rollingdem/engine/rigid_body.py",
      "_turn(2, pz * dt / moments[2]", "_turn(2, pz * h / moments[2]", ("tests/scene/test_rigid_body.py",)),
    M("rigid body: the body frame turned the wrong way", "src/rollingdem/engine/rigid_body.py",
      "    return (vx + qw * tx + (qy * tz - qz * ty),", "    return (vx - qw * tx + (qy * tz - qz * ty),",
      ("tests/scene/test_rigid_body.py",)),
    M("clump torque: r x f with its sign flipped", "src/rollingdem/engine/rigid_body.py",
      "tx += t[m, 0] + ry * f[m, 2] - rz * f[m, 1]", "tx += t[m, 0] - ry * f[m, 2] + rz * f[m, 1]", CLUMP),
    M("clump: the member's own torque left out", "src/rollingdem/engine/rigid_body.py",
      "ty += t[m, 1] + rz * f[m, 0] - rx * f[m, 2]", "ty += rz * f[m, 0] - rx * f[m, 2]", CLUMP),
    M("clump: its weight left out", "src/rollingdem/engine/rigid_body.py",
      "F[0], F[1], F[2] = fx + M * gravity[0], fy + M * gravity[1], fz + M * gravity[2]",
      "F[0], F[1], F[2] = fx, fy, fz", CLUMP),
    M("clump members' weight at their own centres too", "src/rollingdem/engine/template/gather.py",
      "mg = 0.0 if member else mi", "mg = mi", CLUMP),
    M("clump member's velocity without omega x r", "src/rollingdem/engine/rigid_body.py",
      "v[m, 0] = V[0] + oy * rz - oz * ry", "v[m, 0] = V[0]", CLUMP),
    M("clump: the closing kick of L doubled", "src/rollingdem/engine/rigid_body.py",
      "                    L[d] += 0.5 * dt * T[d]\n", "                    L[d] += dt * T[d]\n", CLUMP),
    M("clump members' mass the whole clump's", "src/rollingdem/scene/rigid_bodies.py",
      "share = np.tile(props.mass * volumes / volumes.sum(), m)", "share = np.tile(props.mass + 0.0 * volumes, m)",
      CLUMP),
    M("an outlet's refill forgets the clumps", "src/rollingdem/scene/boundaries.py",
      "self.waiting_clumps.append((st.body_offset[members].copy(),", "((st.body_offset[members].copy(),", CLUMP),
    M("clump members pair with each other", "src/rollingdem/engine/neighbors.py",
      "if clump_i >= 0 and clump[j] == clump_i:", "if clump_i >= 0 and clump[j] == clump_i and False:", CLUMP),
    M("clump onset: the footprint's farthest point, not the hull", "src/rollingdem/scene/clumps.py",
      "reach = np.min(-offsets[going > 1e-12] / going[going > 1e-12])", "reach = np.max(support @ e2)",
      ("tests/scene/test_clumps.py",)),
    M("mesh flow counts a shared edge twice", "src/rollingdem/io/measurements.py",
      "for p in np.flatnonzero(hit.sum(axis=1) > 1):", "for p in []:", ("tests/io/test_measurements.py",)),
    # --- coarse graining (docs/models.md §18) --------------------------------------------------------
    M("coarse graining: sds rolling damping as alpha", C + "rolling.py",
      "2 if self.damping_mode == DAMPING_GIVEN else 0", "1 if self.damping_mode == DAMPING_GIVEN else 0", CG),
    M("coarse graining: jkr w unscaled", C + "cohesion.py", "return (1,)  # pull-off", "return (0,)  # pull-off", CG),
    M("coarse graining: twisting sds mu_tw unscaled", C + "twisting.py", "return (0, 3, 4, 1)", "return (0, 3, 4, 0)",
      CG),
    M("coarse graining: the pair takes the smaller alpha", "src/rollingdem/scene/materials.py",
      "coarse_graining=max(a.coarse_graining, b.coarse_graining))",
      "coarse_graining=min(a.coarse_graining, b.coarse_graining))", CG),
    M("coarse graining: insert counts parcels", "src/rollingdem/scene/particles.py",
      "count = max(1, int(round(check_count(\"count\", count) / alpha ** 3)))",
      "count = max(1, int(round(check_count(\"count\", count) / 1.0)))", CG),
    M("coarse graining: linear time step from the unscaled k_n", C + "normal.py",
      "kn, ks = self.pair_row(pair)[:2]  # as the parcels meet them", "kn, ks = self.normal_stiffness, self.shear_stiffness",
      CG),
]


def _copy_tree(dest: Path) -> None:
    ignore = shutil.ignore_patterns("__pycache__", "*.pyc", ".pytest_cache")
    for part in ("src", "tests"):
        shutil.copytree(ROOT / part, dest / part, ignore=ignore)
    shutil.copy2(ROOT / "pyproject.toml", dest / "pyproject.toml")


def _run_tests(copy: Path, tests) -> tuple[int, list[str], str]:
    """pytest on the copy; (exit code, failed test ids, last output lines)."""
    # caches of its own per copy: Numba's cache does not notice an edit in a module whose function
    # was inlined into another module's cached function (frame.py into rolling.py)
    env = dict(os.environ, PYTHONPATH=str(copy / "src"), ROLLINGDEM_CACHE_DIR=str(copy / "kernels"),
               NUMBA_CACHE_DIR=str(copy / "numba-cache"), ROLLINGDEM_PRECOMPILE="0", PYTHONDONTWRITEBYTECODE="1")
    # the copy's package must be the one imported, not an installed one
    where = subprocess.run([sys.executable, "-c", "import rollingdem; print(rollingdem.__file__)"],
                           cwd=copy, env=env, capture_output=True, text=True)
    if not where.stdout.strip().startswith(str(copy)):
        raise SystemExit(f"error: the copy at {copy} is not the package imported ({where.stdout.strip()}"
                         f"{where.stderr.strip()[-300:]}); uninstall the editable install or run from a clean venv")
    proc = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-rf", *tests],
                          cwd=copy, env=env, capture_output=True, text=True)
    failed = re.findall(r"^FAILED (\S+)", proc.stdout, flags=re.M)
    tail = "\n".join((proc.stdout + proc.stderr).strip().splitlines()[-3:])
    return proc.returncode, failed, tail


def _apply(copy: Path, m: Mutation) -> None:
    path = copy / m.file
    text = path.read_text()
    count = text.count(m.original)
    if count != 1:
        raise SystemExit(f"error: mutation {m.name!r}: its original text occurs {count} times in {m.file}, "
                         "must occur once (the source changed: update the mutation)")
    path.write_text(text.replace(m.original, m.replacement))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--list", action="store_true", help="list the mutations and exit")
    parser.add_argument("--only", action="append", default=None,
                        help="run the mutations whose name contains this text (repeatable: any of them)")
    args = parser.parse_args(argv)
    chosen = [m for m in MUTATIONS if args.only is None or any(t in m.name for t in args.only)]
    if args.list:
        for m in MUTATIONS:
            print(f"{m.name}: {m.file}")
        return 0
    if not chosen:
        print(f"error: --only = {args.only!r} matches no mutation (see --list)", file=sys.stderr)
        return 2

    work = Path(tempfile.mkdtemp(prefix="rollingdem-mutations-"))
    try:
        base = work / "base"
        _copy_tree(base)
        all_tests = sorted({t for m in chosen for t in m.tests})
        t0 = time.perf_counter()
        code, failed, tail = _run_tests(base, all_tests)
        if code != 0:
            print(f"error: the unmutated copy fails its tests ({', '.join(failed) or tail}): fix that first",
                  file=sys.stderr)
            return 1
        print(f"unmutated copy: {len(all_tests)} test files pass ({time.perf_counter() - t0:.0f} s)", flush=True)
        rows = []
        for i, m in enumerate(chosen):
            copy = work / f"m{i}"
            _copy_tree(copy)
            _apply(copy, m)
            t0 = time.perf_counter()
            code, failed, tail = _run_tests(copy, m.tests)
            caught = code != 0
            if caught and not failed:
                failed = [tail.splitlines()[-1] if tail else f"exit {code}"]
            rows.append((m.name, caught, failed, time.perf_counter() - t0))
            print(f"{'caught' if caught else 'MISSED'}  {m.name}  ({len(failed)} failing)", flush=True)
            shutil.rmtree(copy, ignore_errors=True)
    finally:
        shutil.rmtree(work, ignore_errors=True)

    print("\n| mutation | caught | failing tests | s |\n|---|---|---|---|")
    for name, caught, failed, seconds in rows:
        shown = ", ".join(f.split("::")[-1] for f in failed[:3]) + (f" (+{len(failed) - 3})" if len(failed) > 3 else "")
        print(f"| {name} | {'yes' if caught else '**no**'} | {shown} | {seconds:.0f} |")
    missed = [r for r in rows if not r[1]]
    print(f"\n{len(rows) - len(missed)} of {len(rows)} mutations caught")
    return 1 if missed else 0


if __name__ == "__main__":
    sys.exit(main())
