#!/usr/bin/env bash
# A/B speed of this checkout against another commit's, alternating within and across rounds, on any scene of
# `rollingdem bench` (same machine, same state: both read the bench's disk cache of settled scenes).
# usage: BASE=DIR benchmarks/ab.sh WORKDIR ROUNDS [rollingdem bench options...]
#   BASE: a checkout of the other commit (git worktree add DIR COMMIT), run with its own kernel cache;
#   both read the settled scenes from WORKDIR/bench (copy a settled column there to skip settling)
# Prints each run's particle-steps/s and, at the end, each round's ratio (this / base) and their median.
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
work="$1"; rounds="$2"; shift 2
: "${BASE:?set BASE to a checkout of the commit to compare with}"
mkdir -p "$work"
rate() { python3 -c "import json,sys; print(json.load(open(sys.argv[1]))['results'][0]['particle_steps_per_s'])" "$1"; }
this() { ROLLINGDEM_CACHE_DIR="$work/this-kernels" PYTHONPATH="$here/src" python3 -m rollingdem.cli bench "$@" > /dev/null; }
base() { ROLLINGDEM_CACHE_DIR="$work/base-kernels" PYTHONPATH="$BASE/src" python3 -m rollingdem.cli bench "$@" > /dev/null; }
# the side that runs first in a round runs ~3 % slower on a 2-core machine: odd rounds run this
# checkout first, even rounds the base, so that the order cancels in the median
for r in $(seq "$rounds"); do
  if (( r % 2 )); then
    this "$@" --json "$work/this_r$r.json"; base "$@" --json "$work/base_r$r.json"
  else
    base "$@" --json "$work/base_r$r.json"; this "$@" --json "$work/this_r$r.json"
  fi
  echo "round $r this $(rate "$work/this_r$r.json") base $(rate "$work/base_r$r.json")"
done
python3 - "$work" "$rounds" <<'PY'
import json, statistics, sys
work, rounds = sys.argv[1], int(sys.argv[2])
rate = lambda p: json.load(open(p))["results"][0]["particle_steps_per_s"]
ratios = [rate(f"{work}/this_r{r}.json") / rate(f"{work}/base_r{r}.json") for r in range(1, rounds + 1)]
print("ratios (this / base):", " ".join(f"{x:.3f}" for x in ratios), f"median {statistics.median(ratios):.3f}")
PY
