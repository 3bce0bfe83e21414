"""Fused step vs pair pass then gather, in one process (issue 5):
python benchmarks/fused_vs_separate.py SCENE N THREADS   (SCENE: column or slab)

The step loop computes the pair terms and gathers them in one pass (``step_forces``: each thread
gathers the particles its rows complete while their data is in cache). The alternative is the two
passes one after the other (``pair_forces``, then ``gather``). Both do the same work (pair terms,
walls, gravity, closing kick, next opening kick and drift) and leave the same state bit for bit.
This times both on the same state, alternating, 9 rounds of ``REPS`` calls each, and prints the
median ms per call of each and their ratio (a shared machine's load drifts; alternating in one
process compares like with like)."""
import sys
import time

import numba
import numpy as np

from rollingdem import bench

scene, n, threads = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
numba.set_num_threads(threads)
if scene == "column":
    sim = bench.settled_column(n)
    sim.remove_wall(next(w for w in sim.walls if w.name == "cylinder"))
else:
    sim = bench._column_simulation("epsd")
    positions, velocities = bench.slab_state(n)
    sim.add_particles(positions, bench.RADIUS, "table1", velocity=velocities)
sim.run(steps=200, progress=False)
st = sim._state
K = sim.kernel()
(dt, gravity, x, v, w, f, t, radius, mass, inertia, mat, ids, pp, wall_kind, wall_geom, wall_vel, wall_omega,
 wall_mat, whist, wtouch, nl_start, nl_j, hist, touch, pair_force, pair_torque_j, tr_start, tr_k, cell_start,
 cell_items, cell_of, counts, x_ref, skin, energy, contacts, info, ready, ready_row, blocks, lanes) = \
    st.kernel_args(sim.dt, np.asarray(sim.gravity), sim.skin, sim.pair_parameters())
K._order(nl_start, nl_j, cell_start, cell_of, counts, info, ready, ready_row, blocks.shape[0])
order = np.arange(x.shape[0], dtype=np.int32)
half_skin = 0.5 * skin
gather_tail = (tr_start, tr_k, touch, pair_force, pair_torque_j, wall_kind, wall_geom, wall_vel, wall_omega, wall_mat,
               whist, wtouch, energy, contacts, x_ref, half_skin)


def separate():
    K.pair_forces(dt, x, v, w, f, t, radius, mass, mat, pp, nl_start, nl_j, hist, touch, pair_force, pair_torque_j,
                  energy, contacts, blocks, lanes)
    K.gather(dt, 2.0, gravity, x, v, w, f, t, radius, mass, inertia, mat, pp, *gather_tail, order)


def fused():
    K.step_forces(dt, 2.0, gravity, x, v, w, f, t, radius, mass, inertia, mat, pp, nl_start, nl_j, hist, touch,
                  pair_force, pair_torque_j, tr_start, tr_k, *gather_tail[5:], ready, ready_row, blocks, lanes)


REPS = max(3, 2_000_000 // x.shape[0])
saved = [a.copy() for a in (x, v, w, f, t)]
times = {"separate": [], "fused": []}
for fn in (separate, fused):
    fn()
for _ in range(9):
    for name, fn in (("separate", separate), ("fused", fused)):
        for a, s in zip((x, v, w, f, t), saved):  # the same state for both (each call drifts the spheres)
            a[...] = s
        tic = time.perf_counter()
        for _ in range(REPS):
            fn()
        times[name].append((time.perf_counter() - tic) / REPS * 1e3)
sep, fus = np.median(times["separate"]), np.median(times["fused"])
deferred = int((ready_row[:x.shape[0]] == x.shape[0]).sum())
print(f"{scene} N={x.shape[0]} threads={threads} deferred={deferred}: separate {sep:.3f} ms, fused {fus:.3f} ms, "
      f"fused/separate {fus / sep:.3f}")
