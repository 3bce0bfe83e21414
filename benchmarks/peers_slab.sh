#!/usr/bin/env bash
# Scaling in N side by side: the slab scene at 20,000 and 1,000,000 spheres, 500 steps, 2 processes,
# LIGGGHTS (EPSD) and rollingdem (EPSD) alternating on the identical state, ROUNDS rounds.
# Is the cost per particle-step flat in N on this machine, for either code?
# Needs: apt-get install liggghts openmpi-bin.   usage: benchmarks/peers_slab.sh WORKDIR [ROUNDS]
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
work="$1"; rounds="${2:-2}"
mkdir -p "$work"; cd "$work"
M="mpirun --allow-run-as-root --oversubscribe"
for n in 20000 1000000; do
  [ -f "slab$n.dump" ] || python3 -c "from rollingdem import bench; x, v = bench.slab_state($n); bench.write_liggghts_dump('slab$n.dump', x, v, bench.RADIUS)"
done
for r in $(seq "$rounds"); do
  for n in 20000 1000000; do
    L=$(python3 -c "print(0.6 if $n <= 20000 else 3.7)")
    $M -np 2 liggghts -in "$here/liggghts_slab.run" -var rf epsd -var dump "slab$n.dump" -var L "$L" \
      -log "lig_slab${n}_r$r.log" > /dev/null
    t=$(grep 'Loop time' "lig_slab${n}_r$r.log" | awk '{print $4}')
    echo "round $r liggghts N=$n loop $t s $(python3 -c "print(round($n * 500 / $t / 1e6, 2))") M"
    rollingdem bench --scene slab --particles $n --steps 500 --threads 2 --json "rd_slab${n}_r$r.json" > /dev/null
    echo "round $r rollingdem N=$n $(python3 -c "import json; r=json.load(open('rd_slab${n}_r$r.json'))['results'][0]; print(round(r['wall_s'], 3), 's', round(r['particle_steps_per_s']/1e6, 2), 'M')")"
  done
done
