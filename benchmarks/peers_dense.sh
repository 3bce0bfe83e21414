#!/usr/bin/env bash
# Side-by-side timing on dense beds at rest, the identical state in the three codes: LIGGGHTS 3.8
# (EPSD), rollingdem (EPSD) and LAMMPS (rolling sds), alternating, ROUNDS rounds, at NPS processes /
# threads, STEPS steps timed (default 10,000). Two scenes (benchmarks/peers_dense.py writes their
# states from the bench's disk cache):
#   dense: the settled 20,000-sphere column of `rollingdem bench --scene dense-bed`, cylinder and plate kept;
#   rough: the bed of `rollingdem bench --scene rough-bed`: 20,000 free spheres on 9,898 fixed ones, in a
#          square box (plate and four side planes); the fixed spheres are not integrated, of infinite
#          mass to their partners, their mutual pairs excluded (as rollingdem leaves them out).
# Inputs: benchmarks/{liggghts,lammps}_{dense,rough}bed.run. At the end: the medians, rollingdem / the
# faster peer per scene and process count, and the three codes' last states side by side (atoms, dt,
# steps, contacts per sphere, speeds, displacements).
# All three start from positions and velocities alone (spins and contact histories zero), so the
# beds relax a little at first, alike. Known differences: LAMMPS has rolling sds, not EPSD; at a
# contact with a fixed sphere LIGGGHTS's EPSD dashpot takes the reduced rolling inertia of both
# spheres where rollingdem takes the free one's; the Debian LIGGGHTS build warns that its EPSD
# model is not whitelisted ("unoptimized, up to 20%"), as for benchmarks/peers.sh.
# Needs: apt-get install liggghts lammps openmpi-bin.
# usage: [NPS="2 1"] [STEPS=10000] benchmarks/peers_dense.sh WORKDIR [ROUNDS]
set -euo pipefail
here="$(cd "$(dirname "$0")/.." && pwd)"
work="$1"; rounds="${2:-3}"; steps="${STEPS:-10000}"
mkdir -p "$work"; cd "$work"
export PYTHONPATH="$here/src${PYTHONPATH:+:$PYTHONPATH}"  # this checkout's rollingdem
py="python3 $here/benchmarks/peers_dense.py"
M="mpirun --allow-run-as-root --oversubscribe"
loop() {  # "loop S s R M" from the "Loop time of S on P procs for N steps with A atoms" line of a log
  grep 'Loop time' "$1" | awk '{printf "loop %s s %.2f M\n", $4, $12 * $9 / $4 / 1e6}'; }
$py prepare .
for r in $(seq "$rounds"); do
  for scene in dense rough; do
    vars=$(cat "$scene.vars")
    for np_ in ${NPS:-2 1}; do
      tag="${scene}_np${np_}_r$r"
      $M -np $np_ liggghts -in "$here/benchmarks/liggghts_${scene}bed.run" -var dump "$scene.dump" $vars \
        -var nsteps "$steps" -var final "lig_$tag.final" -log "lig_$tag.log" > /dev/null
      echo "round $r $scene liggghts np=$np_ $(loop "lig_$tag.log")"
      $py time "$scene" "$scene.dump" "$steps" "$np_" "rd_$tag.json" "rd_$tag.final"
      echo "round $r $scene rollingdem threads=$np_ $(python3 -c "import json; r=json.load(open('rd_$tag.json'))['results'][0]; print('wall', round(r['wall_s'], 3), 's', round(r['particle_steps_per_s']/1e6, 2), 'M')")"
      $M -np $np_ lmp -in "$here/benchmarks/lammps_${scene}bed.run" -var data "$scene.data" $vars \
        -var nsteps "$steps" -var final "lmp_$tag.final" -log "lmp_$tag.log" > /dev/null
      echo "round $r $scene lammps np=$np_ $(loop "lmp_$tag.log")"
    done
  done
done
$py summary .
