"""What the fields measurement costs a run: a bed of N glass spheres (radius 0.9-1.1 mm, EPSD) settled
in a box periodic along x and y, then runs of 10,000 steps without and with ``ContinuumFields``
sampled every 1,000 steps (its .vti files and profile written), alternating, 4 rounds.

usage: python benchmarks/fields_cost.py [N=2000] [WIDTH=0.0011 m]
"""

import sys
import tempfile
import time

import rollingdem as rd

n = int(sys.argv[1]) if len(sys.argv) > 1 else 2000
width = float(sys.argv[2]) if len(sys.argv) > 2 else 0.0011
side = 0.016 * (n / 500) ** 0.5
sim = rd.Simulation(contact=rd.ContactModel(rolling="epsd"), periodic={"x": (0.0, side), "y": (0.0, side)})
sim.add_material(rd.Material("glass", youngs_modulus=5e6, poisson_ratio=0.3, density=2500.0, restitution=0.3,
                             friction=0.5, rolling_friction=0.2))
sim.add_wall(rd.Plane(point=(0, 0, 0), normal=(0, 0, 1)))
sim.insert(rd.BoxRegion((0, 0, 0), (side, side, 0.04)), count=n, radius=rd.Uniform(0.0009, 0.0011), material="glass",
           seed=1)
sim.run(1.0, until=rd.Settled())
out = tempfile.mkdtemp()
sim.run(steps=10, observers=[rd.ContinuumFields("warm", width=width, interval=1000 * sim.dt).write_to(out)])
seconds = {"without": [], "with": []}
grid = None
for r in range(4):
    for kind in (("without", "with") if r % 2 == 0 else ("with", "without")):
        fields = rd.ContinuumFields(f"f{r}", width=width, interval=1000 * sim.dt).write_to(out)
        tic = time.perf_counter()
        sim.run(steps=10_000, observers=[fields] if kind == "with" else [])
        seconds[kind].append(time.perf_counter() - tic)
        grid = fields.grid if kind == "with" else grid
ratios = sorted(w / wo for w, wo in zip(seconds["with"], seconds["without"]))
print(f"{n} spheres, grid {grid.shape}, width {width:g} m: 10,000 steps in "
      f"{min(seconds['without']):.2f}-{max(seconds['without']):.2f} s without the fields, "
      f"{min(seconds['with']):.2f}-{max(seconds['with']):.2f} s with them sampled every 1,000 steps; "
      f"ratios {' '.join(f'{x:.3f}' for x in ratios)}, median {0.5 * (ratios[1] + ratios[2]):.3f}")
