#!/usr/bin/env bash
# The GPU measurement (docs/gpu.md), for one short loan of a machine with an NVIDIA GPU: under 10
# minutes with the installs and compiles. It installs the package (with the cuda extra where PyPI
# is reachable, else on the numba-cuda already there), runs a quick validation case on the GPU
# backend, then times the slab at 20,000, 10^6 and 10^7 spheres and the column-collapse at 20,000
# (settled on the CPU first, if the disk cache lacks it), and prints
# particle-steps per second, state bytes per particle (the arrays the device holds), the device's
# memory in use, and the compile time. Each part has a time limit of its own: one that runs out is
# reported and the rest goes on.
# usage: benchmarks/gpu.sh [OUT]     (OUT, default gpu-results/: logs and JSON)
set -uo pipefail
cd "$(dirname "$0")/.."
out="${1:-gpu-results}"
mkdir -p "$out"
start=$(date +%s)
part() {  # part NAME SECONDS COMMAND...: run with a limit, log to OUT/NAME.log, say how it ended
  local name="$1" limit="$2"; shift 2
  local t0=$(date +%s)
  timeout "$limit" "$@" > "$out/$name.log" 2>&1
  local rc=$?
  echo "== $name: exit $rc ($(( $(date +%s) - t0 )) s; limit $limit s)"
  tail -n 6 "$out/$name.log"
}

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv | tee "$out/gpu.txt"
python3 -m pip install -q -e ".[cuda]" > "$out/install.log" 2>&1 \
  || python3 -m pip install -q --no-deps -e . >> "$out/install.log" 2>&1
python3 - <<'EOF' | tee "$out/versions.txt"
import numba, rollingdem
from rollingdem.cuda_target import require
cuda = require()
import numba_cuda
device = cuda.get_current_device()
print("rollingdem", rollingdem.__version__, "numba", numba.__version__, "numba-cuda", numba_cuda.__version__,
      "device", device.name, "cc", device.compute_capability)
EOF

# correctness on the GPU: a quick validation case of one sphere per run, for two rolling models. A
# sphere alone is the GPU's worst case (each step is a few kernel launches and a read of two
# counters, tens of microseconds, for one particle), so the whole quick set does not fit a short loan
part validate 150 rollingdem validate --backend cuda --quick -c rolling-slope -m epsd -m cdt -w 1 --no-progress \
  -o "$out/validate"

# speed, in one process so that the kernels compile once: the slab (EPSD, Hertz with history) at
# 20,000, 10^6 and 10^7 spheres, the column-collapse at 20,000 (its settled column from the disk
# cache, or settled on the CPU first); each result written as soon as it is measured
part speed 330 python3 - "$out" <<'PY'
import dataclasses, json, pathlib, sys, time
from rollingdem import bench
out = pathlib.Path(sys.argv[1])
for name, run in (("slab-20k", lambda: bench.slab(20000, 500, backend="cuda")),
                  ("slab-1M", lambda: bench.slab(1_000_000, 100, backend="cuda")),
                  ("collapse-20k", lambda: bench.column_collapse(20000, 2000, backend="cuda")),
                  ("slab-10M", lambda: bench.slab(10_000_000, 20, backend="cuda"))):
    tic = time.perf_counter()
    r = run()
    (out / f"{name}.json").write_text(json.dumps({"results": [dataclasses.asdict(r)]}, indent=2))
    print(f"{name}: {r.particle_steps_per_s / 1e6:.1f} M particle-steps/s, {time.perf_counter() - tic:.0f} s",
          flush=True)
PY
python3 - "$out" <<'EOF'
import json, pathlib, sys
for f in sorted(pathlib.Path(sys.argv[1]).glob("*.json")):
    for r in json.loads(f.read_text())["results"]:
        print(f"{f.stem:14s} N={r['particles']:<9d} {r['particle_steps_per_s'] / 1e6:9.1f} M particle-steps/s  "
              f"state {r['state_bytes_per_particle']:.0f} B/p  compile {r['compile_s']:.1f} s  rebuilds {r['rebuilds']}"
              f"  {r.get('device_memory_bytes_per_particle', 0):.0f} B/p on the device")
EOF
echo "total $(( $(date +%s) - start )) s"
