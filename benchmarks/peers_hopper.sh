#!/usr/bin/env bash
# Side-by-side timing of the mesh-hopper scene (20,000 spheres discharging from a 10,000-triangle
# STL hopper, 5,000 steps) on the identical state: LIGGGHTS 3.8 (fix mesh/surface + wall/gran, EPSD)
# and rollingdem (EPSD), alternating, ROUNDS rounds, at NPS processes/threads.
# Needs: apt-get install liggghts openmpi-bin.
# usage: [NPS="2 1"] benchmarks/peers_hopper.sh WORKDIR [ROUNDS]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
work="$1"; rounds="${2:-3}"
mkdir -p "$work"; cd "$work"
cp "$here/benchmarks/liggghts_hopper.run" .
# the scene's state (built and cached by rollingdem on first use) as a LIGGGHTS dump, and its STL
python3 - <<'PY'
from rollingdem import bench
sim = bench.hopper_simulation(20000)
bench.write_liggghts_dump("hopper.dump", sim.positions, sim.velocities, bench.HOPPER_RADIUS)
sim.walls[0].mesh.write("hopper.stl")
PY
M="mpirun --allow-run-as-root --oversubscribe"
for r in $(seq "$rounds"); do
  for np_ in ${NPS:-2 1}; do
    $M -np $np_ liggghts -in liggghts_hopper.run -var dump hopper.dump -var nsteps 5000 \
      -log "lig_np${np_}_r$r.log" > /dev/null
    echo "round $r liggghts np=$np_ $(grep 'Loop time' "lig_np${np_}_r$r.log")"
    rollingdem bench --scene mesh-hopper --threads $np_ --steps 5000 --json "rd_t${np_}_r$r.json" > /dev/null
    echo "round $r rollingdem threads=$np_ $(python3 -c "import json; r=json.load(open('rd_t${np_}_r$r.json'))['results'][0]; print(r['wall_s'], 's', r['particle_steps_per_s']/1e6, 'M', 'walls', r['split_s_per_step']['walls'])")"
  done
done
