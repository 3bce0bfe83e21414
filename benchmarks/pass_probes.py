"""The slab's passes at 20,000 and 10^6 spheres, each timed alone, against stripped-down copies
(docs/scaling.md): ``minpair`` and ``mingather`` read and write the same arrays as the pair pass and
the gather with no physics; ``cand`` is the pair pass's distance tests only, ``inputs`` adds the
contacts' inputs (v, omega, m of both spheres), ``histread`` their history rows read, ``poolwrite``
the rows written. 2 threads; the fastest of 5 rounds, ns per sphere.
usage: python benchmarks/pass_probes.py [steps before timing, default 200]
"""
import sys

import numba
from numba import njit, prange, uint32, uint64

from rollingdem import ContactModel
from rollingdem import bench
from rollingdem.engine.phases import seconds_per_call

numba.set_num_threads(2)
STEPS = int(sys.argv[1]) if len(sys.argv) > 1 else 200

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

K = ContactModel("hertz", rolling="epsd").kernel(False)
ce = K.candidate_entries; ei = K.entry_inputs
LANE_HITS, CB, BS, HS = K.LANE_HITS, K.CONTACT_BLOCK, K.BLOCK_SHIFT, K.HISTORY_SIZE
POOL_GROUP = K.POOL_GROUP

@njit(error_model="numpy", fastmath={"contract"})
def rows(mode, lo, hi, x, v, w, f, t, radius, mass, nl_start, nl_j, nl_i, pool, contact_row, groups, contacts, block, lanes):
    for i in range(lo, hi):
        for d in range(3):
            f[i, d] = 0.0; t[i, d] = 0.0
        contacts[i] = 0
    tile = (lanes.shape[0] - LANE_HITS) * CB
    kend = nl_start[hi]
    acc = 0.0
    for k0 in range(nl_start[lo], kend, tile):
        nhit = ce(k0, min(k0 + tile, kend), x, radius, nl_j, nl_i, contact_row, lanes)
        if mode == 0:
            acc += nhit
            continue
        for e in range(nhit):
            k = uint64(lanes[LANE_HITS + (e >> BS), e & (CB - 1)])
            i = uint32(nl_i[k])
            touching, j, row, inputs = ei(i, k, x, v, w, radius, mass, nl_j, pool, contact_row, groups)
            if not touching:
                continue
            s = 0.0
            for q in range(18):
                s += inputs[q]
            if mode >= 2:
                urow = uint64(row)
                for q in range(HS):
                    s += pool[urow, q]
            if mode >= 3:
                urow = uint64(row)
                for q in range(HS + 6):
                    pool[urow, q] = s
            f[i, 0] += s
            contacts[i] += 1
    f[lo, 1] += acc

@njit(parallel=True, error_model="numpy", fastmath={"contract"})
def passv(mode, x, v, w, f, t, radius, mass, nl_start, nl_j, nl_i, pool, contact_row, groups, contacts, blocks, lanes):
    n = x.shape[0]
    nblock = blocks.shape[0]
    ngroups = (n + POOL_GROUP - 1) // POOL_GROUP
    for b in prange(nblock):
        rows(mode, min(b * ngroups // nblock * POOL_GROUP, n), min((b + 1) * ngroups // nblock * POOL_GROUP, n),
             x, v, w, f, t, radius, mass, nl_start, nl_j, nl_i, pool, contact_row, groups, contacts, blocks[b], lanes[b])

def slab(n):
    x, v = bench.slab_state(n)
    sim = bench._column_simulation("epsd")
    sim.add_particles(x, bench.RADIUS, "table1", velocity=v)
    sim.run(steps=STEPS, progress=False)
    return sim


sims = {n: slab(n) for n in (20000, 1000000)}
ph = {n: s.passes() for n, s in sims.items()}


def variants(n):
    st = sims[n]._state
    pair_args = (st.x, st.v, st.w, st.f, st.t, st.radius, st.mass, st.contact_list.start, st.contact_list.j, st.contact_list.i, st.contact_list.pool,
                 st.contact_list.contact_row, st.contact_list.groups, st.contacts, st._blocks, st._lanes)
    return [("pair", ph[n].pair),
            ("minpair", lambda: minimal_pair(st.x, st.radius, st.contact_list.start, st.contact_list.j, st.contact_list.i, st.contact_list.contact_row, st.f,
                                             st.t, st.contacts)),
            ("cand", lambda: passv(0, *pair_args)), ("inputs", lambda: passv(1, *pair_args)),
            ("histread", lambda: passv(2, *pair_args)), ("poolwrite", lambda: passv(3, *pair_args)),
            ("gather", ph[n].gather_plain),
            ("mingather", lambda: minimal_gather(st.x, st.v, st.w, st.f, st.t, st.mass, st.inertia, st.x_ref,
                                                 st.contact_list.tr_start, st.contact_list.tr_k, st.contact_list.contact_row, st.contact_list.pool, 0.0))]


res = {}
for rnd in range(5):
    for n in sims:
        for name, fn in variants(n):
            res.setdefault((name, n), []).append(seconds_per_call(fn, max(1, 20000 * 20 // n), 3) / n * 1e9)
        ph[n].restore()
for name, _ in variants(20000):
    a, b = min(res[(name, 20000)]), min(res[(name, 1000000)])
    print(f"{name:10s} 20k {a:6.2f} ns/p  1e6 {b:6.2f} ns/p  ratio {b / a:.2f}")
