"""The rollingdem side of benchmarks/peers_dense.sh: the dense beds at rest, on the identical state.

  prepare WORKDIR                  the two scenes' states as dumps the peers read (dense.dump: the settled
                                   20,000-sphere column of ``rollingdem bench --scene dense-bed``; rough.dump:
                                   the ``--scene rough-bed`` bed on its rough base, fixed spheres of type 2),
                                   LAMMPS data files of them (dense.data, rough.data) and the -var arguments
                                   of the peers' inputs (dense.vars, rough.vars)
  time SCENE DUMP STEPS THREADS JSON FINAL
                                   rollingdem (EPSD, bench's TABLE1, DT, SKIN) from DUMP, one untimed step,
                                   then STEPS timed steps on THREADS threads: the figures to JSON, the state
                                   after them to FINAL (a dump)
  summary WORKDIR                  the medians of the rounds and rollingdem / the faster peer, per scene and
                                   process count; then the three codes' last states side by side: atoms, dt,
                                   steps, contacts per sphere, speeds, displacements

All three codes start from positions and velocities alone (angular velocities and contact histories zero:
the peers' read_dump and read_data hold no more). SCENE is dense or rough.
"""
from __future__ import annotations

import json
import re
import sys
from pathlib import Path

import numpy as np

from rollingdem import bench

SCENES = {"dense": "dense bed at rest (settled column, cylinder kept)", "rough": "rough-base bed"}


def _state(scene):
    """(positions, velocities, fixed mask or None, -var arguments, box (lo, hi)) of the scene's bench state."""
    if scene == "dense":
        sim = bench.settled_column(20000)
        rcyl = bench.column_radius(sim.n_particles)
        ztop = float(np.ceil((sim.positions[:, 2].max() + 0.04) * 100) / 100)
        lo, hi = (-rcyl - 0.01, -rcyl - 0.01, -0.01), (rcyl + 0.01, rcyl + 0.01, ztop)
        return sim.positions, sim.velocities, None, f"-var rcyl {rcyl!r} -var ztop {ztop!r}", (lo, hi)
    sim = bench.rough_bed_simulation(20000, True)
    fixed = sim.fixed.astype(bool)
    half = bench.rough_bed_half_width(int((~fixed).sum()))
    ztop = float(np.ceil((sim.positions[:, 2].max() + 0.04) * 100) / 100)
    lo, hi = (-half - 0.01, -half - 0.01, -0.01), (half + 0.01, half + 0.01, ztop)
    return sim.positions, sim.velocities, fixed, f"-var half {half!r} -var ztop {ztop!r}", (lo, hi)


def _write_data(path, x, v, fixed, box):
    """A LAMMPS atom_style sphere data file of the state (diameter 2 RADIUS, density TABLE1's), types as the dump's."""
    n = len(x)
    types = np.ones(n, dtype=int) if fixed is None else np.where(fixed, 2, 1)
    with open(path, "w") as fh:
        fh.write(f"rollingdem bench state\n\n{n} atoms\n{int(types.max())} atom types\n\n")
        for axis, lo, hi in zip("xyz", *box):
            fh.write(f"{lo!r} {hi!r} {axis}lo {axis}hi\n")
        fh.write("\nAtoms # sphere\n\n")
        np.savetxt(fh, np.column_stack([np.arange(1, n + 1), types, np.full(n, 2 * bench.RADIUS),
                                        np.full(n, bench.TABLE1["density"]), x]),
                   fmt=["%d", "%d", "%.10g", "%.10g", "%.10g", "%.10g", "%.10g"])
        fh.write("\nVelocities\n\n")
        np.savetxt(fh, np.column_stack([np.arange(1, n + 1), v, np.zeros((n, 3))]),
                   fmt=["%d"] + ["%.10g"] * 6)


def prepare(work):
    work = Path(work)
    for scene in SCENES:
        x, v, fixed, args, box = _state(scene)
        bench.write_liggghts_dump(work / f"{scene}.dump", x, v, bench.RADIUS, fixed=fixed)
        _write_data(work / f"{scene}.data", x, v, fixed, box)
        (work / f"{scene}.vars").write_text(args + "\n")
        print(f"{scene}: {len(x)} spheres ({0 if fixed is None else int(fixed.sum())} fixed), {args}")


def time_scene(scene, dump, steps, threads, json_out, final):
    from rollingdem.engine.threads import fix_threads

    fix_threads(threads)
    sim = bench.column_from_dump(dump) if scene == "dense" else bench.rough_bed_from_dump(dump)
    wall, rebuilds = bench._time_run(sim, steps)
    fixed = sim.fixed.astype(bool) if len(sim.fixed) else None
    bench.write_liggghts_dump(final, sim.positions, sim.velocities, bench.RADIUS, fixed=fixed)
    r = bench._result(f"{scene}-bed-peers", "epsd", sim, steps, 0.0, wall, rebuilds, threads,
                      f"{SCENES[scene]} from {dump}", split_repeats=2)
    bench.write_json([r], json_out)
    doc = json.loads(Path(json_out).read_text())
    doc["dt"] = sim.dt
    Path(json_out).write_text(json.dumps(doc, indent=2))


def _dump(path):
    d = bench._read_dump(path, ("id", "type", "x", "y", "z", "vx", "vy", "vz", "radius"))
    return d[np.argsort(d[:, 0], kind="stable")]


def _contacts(scene, d):
    """Contacts per sphere of a state (pairs counted for both, walls once, as rollingdem counts them):
    touching pairs but those of two fixed spheres, free spheres touching a wall."""
    from scipy.spatial import cKDTree

    x, r, fixed = d[:, 2:5], d[:, 8], d[:, 1] == 2
    pairs = cKDTree(x).query_pairs(2 * r.max(), output_type="ndarray")
    i, j = pairs[:, 0], pairs[:, 1]
    touching = (np.linalg.norm(x[i] - x[j], axis=1) < r[i] + r[j]) & ~(fixed[i] & fixed[j])
    free = ~fixed
    walls = x[free, 2] < r[free]
    if scene == "dense":
        walls |= np.hypot(x[free, 0], x[free, 1]) > bench.column_radius(len(x)) - r[free]
    else:
        half = bench.rough_bed_half_width(int(free.sum()))
        walls |= (np.abs(x[free, 0]) > half - r[free]) | (np.abs(x[free, 1]) > half - r[free])
    return (2 * touching.sum() + walls.sum()) / len(x)


def _peer_log(path):
    """(loop seconds, steps, atoms, dt) from a LIGGGHTS/LAMMPS log (thermo with a Dt column)."""
    lines = Path(path).read_text().splitlines()
    m = next(re.search(r"Loop time of ([\d.eE+-]+) on \d+ procs for (\d+) steps with (\d+) atoms", ln)
             for ln in lines if ln.startswith("Loop time"))
    k = max(i for i, ln in enumerate(lines) if ln.split()[:1] == ["Step"] and "Dt" in ln.split())
    head = lines[k].split()
    last = [ln.split() for ln in lines[k + 1:] if ln.split() and ln.split()[0].isdigit()][-1]
    return float(m.group(1)), int(m.group(2)), int(m.group(3)), float(last[head.index("Dt")])


def summary(work):
    from scipy.spatial import cKDTree

    work = Path(work)
    print("\n== medians over the rounds (particle-steps/s over all spheres, fixed ones included) ==")
    for scene in SCENES:
        nps = sorted({int(p.name.split("_np")[1].split("_")[0]) for p in work.glob(f"lig_{scene}_np*_r*.log")},
                     reverse=True)
        for np_ in nps:
            rows = {}
            for code in ("lig", "rd", "lmp"):
                times, rate = [], []
                for p in sorted(work.glob(f"{code}_{scene}_np{np_}_r*.{'json' if code == 'rd' else 'log'}")):
                    if code == "rd":
                        res = json.loads(p.read_text())["results"][0]
                        t, n, s = res["wall_s"], res["particles"], res["steps"]
                    else:
                        try:
                            t, s, n, _ = _peer_log(p)
                        except (StopIteration, AttributeError, IndexError, ValueError):
                            continue  # a run that did not finish
                    times.append(t)
                    rate.append(n * s / t)
                if times:
                    rows[code] = (float(np.median(times)), float(np.median(rate)), len(times))
            for code, name in (("lig", "LIGGGHTS"), ("rd", "rollingdem"), ("lmp", "LAMMPS")):
                if code in rows:
                    t, rate, k = rows[code]
                    print(f"{scene:5s} np={np_} {name:10s} median {t:8.3f} s  {rate / 1e6:7.2f} M particle-steps/s "
                          f"({k} rounds)")
            peers = [rows[c][1] for c in ("lig", "lmp") if c in rows]
            if "rd" in rows and peers:
                print(f"{scene:5s} np={np_} rollingdem / faster peer: {rows['rd'][1] / max(peers):.2f}x")
    print("\n== the same thing simulated? the last round's states, largest process count ==")
    for scene in SCENES:
        logs = sorted(work.glob(f"lig_{scene}_np*_r*.log"))
        if not logs:
            continue
        np_ = max(int(p.name.split("_np")[1].split("_")[0]) for p in logs)
        r = max(int(p.stem.split("_r")[-1]) for p in logs)
        start = _dump(work / f"{scene}.dump")
        free = start[:, 1] != 2
        print(f"{scene}: start  {len(start)} spheres ({(~free).sum()} fixed), contacts/sphere "
              f"{_contacts(scene, start):.3f}, max speed {np.linalg.norm(start[free, 5:8], axis=1).max():.4f} m/s")
        for code, name in (("lig", "LIGGGHTS"), ("rd", "rollingdem"), ("lmp", "LAMMPS")):
            final = work / f"{code}_{scene}_np{np_}_r{r}.final"
            if not final.exists():
                print(f"{scene}: {name:10s} no final state ({final.name})")
                continue
            d = _dump(final)
            if code == "rd":
                doc = json.loads((work / f"rd_{scene}_np{np_}_r{r}.json").read_text())
                res = doc["results"][0]
                steps, atoms, dt = res["steps"], res["particles"], doc["dt"]
                own = f", rollingdem's own count {res['contacts_per_particle']:.3f}"
            else:
                _, steps, atoms, dt = _peer_log(work / f"{code}_{scene}_np{np_}_r{r}.log")
                own = ""
            # each sphere matched to the nearest start position (read_dump on several processes gives
            # the atoms new ids): a sphere moved far less than a radius, so the match is one to one
            gap, k = cKDTree(start[:, 2:5]).query(d[:, 2:5])
            if len(d) != len(start) or len(np.unique(k)) != len(k) or gap.max() > bench.RADIUS:
                print(f"{scene}: {name:10s} not the start's spheres moved a little: {len(d)} spheres, "
                      f"largest distance to a start position {gap.max():.3g} m")
                continue
            d = d[np.argsort(k)]
            disp = np.linalg.norm(d[:, 2:5] - start[:, 2:5], axis=1)[free]
            moved = np.abs(d[~free, 2:5] - start[~free, 2:5]).max() if (~free).any() else 0.0
            if (d[:, 1] != start[:, 1]).any():
                print(f"{scene}: {name:10s} {int((d[:, 1] != start[:, 1]).sum())} spheres changed type")
            print(f"{scene}: {name:10s} atoms {atoms} dt {dt:g} s steps {steps}: contacts/sphere "
                  f"{_contacts(scene, d):.3f}{own}; max speed {np.linalg.norm(d[free, 5:8], axis=1).max():.4f} m/s; "
                  f"displacement mean {disp.mean() * 1e6:.1f} um max {disp.max() * 1e3:.3f} mm; fixed moved "
                  f"{moved:.1e} m")


if __name__ == "__main__":
    cmd, args = sys.argv[1], sys.argv[2:]
    if cmd == "prepare":
        prepare(*args)
    elif cmd == "time":
        time_scene(args[0], args[1], int(args[2]), int(args[3]), args[4], args[5])
    elif cmd == "summary":
        summary(*args)
    else:
        sys.exit(__doc__)
