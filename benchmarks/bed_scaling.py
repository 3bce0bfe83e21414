"""Cost per particle-step at 20,000 and 10^6 spheres at the same contact density.

The settled columns of the disk cache (``rollingdem.bench.settled_column``), cylinder kept: two
beds at rest with ~4.2 contacts and ~8.2 neighbors per sphere at both sizes. Unlike the collapse,
whose narrow 20,000-sphere column sheds its contacts (1.8 per sphere) while the wide 10^6 bed keeps
them (4.0), this compares the same work per sphere, so the ratio is what N itself costs.
``bench.scaling`` steps both in turn, in chunks, so that both see the same load of the machine.

usage: python benchmarks/bed_scaling.py [THREADS] [STEPS, default 600]
"""
import sys

import numba

numba.set_num_threads(int(sys.argv[1]) if len(sys.argv) > 1 else 2)
from rollingdem import bench  # noqa: E402

for result in bench.scaling(steps=int(sys.argv[2]) if len(sys.argv) > 2 else 600, scene="column-bed"):
    print(bench.format_row(result))
