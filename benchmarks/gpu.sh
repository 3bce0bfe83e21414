#!/usr/bin/env bash
# The GPU measurement (docs/gpu.md), for one short loan of a machine with an NVIDIA GPU: under 10
# minutes with the installs and compiles. It makes the package importable, runs a quick validation
# case on the GPU backend, then times the slab at 10^6, 10^7 and 20,000 spheres and the
# column-collapse at 20,000 and 10^6, and prints particle-steps per second, the arrays the device
# holds per particle, each phase of a step (the device's passes and the host's share) and the
# compile time. A column missing from the disk cache is settled on the GPU first. Each part has a
# time limit of its own, the last one what is left of the 10 minutes: one that runs out is reported,
# and what it measured so far is kept.
#
# usage: [WHEELS=DIR] benchmarks/gpu.sh [OUT]     (OUT, default gpu-results/: logs and JSON)
#   The package runs from src/. Its dependencies come from PyPI (pip install -e ".[cuda]"), or, on
#   a machine without PyPI, from the wheels in DIR, installed beside the machine's own packages
#   (benchmarks/gpu_wheels.py makes them). ROLLINGDEM_CACHE_DIR chooses the disk cache as usual: a
#   settled column in its sibling bench/ folder is used as it is.
set -uo pipefail
cd "$(dirname "$0")/.."
out="${1:-gpu-results}"
mkdir -p "$out"
start=$(date +%s)
budget=570  # s, the whole script: a 10-minute loan, less the summary
part() {  # part NAME SECONDS COMMAND...: run with a limit, log to OUT/NAME.log, say how it ended
  local name="$1" limit="$2"; shift 2
  local t0=$(date +%s)
  timeout "$limit" "$@" > "$out/$name.log" 2>&1
  local rc=$?
  echo "== $name: exit $rc ($(( $(date +%s) - t0 )) s; limit $limit s)"
  tail -n 8 "$out/$name.log"
}
left() { echo $(( budget - ($(date +%s) - start) )); }

nvidia-smi --query-gpu=name,driver_version,memory.total --format=csv | tee "$out/gpu.txt"
if [ -n "${WHEELS:-}" ]; then
  site="${TMPDIR:-/tmp}/rollingdem-site"
  python3 -m pip install -q --no-index --no-deps --no-compile --upgrade --target "$site" "$WHEELS"/*.whl \
    > "$out/install.log" 2>&1 || { echo "installing the wheels of $WHEELS failed:"; tail -n 5 "$out/install.log"; }
  export PYTHONPATH="$site${PYTHONPATH:+:$PYTHONPATH}"
else
  python3 -m pip install -q -e ".[cuda]" > "$out/install.log" 2>&1 \
    || python3 -m pip install -q --no-deps -e . >> "$out/install.log" 2>&1
fi
export PYTHONPATH="$PWD/src${PYTHONPATH:+:$PYTHONPATH}" PYTHONUNBUFFERED=1
python3 - <<'EOF' 2>&1 | tee "$out/versions.txt" || { echo "the package cannot run here: see above"; exit 1; }
import numba, rollingdem, rollingdem.bench, rollingdem.io.casefile, rollingdem.cli, rollingdem.validate  # what the parts import
from rollingdem.engine.cuda.target import require
cuda = require()
import numba_cuda
device = cuda.get_current_device()
print("rollingdem", rollingdem.__version__, "from", rollingdem.__file__, "numba", numba.__version__,
      "numba-cuda", numba_cuda.__version__, "device", getattr(device, "name", "the simulator"), "cc",
      getattr(device, "compute_capability", None))
EOF

# correctness on the GPU: a quick validation case of one sphere per run, for two rolling models. A
# sphere alone is the GPU's worst case (each step is a few kernel launches and a read of two
# counters, tens of microseconds, for one particle), so the whole quick set does not fit a short loan
part validate 150 python3 -m rollingdem.cli validate --backend cuda --quick -c rolling-slope -m epsd -m cdt -w 1 \
  --no-progress -o "$out/validate"

# speed, in one process so that the kernels compile once: the slab (EPSD, Hertz with history) at
# 10^6, 10^7 and 20,000 spheres, the column-collapse at 20,000 and 10^6 (settled on the GPU if the
# disk cache lacks it); each result written as soon as it is measured
part speed "$(left)" python3 - "$out" <<'PY'
import dataclasses, json, pathlib, sys, time, traceback
from rollingdem import bench
out = pathlib.Path(sys.argv[1])


def collapse(particles, steps):
    tic = time.perf_counter()
    bench.settled_column(particles, backend="cuda", checkpoint_every=bench.SETTLE)  # no partial checkpoints
    print(f"column of {particles}: {time.perf_counter() - tic:.0f} s to settle or load", flush=True)
    return bench.column_collapse(particles, steps, backend="cuda")


for name, run in (("slab-1M", lambda: bench.slab(1_000_000, 100, backend="cuda")),
                  ("slab-10M", lambda: bench.slab(10_000_000, 20, backend="cuda")),
                  ("slab-20k", lambda: bench.slab(20000, 500, backend="cuda")),
                  ("collapse-20k", lambda: collapse(20000, 2000)),
                  ("collapse-1M", lambda: collapse(1_000_000, 300))):
    tic = time.perf_counter()
    try:
        r = run()
    except Exception:
        traceback.print_exc()
        continue
    (out / f"{name}.json").write_text(json.dumps({"results": [dataclasses.asdict(r)]}, indent=2))
    print(f"{name}: {r.particle_steps_per_s / 1e6:.1f} M particle-steps/s, {time.perf_counter() - tic:.0f} s",
          flush=True)
    print(bench.format_row(r), flush=True)
PY
python3 - "$out" <<'EOF'
import json, pathlib, sys
for f in sorted(pathlib.Path(sys.argv[1]).glob("*.json")):
    for r in json.loads(f.read_text())["results"]:
        print(f"{f.stem:14s} N={r['particles']:<9d} {r['particle_steps_per_s'] / 1e6:9.1f} M particle-steps/s  "
              f"device {r.get('device_memory_bytes_per_particle', 0):.0f} B/p  host state "
              f"{r['state_bytes_per_particle']:.0f} B/p  compile {r['compile_s']:.1f} s  rebuilds {r['rebuilds']}")
        print(" " * 15 + ", ".join(f"{k} {v * 1e3:.3g} ms" for k, v in r["split_s_per_step"].items()))
EOF
echo "total $(( $(date +%s) - start )) s"
