"""Hashes of the final state of a fixed set of runs: a refactor that changes no result leaves them
all equal, bit for bit.

    python benchmarks/result_hashes.py --write before.json      # record (1 and 2 threads)
    python benchmarks/result_hashes.py --check before.json      # after the change: exit 1 if any differs
    python benchmarks/result_hashes.py --scene slab --threads 1  # a part of it

Scenes (each hashed from its state: positions, velocities, angular velocities, forces, torques,
and the energies it tracks):

- ``collapse``: the bench's settled 20,000-sphere column (``rollingdem.bench.settled_column``, from
  the disk cache or settled now, a few minutes), cylinder removed, 300 steps. The settled start is
  hashed too: a column cached by another version of the code shows up as a different start.
- ``slab``: the bench's slab of 20,000 spheres falling onto the plate, 300 steps.
- ``mixture``: 3,000 spheres of two materials with a per-pair override, radii uniform in
  R (1 +- 0.2), EPSD with Marshall twisting and energy tracking, poured into a cylinder, 2,000 steps.
- ``walls``: 1,500 spheres in a cylinder turning about its axis on a rising plate; then the
  cylinder is removed, the plate stopped and gravity tilted, 1,000 steps each.
- ``hopper``: a turning mesh hopper fed by an inflow, drained by an outlet below it, 400
  spheres at the start; 3,000 steps, a checkpoint restored, 1,000 more steps.
- ``bonded``: an x-periodic slab of bonded spheres on a bed of fixed spheres, sheared by a moving
  plane, 2,000 steps.
- ``rolling-flat/<model>``: the validation case 1 run of every rolling model (one sphere, 0.3 s).

Every scene runs on each thread count asked for; the hashes must agree across them (the engine is
bit-identical for any thread count) and, with ``--check``, with the recorded file. Floating-point
results depend on the processor's instruction set, so compare runs made on one machine.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np


def state_hash(sim) -> str:
    h = hashlib.sha256()
    for a in (sim.positions, sim.velocities, sim.angular_velocities, sim.forces, sim.torques):
        h.update(np.ascontiguousarray(a, dtype=np.float64).tobytes())
    h.update(np.float64(sim.time).tobytes())
    if sim.track_energy:
        h.update(json.dumps(sim.dissipated_energy(), sort_keys=True).encode())
    return h.hexdigest()[:16]


def collapse() -> dict:
    from rollingdem.bench import _collapse, settled_column

    sim = settled_column(20000, echo=lambda m: print(m, file=sys.stderr))
    start = state_hash(sim)
    _collapse(sim).run(steps=300)
    return {"start": start, "end": state_hash(sim)}


def slab() -> dict:
    from rollingdem.bench import _slab_simulation

    sim = _slab_simulation(20000)
    sim.run(steps=300)
    return {"end": state_hash(sim)}


def mixture_simulation():
    """The mixture scene, poured but not yet stepped."""
    import rollingdem as rd

    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd", twisting="marshall"), dt=1e-5,
                        track_energy=True)
    sim.add_material(rd.Material("soft", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2, restitution=0.5,
                                 rolling_damping=0.3))
    sim.add_material(rd.Material("hard", 2e8, 0.3, 2500, friction=0.4, rolling_friction=0.05, restitution=0.8,
                                 rolling_damping=0.1))
    sim.set_pair("soft", "hard", friction=0.6, rolling_friction=0.1)
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="hard", name="plate"))
    sim.add_wall(rd.Cylinder(0.06, material="hard", name="tube"))
    sizes = rd.Uniform(0.004, 0.006)
    sim.insert(rd.CylinderRegion(0.06, 0.0, 0.3), 1500, sizes, "soft", seed=3)
    sim.insert(rd.CylinderRegion(0.06, 0.3, 0.6), 1500, sizes, "hard", seed=4)
    return sim


def mixture() -> dict:
    sim = mixture_simulation()
    sim.run(steps=2000)
    return {"end": state_hash(sim)}


def walls() -> dict:
    import rollingdem as rd

    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt"), dt=1e-5)
    sim.add_material(rd.Material("m", 40e6, 0.49, 1056, friction=0.8, rolling_friction=0.2, restitution=0.5))
    sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1), material="m", name="plate"))
    sim.add_wall(rd.Cylinder(0.05, material="m", name="tube"))
    sim.insert(rd.CylinderRegion(0.05, 0.0, 0.4), 1500, 0.005, "m", seed=5)
    sim.run(steps=1000)
    sim.set_wall_velocity("tube", angular_velocity=(0.0, 0.0, 3.0))
    sim.set_wall_velocity("plate", velocity=(0.0, 0.0, 0.05))
    sim.run(steps=1000)
    middle = state_hash(sim)
    sim.remove_wall("tube")
    sim.set_wall_velocity("plate", velocity=(0.0, 0.0, 0.0))
    sim.gravity = (1.5, 0.0, -9.7)
    sim.run(steps=1000)
    return {"middle": middle, "end": state_hash(sim)}


def hopper() -> dict:
    import tempfile

    import rollingdem as rd

    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="epsd"), dt=1e-5)
    sim.add_material(rd.Material("m", 5e7, 0.3, 2500, friction=0.5, rolling_friction=0.1, restitution=0.6))
    sim.add_wall(rd.MeshWall.shape("hopper", top_radius=0.06, outlet_radius=0.018, height=0.08, material="m",
                                   name="hopper", angular_velocity=(0.0, 0.0, 2.0)))
    sim.insert(rd.CylinderRegion(0.045, 0.08, 0.16), 400, rd.Uniform(0.0035, 0.0045), "m", seed=7,
              velocity=(0.0, 0.0, -1.5))
    sim.add_outlet(rd.BoxRegion((-0.1, -0.1, -0.2), (0.1, 0.1, 0.06)), name="out", interval=2e-4)
    sim.add_inflow(rd.CylinderRegion(0.04, 0.17, 0.22), radius=0.004, material="m", rate=5000, seed=2,
                   velocity=(0.0, 0.0, -0.5), interval=3e-4)
    sim.run(steps=3000)
    middle = state_hash(sim) + json.dumps(sim.boundary_counts(), sort_keys=True)
    with tempfile.TemporaryDirectory() as folder:
        sim = rd.Simulation.restore(sim.checkpoint(Path(folder) / "c.npz"))
    sim.set_wall_velocity("hopper", angular_velocity=(0.0, 0.0, -1.0))
    sim.run(steps=1000)
    return {"middle": hashlib.sha256(middle.encode()).hexdigest()[:16],
            "end": state_hash(sim) + "/" + json.dumps(sim.boundary_counts(), sort_keys=True)}


def bonded() -> dict:
    import rollingdem as rd

    sim = rd.Simulation(contact=rd.ContactModel("hertz", rolling="cdt", twisting="marshall"), dt=2e-6,
                        periodic={"x": (0.0, 0.06)})
    sim.add_material(rd.Material("m", 5e7, 0.3, 2500, friction=0.5, rolling_friction=0.1, restitution=0.6))
    r = 0.0025
    grid = np.array([[(i + 0.5) * 2 * r, (j + 0.5) * 2 * r, 0.0] for i in range(12) for j in range(6)])
    sim.add_particles(grid, r, "m", fixed=True)
    slab = np.concatenate([grid + (0.0, 0.0, 2 * r * k) for k in (1, 2, 3)])
    sim.add_particles(slab, r, "m", allow_overlap=True)
    sim.add_bonds(rd.ParallelBond(youngs_modulus=5e7, tensile_strength=2e4, cohesion=2e4), gap=1e-6)
    sim.add_wall(rd.Plane(point=(0.0, 0.0, 7 * r + 1e-6), normal=(0, 0, -1), material="m", name="lid",
                          velocity=(0.5, 0.0, -0.05)))
    sim.add_wall(rd.Plane(point=(0.0, -r, 0.0), normal=(0, 1, 0), material="m"))
    sim.add_wall(rd.Plane(point=(0.0, 12 * r + r, 0.0), normal=(0, -1, 0), material="m"))
    sim.run(steps=2000)
    return {"end": state_hash(sim) + "/" + json.dumps(sim.bond_counts(), sort_keys=True)}


def rolling_flat(label, model) -> dict:
    """Validation case 1 (``rollingdem.experiments.single_sphere``): the sphere settled 0.2 s on the
    wall, launched at 1 m/s with no spin, 0.3 s of rolling."""
    from rollingdem.experiments.single_sphere import DT, sphere_on_wall

    sim = sphere_on_wall(model, settle=0.0)
    sim.run(steps=round(0.2 / DT))
    sim.set_velocities([0], velocity=(1.0, 0.0, 0.0), angular_velocity=(0.0, 0.0, 0.0))
    sim.run(steps=round(0.3 / DT))
    return {"end": state_hash(sim)}


def scenes() -> dict:
    from rollingdem.experiments.single_sphere import validation_models

    out = {"collapse": collapse, "slab": slab, "mixture": mixture, "walls": walls, "hopper": hopper, "bonded": bonded}
    for label, model in validation_models().items():
        out[f"rolling-flat/{label}"] = (lambda lb=label, m=model: rolling_flat(lb, m))
    return out


def main(argv=None) -> int:
    all_scenes = scenes()
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", action="append", default=None, help="a scene (repeatable; default: all)")
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="thread counts (default: 1 2)")
    parser.add_argument("--write", type=Path, default=None, help="write the hashes to this JSON file")
    parser.add_argument("--check", type=Path, default=None, help="compare with this JSON file; exit 1 if any differs")
    args = parser.parse_args(argv)
    unknown = [s for s in (args.scene or []) if s not in all_scenes]
    if unknown:
        print(f"error: --scene = {unknown[0]!r} is not known: allowed are {', '.join(all_scenes)}", file=sys.stderr)
        return 2
    import numba

    bad = [t for t in args.threads if not 1 <= t <= numba.config.NUMBA_NUM_THREADS]
    if bad:
        print(f"error: --threads = {bad[0]} is not allowed: must be in [1, {numba.config.NUMBA_NUM_THREADS}]",
              file=sys.stderr)
        return 2
    if args.check is not None and not args.check.is_file():
        print(f"error: --check = {str(args.check)!r} is not allowed: no such file", file=sys.stderr)
        return 2

    from rollingdem.engine.threads import fix_threads

    results, ok = {}, True
    for name in args.scene or list(all_scenes):
        per_thread = {}
        for t in args.threads:
            fix_threads(t)
            per_thread[t] = all_scenes[name]()
        first = per_thread[args.threads[0]]
        same = all(v == first for v in per_thread.values())
        ok &= same
        results[name] = first
        print(f"{name:32s} {' '.join(f'{k}={v}' for k, v in first.items())}"
              + ("" if same else f"  THREADS DIFFER: {per_thread}"), flush=True)
    if args.write is not None:
        args.write.write_text(json.dumps(results, indent=1, sort_keys=True) + "\n")
        print(f"written: {args.write}")
    if args.check is not None:
        recorded = json.loads(args.check.read_text())
        for name, value in results.items():
            if name not in recorded:
                print(f"{name}: not in {args.check}")
            elif recorded[name] != value:
                ok = False
                print(f"DIFFERS {name}: recorded {recorded[name]}, now {value}")
        print("all equal" if ok else "some differ")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
