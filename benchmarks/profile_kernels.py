"""Where the compiled step spends its time: [PROFILE_SCENE=dense-bed] python benchmarks/profile_kernels.py [STEPS] [THREADS] [SKIP]

Samples the 20,000-sphere column collapse (``rollingdem bench``'s scene, from its cached settled
state, cylinder lifted, SKIP steps in; with PROFILE_SCENE=dense-bed the cylinder stays: ``bench --scene
dense-bed``'s bed at rest, with the EPSD model of the column) with Linux ``perf record`` for STEPS steps, and prints the
share of the samples in each compiled function (the parallel and serial drivers, ``contact``, the
neighbor rebuild) and the hottest instruction offsets in each, for ``objdump -d`` of the object
files it leaves in the output folder.

Numba's JIT code has no symbols that perf can see. So the kernels are compiled afresh (into a
temporary ``ROLLINGDEM_CACHE_DIR``, so their object code is in memory), and the script writes
perf's map file ``/tmp/perf-PID.map`` from each function's address and the symbol table (``nm``)
of its object code. The neighbor search is loaded from Numba's cache and is not attributed (about
3 % of a step on this scene: ``rollingdem bench`` times it). Inlined functions (``pair_row``, ``gather_one``, the
sub-model kernels) show as part of the function they are inlined into. Needs ``perf`` (Debian
``linux-perf``) and ``nm``; perf's own overhead is a few per cent.
"""
import collections
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

STEPS = int(sys.argv[1]) if len(sys.argv) > 1 else 4000
THREADS = int(sys.argv[2]) if len(sys.argv) > 2 else 1
SKIP = int(sys.argv[3]) if len(sys.argv) > 3 else 200
OUT = Path(os.environ.get("PROFILE_OUT", tempfile.mkdtemp(prefix="rollingdem-profile-")))


def sampled_run():
    import numba

    from rollingdem import Simulation
    from rollingdem.engine import neighbors

    numba.set_num_threads(THREADS)
    sim = Simulation.restore(os.environ["ROLLINGDEM_PROFILE_STATE"])
    if os.environ.get("PROFILE_SCENE", "column-collapse") == "column-collapse":
        sim.remove_wall(next(w for w in sim.walls if w.name == "cylinder"))
    sim.run(steps=SKIP, progress=False)
    tic = time.perf_counter()
    sim.run(steps=STEPS, progress=False)
    wall = time.perf_counter() - tic
    print(f"{STEPS} steps in {wall:.2f} s: {sim.n_particles * STEPS / wall / 1e6:.2f} M particle-steps/s "
          f"(under perf), {THREADS} thread(s)")
    lines = []
    for module in (sim.engine_module(), neighbors):
        for name in dir(module):
            dispatcher = getattr(module, name)
            for cres in getattr(dispatcher, "overloads", {}).values():
                library = cres.library
                try:
                    obj = library.serialize_using_object_code()[2][0]
                except RuntimeError:  # loaded from Numba's cache, or never called
                    continue
                path = OUT / f"{name}.o"
                path.write_bytes(obj)
                symbols = {}
                for row in subprocess.run(["nm", "-S", "--defined-only", str(path)], capture_output=True,
                                          text=True).stdout.splitlines():
                    parts = row.split()
                    if len(parts) == 4 and parts[2] in "tT":
                        symbols[parts[3]] = (int(parts[0], 16), int(parts[1], 16))
                own = cres.fndesc.llvm_func_name
                if own not in symbols:
                    continue
                base = library.get_pointer_to_function(own) - symbols[own][0]
                start, size = symbols[own]
                lines.append(f"{base + start:x} {size:x} {name}\n")  # the function itself, not its wrappers
    mapfile = Path(f"/tmp/perf-{os.getpid()}.map")
    mapfile.write_text("".join(sorted(lines)))
    (OUT / "mapfile").write_text(str(mapfile))


def main():
    if os.environ.get("ROLLINGDEM_PROFILE_CHILD"):
        sampled_run()
        return
    from rollingdem import bench

    state = bench._cache_dir() / "profile_state.npz"
    bench.settled_column(20000).checkpoint(state)  # from the bench's cache of settled states
    # ROLLINGDEM_PRECOMPILE=0: every kernel compiled in the sampled process (a helper's would be
    # loaded from the cache, without the object code that maps the samples)
    env = dict(os.environ, ROLLINGDEM_PROFILE_CHILD="1", PROFILE_OUT=str(OUT), ROLLINGDEM_PROFILE_STATE=str(state),
               ROLLINGDEM_CACHE_DIR=str(OUT / "kernels"), ROLLINGDEM_PRECOMPILE="0")
    data = OUT / "perf.data"
    OUT.mkdir(parents=True, exist_ok=True)
    subprocess.run(["perf", "record", "-F", "2000", "-o", str(data), sys.executable, __file__,
                    str(STEPS), str(THREADS), str(SKIP)], env=env, check=True)
    maps = {}
    mapfile = Path((OUT / "mapfile").read_text())
    if True:
        for row in mapfile.read_text().splitlines():
            start, size, name = row.split()
            maps[int(start, 16)] = (int(size, 16), name)
    ips = subprocess.run(["perf", "script", "-i", str(data), "-F", "ip"], capture_output=True,
                         text=True).stdout.split()
    by_function, by_offset = collections.Counter(), collections.defaultdict(collections.Counter)
    starts = sorted(maps)
    import bisect
    for ip in ips:
        ip = int(ip, 16)
        at = bisect.bisect_right(starts, ip) - 1
        if at >= 0 and ip < starts[at] + maps[starts[at]][0]:
            name = maps[starts[at]][1]
            by_function[name] += 1
            by_offset[name][ip - starts[at]] += 1
    total = sum(by_function.values())
    print(f"\n{total} samples in the compiled kernels ({len(ips)} in all, compilation included)")
    for name, count in by_function.most_common():
        hot = ", ".join(f"{off:x} ({n / count:.0%})" for off, n in by_offset[name].most_common(4))
        print(f"{name:24s} {count / total:6.1%}   hottest offsets: {hot}")
    print(f"\nobject files for objdump -d: {OUT}")


if __name__ == "__main__":
    main()
