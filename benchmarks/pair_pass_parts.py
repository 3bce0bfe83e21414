"""The pair pass built up piece by piece on the slab at 20,000 and 10^6 spheres (docs/scaling.md):
the distance tests only (cand), + the contacts' inputs (inputs), + their history rows read (histread),
+ rows written (poolwrite), and the real pass. 2 threads.
usage: python benchmarks/pair_pass_parts.py [steps before timing, default 200]
"""
import sys

import numba
from numba import njit, prange, uint32, uint64
from rollingdem import bench, ContactModel
numba.set_num_threads(2)
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
    sim = bench._column_simulation("epsd"); sim.add_particles(x, bench.RADIUS, "table1", velocity=v)
    sim.run(steps=int(sys.argv[1]) if len(sys.argv) > 1 else 200, progress=False)
    return sim
sims = {n: slab(n) for n in (20000, 1000000)}
ph = {n: bench._Phases(s) for n, s in sims.items()}
def var(st, mode):
    a = (st.x, st.v, st.w, st.f, st.t, st.radius, st.mass, st.nl_start, st.nl_j, st.nl_i, st.pool, st.contact_row, st.groups, st.contacts, st._blocks, st._lanes)
    return lambda: passv(mode, *a)
res = {}
for rnd in range(5):
    for n, s in sims.items():
        st = s._state
        fns = [("cand", var(st, 0)), ("inputs", var(st, 1)), ("histread", var(st, 2)), ("poolwrite", var(st, 3)), ("real", ph[n].pair)]
        for name, fn in fns:
            t = bench._seconds_per_call(fn, max(1, 20000 * 20 // n), 3)
            res.setdefault((name, n), []).append(t / n * 1e9)
        ph[n].restore()
for name in ("cand", "inputs", "histread", "poolwrite", "real"):
    a = min(res[(name, 20000)]); b = min(res[(name, 1000000)])
    print(f"{name:10s} 20k {a:6.2f} ns/p  1e6 {b:6.2f} ns/p  ratio {b/a:.2f}")
st = sims[1000000]._state
print("contacts/p", st.contacts.sum()/st.n, "entries/p", st.nl_start[st.n]/st.n, "blocks", st._blocks.shape)
