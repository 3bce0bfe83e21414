"""Half list vs full list, measured (issue 5): python benchmarks/half_vs_full_list.py MODEL THREADS [DUMP]

The engine keeps a half list: each contact is computed once, its force and j-torque are kept per pair,
and a second pass gathers them onto the second partner (conflict-free, no atomics). The alternative is
a full list with one writer per particle: every contact is computed from both sides (twice the contact
work, each side with its own copy of the history), in one pass, with no gather. This builds the full
list and its history from the engine's half list on the same state (the 20,000-sphere collapse, 200
steps after the cylinder is lifted; the LIGGGHTS-settled state if DUMP is given), checks that both
give the same forces to round-off, and prints: half ms, full ms, full/half, best of 7 x 20 force passes
(walls and gravity included in both).

It was written for the per-entry history rows of commit ae2afde and earlier (``git worktree add
/tmp/ae2afde ae2afde`` and run it there with PYTHONPATH=/tmp/ae2afde/src): the contact pool that
replaced them (``rollingdem.engine.neighbors``) changes the half list's cost, not the comparison's answer
(the full list does every contact twice)."""
import time, sys, numpy as np, numba
import rollingdem.engine.state
if hasattr(rollingdem.engine.state.EngineState(6), "pool"):
    sys.exit("half_vs_full_list.py measures the per-entry history layout of commit ae2afde: run it from a checkout of it")
from numba import njit, prange
from rollingdem import bench
rolling = sys.argv[1] if len(sys.argv) > 1 else "epsd"
nthreads = int(sys.argv[2]) if len(sys.argv) > 2 else 1
numba.set_num_threads(nthreads)
if len(sys.argv) > 3:
    sim = bench.column_from_dump(sys.argv[3], rolling=rolling)
else:
    sim = bench.settled_column(20000, rolling=rolling)
sim.remove_wall(next(w for w in sim.walls if w.name == "cylinder"))
sim.run(200*sim.dt)
st = sim._state
K = sim.kernel()
a = st.kernel_args(sim.dt, np.asarray(sim.gravity), sim.skin, sim.pair_parameters())
(dt, gravity, x, v, w, f, t, radius, mass, inertia, mat, ids, pp, wall_kind, wall_geom, wall_vel, wall_omega,
 wall_mat, whist, wtouch, nl_start, nl_j, nl_i, hist, touch, pair_force, pair_torque_j, tr_start, tr_k, cell_start, cell_items,
 cell_of, counts, x_ref, skin, energy, contacts, info, blocks, lanes) = a
n = x.shape[0]
nent = nl_start[n]
owner = np.repeat(np.arange(n), np.diff(nl_start[:n+1]))
# full list: row i = its half row, then the entries where it is the second partner
fl_start = np.zeros(n + 1, np.int64)
rows_j, rows_h = [], []
for i in range(n):
    ks = np.arange(nl_start[i], nl_start[i+1])
    ms = tr_k[tr_start[i]:tr_start[i+1]]
    rows_j.append(np.concatenate([nl_j[ks], owner[ms]]))
    hh = np.concatenate([hist[ks], -hist[ms]])  # j's view: normal and springs flip
    rows_h.append(hh)
    fl_start[i+1] = fl_start[i] + len(ks) + len(ms)
fl_j = np.concatenate(rows_j).astype(nl_j.dtype)
fhist = np.ascontiguousarray(np.concatenate(rows_h))
ftouch = (np.abs(fhist[:, :3]).sum(1) > 0).astype(touch.dtype)
contact = K.contact
entry_inputs = K.entry_inputs  # the engine's distance test and contact inputs

@njit(inline="always")
def full_row(i, dt, x, v, w, f, t, radius, mass, mat, pp, fl_start, fl_j, hist, touch, contacts):
    fx = fy = fz = tx = ty = tz = 0.0
    nc = 0
    for k in range(fl_start[i], fl_start[i + 1]):
        touching, j, g = entry_inputs(i, k, x, v, w, radius, mass, fl_j, hist, touch)
        if not touching:
            continue
        res = contact(hist, k, g[0], g[1], g[2], g[3], g[4], g[5], g[6], g[7], g[8], g[9], g[10], g[11], g[12],
                      g[13], g[14], g[15], g[16], g[17], pp[mat[i], mat[j]], dt)
        fx += res[0]; fy += res[1]; fz += res[2]
        tx += res[3]; ty += res[4]; tz += res[5]
        nc += 1
    f[i, 0] = fx; f[i, 1] = fy; f[i, 2] = fz
    t[i, 0] = tx; t[i, 1] = ty; t[i, 2] = tz
    contacts[i] = nc

@njit(parallel=True, error_model="numpy", fastmath={"contract"})
def full_par(dt, x, v, w, f, t, radius, mass, mat, pp, fl_start, fl_j, hist, touch, contacts):
    for i in prange(x.shape[0]):
        full_row(i, dt, x, v, w, f, t, radius, mass, mat, pp, fl_start, fl_j, hist, touch, contacts)

@njit(parallel=True, error_model="numpy", fastmath={"contract"})
def full_ser(dt, x, v, w, f, t, radius, mass, mat, pp, fl_start, fl_j, hist, touch, contacts):
    for i in range(x.shape[0]):
        full_row(i, dt, x, v, w, f, t, radius, mass, mat, pp, fl_start, fl_j, hist, touch, contacts)

ser = nthreads == 1
empty_tr = np.zeros_like(tr_start)
h0 = hist.copy(); fh0 = fhist.copy(); t0 = touch.copy(); ft0 = ftouch.copy()
def half():
    (K.pair_forces_serial if ser else K.pair_forces)(dt, x, v, w, f, t, radius, mass, mat, pp, nl_start, nl_j, nl_i, hist, touch,
                                                     pair_force, pair_torque_j, energy, contacts, blocks, lanes)
    (K.gather_serial if ser else K.gather)(0.0 * dt, 0.0, gravity, x, v, w, f, t, radius, mass, inertia, mat, pp, tr_start, tr_k,
        nl_j, touch, pair_force, pair_torque_j, wall_kind, wall_geom, wall_vel, wall_omega, wall_mat, whist, wtouch, energy,
        contacts, x_ref, 0.5 * skin)
def full():
    (full_ser if ser else full_par)(dt, x, v, w, f, t, radius, mass, mat, pp, fl_start, fl_j, fhist, ftouch, contacts)
    (K.gather_serial if ser else K.gather)(0.0 * dt, 0.0, gravity, x, v, w, f, t, radius, mass, inertia, mat, pp, empty_tr, tr_k,
        nl_j, touch, pair_force, pair_torque_j, wall_kind, wall_geom, wall_vel, wall_omega, wall_mat, whist, wtouch, energy,
        contacts, x_ref, 0.5 * skin)
# check: forces agree
hist[...] = h0; touch[...] = t0; half(); fa = f.copy(); ta = t.copy()
fhist[...] = fh0; ftouch[...] = ft0; full(); fb = f.copy(); tb = t.copy()
print("entries half", nent, "full", fl_start[n], "max |dF|/max|F|", np.abs(fa - fb).max() / np.abs(fa).max(),
      "max |dT|/max|T|", np.abs(ta - tb).max() / np.abs(ta).max(), file=sys.stderr)
res = {"half": [], "full": []}
for rep in range(7):
    for name, fn in (("half", half), ("full", full)):
        hist[...] = h0; touch[...] = t0; fhist[...] = fh0; ftouch[...] = ft0
        tic = time.perf_counter()
        for _ in range(20):
            fn()
        res[name].append((time.perf_counter() - tic) / 20)
h = min(res["half"]) * 1e3; fu = min(res["full"]) * 1e3
print(f"{h:.3f} {fu:.3f} {fu/h:.3f}")
