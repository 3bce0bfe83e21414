#!/usr/bin/env bash
# Side-by-side timing of the column-collapse scene (20,000 spheres, 10,000 steps) on the identical
# settled state: LIGGGHTS (EPSD), LAMMPS (rolling sds) and rollingdem (EPSD), alternating, ROUNDS
# rounds, 1 and 2 processes/threads. Needs: apt-get install liggghts lammps openmpi-bin.
# usage: [NPS="2 1"] [BASE=DIR] benchmarks/peers.sh WORKDIR [ROUNDS]   (WORKDIR gets the inputs, the dump and
# the logs; NPS: the process/thread counts of each round; BASE: a checkout of another commit, e.g. from
# `git worktree add DIR COMMIT`, timed in each round after this one, with its own kernel cache)
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
work="$1"; rounds="${2:-3}"
mkdir -p "$work"; cd "$work"
cp -n "$here/benchmarks/reference/"* . 2>/dev/null || true
M="mpirun --allow-run-as-root --oversubscribe"
if [ ! -f column20k.dump ]; then
  $M -np 2 liggghts -in liggghts_in.build -var rf epsd -var out column20k > build.log
fi
[ -f column20k.data ] || python3 dump2data.py column20k.dump column20k.data
for r in $(seq "$rounds"); do
  for np_ in ${NPS:-2 1}; do
    $M -np $np_ liggghts -in liggghts_in.run -var rf epsd -var dump column20k.dump -var nsteps 10000 \
      -log "lig_np${np_}_r$r.log" > /dev/null
    echo "round $r liggghts np=$np_ $(grep 'Loop time' "lig_np${np_}_r$r.log")"
    rollingdem bench --from-dump column20k.dump --threads $np_ --steps 10000 --json "rd_t${np_}_r$r.json" > /dev/null
    echo "round $r rollingdem threads=$np_ $(python3 -c "import json; r=json.load(open('rd_t${np_}_r$r.json'))['results'][0]; print(r['wall_s'], 's', r['particle_steps_per_s']/1e6, 'M')")"
    if [ -n "${BASE:-}" ]; then
      ROLLINGDEM_CACHE_DIR="$work/base-kernels" PYTHONPATH="$BASE/src" python3 -m rollingdem.cli bench \
        --from-dump column20k.dump --threads $np_ --steps 10000 --json "base_t${np_}_r$r.json" > /dev/null
      echo "round $r base threads=$np_ $(python3 -c "import json; r=json.load(open('base_t${np_}_r$r.json'))['results'][0]; print(r['wall_s'], 's', r['particle_steps_per_s']/1e6, 'M')")"
    fi
    $M -np $np_ lmp -in lammps_in.run -var data column20k.data -var nsteps 10000 -log "lmp_np${np_}_r$r.log" > /dev/null
    echo "round $r lammps np=$np_ $(grep 'Loop time' "lmp_np${np_}_r$r.log")"
  done
done
