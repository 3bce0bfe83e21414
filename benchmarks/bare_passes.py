"""Bare streams against the real passes on the slab at 20,000 and 10^6 spheres (docs/scaling.md).

The gather and the pair pass, each timed alone, against a kernel that reads and writes the same
arrays with no physics (minimal_gather, minimal_pair). 2 threads.
usage: python benchmarks/bare_passes.py [steps before timing, default 100; the table in docs/scaling.md: 200]
"""
import sys

import numba
from numba import njit, prange, uint32, uint64
from rollingdem import bench
numba.set_num_threads(2)

@njit(parallel=True, cache=True)
def minimal_pair(x, radius, nl_start, nl_j, nl_i, contact_row, f, t, contacts):
    n = x.shape[0]
    nb = 2
    for b in prange(nb):
        lo = b * n // nb; hi = (b + 1) * n // nb
        for i in range(lo, hi):
            sx = 0.0; sy = 0.0; sz = 0.0; c = 0
            for k in range(nl_start[i], nl_start[i + 1]):
                j = uint32(nl_j[k])
                dx = x[i, 0] - x[j, 0]; dy = x[i, 1] - x[j, 1]; dz = x[i, 2] - x[j, 2]
                r = radius[i] + radius[j]
                if dx * dx + dy * dy + dz * dz < r * r or contact_row[uint64(k)] >= 0:
                    c += 1; sx += dx; sy += dy; sz += dz
            f[i, 0] = sx; f[i, 1] = sy; f[i, 2] = sz
            t[i, 0] = sx; t[i, 1] = sy; t[i, 2] = sz
            contacts[i] = c

@njit(parallel=True, cache=True)
def minimal_gather(x, v, w, f, t, mass, inertia, x_ref, tr_start, tr_k, contact_row, pool, dt):
    n = x.shape[0]
    nb = 2
    for b in prange(nb):
        lo = b * n // nb; hi = (b + 1) * n // nb
        for i in range(lo, hi):
            fx = f[i, 0]; fy = f[i, 1]; fz = f[i, 2]
            for q in range(tr_start[i], tr_start[i + 1]):
                k = uint64(tr_k[q]); row = contact_row[k]
                if row >= 0:
                    fx -= pool[uint64(row), 10]; fy -= pool[uint64(row), 11]; fz -= pool[uint64(row), 12]
            m = mass[i]; I = inertia[i]
            v[i, 0] += dt * fx / m; v[i, 1] += dt * fy / m; v[i, 2] += dt * fz / m
            w[i, 0] += dt * t[i, 0] / I; w[i, 1] += dt * t[i, 1] / I; w[i, 2] += dt * t[i, 2] / I
            x[i, 0] += dt * v[i, 0]; x[i, 1] += dt * v[i, 1]; x[i, 2] += dt * v[i, 2]
            if abs(x[i, 0] - x_ref[i, 0]) > 1.0:
                x_ref[i, 0] = 0.0

def slab(n):
    x, v = bench.slab_state(n)
    sim = bench._column_simulation("epsd"); sim.add_particles(x, bench.RADIUS, "table1", velocity=v)
    sim.run(steps=int(sys.argv[1]) if len(sys.argv) > 1 else 100, progress=False)
    return sim

sims = {n: slab(n) for n in (20000, 1000000)}
ph = {n: bench._Phases(s) for n, s in sims.items()}
def mp(st): return lambda: minimal_pair(st.x, st.radius, st.nl_start, st.nl_j, st.nl_i, st.contact_row, st.f, st.t, st.contacts)
def mg(st): return lambda: minimal_gather(st.x, st.v, st.w, st.f, st.t, st.mass, st.inertia, st.x_ref, st.tr_start, st.tr_k, st.contact_row, st.pool, 0.0)
res = {}
for rnd in range(5):
    for n, s in sims.items():
        st = s._state
        for name, fn in (("pair", ph[n].pair), ("minpair", mp(st)), ("gather", ph[n].gather_plain), ("mingather", mg(st))):
            t = bench._seconds_per_call(fn, max(1, 20000 * 20 // n), 3)
            res.setdefault((name, n), []).append(t / n * 1e9)
for name in ("pair", "minpair", "gather", "mingather"):
    a = min(res[(name, 20000)]); b = min(res[(name, 1000000)])
    print(f"{name:10s} 20k {a:6.2f} ns/p  1e6 {b:6.2f} ns/p  ratio {b/a:.2f}")
