"""Cost per particle-step at 20,000 and 10^6 spheres at the same contact density.

The settled columns of the disk cache (``rollingdem.bench.settled_column``), cylinder kept: two
beds at rest with ~4.2 contacts and ~8.2 neighbors per sphere at both sizes. Unlike the collapse,
whose narrow 20,000-sphere column sheds its contacts (1.8 per sphere) while the wide 10^6 bed keeps
them (4.0), this compares the same work per sphere, so the ratio is what N itself costs.
Both are stepped in turn, in chunks of 100 steps, so that both see the same load of the machine.

usage: python benchmarks/bed_scaling.py [THREADS] [CHUNKS]
"""
import sys

import numba
import numpy as np

numba.set_num_threads(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
from rollingdem import bench  # noqa: E402

chunks = int(sys.argv[2]) if len(sys.argv) > 2 else 6
sims = [bench.settled_column(n) for n in (20000, 1_000_000)]
for sim in sims:
    bench._warm_up(sim)
walls = np.zeros((2, chunks))
for c in range(chunks):
    for s, sim in enumerate(sims):
        walls[s, c], _ = bench._timed_steps(sim, 100)
per = walls / np.array([[sim.n_particles] for sim in sims])
for s, sim in enumerate(sims):
    contacts, neighbors = bench._contacts_per_particle(sim)
    print(f"N={sim.n_particles}: {sim.n_particles * 100 * chunks / walls[s].sum() / 1e6:.2f} M particle-steps/s, "
          f"contacts/p {contacts:.2f}, neighbors/p {neighbors:.2f}")
print(f"cost per particle-step at 10^6 / at 20,000: {per[1].sum() / per[0].sum():.2f}x "
      f"(chunk by chunk {', '.join(f'{r:.2f}' for r in per[1] / per[0])})")
