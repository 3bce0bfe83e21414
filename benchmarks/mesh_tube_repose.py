"""Issue 27's acceptance figures: the tube the analytic cylinder and an open mesh tube of 96 flat
sides, for several seeds, each seed's pair run in turn: the built-in default case's settled column
height (its spheres settle 0.6 s in the tube on a plate; mean top of the highest 50 spheres), and
the 1,000-sphere pile of the seed report's case 3 (``experiments.pile.pile_run``: the column 1 diameter
high, the tube removed, the angle by rollingdem.analysis.repose.repose_angle).

usage: python benchmarks/mesh_tube_repose.py [SEEDS]   (default 4)
"""

import sys

import numpy as np

from rollingdem.experiments.pile import PileSetup, pile_run
from rollingdem.io.casefile import build_simulation, default_case_path, load_case
from rollingdem.io.mapping_file import read_mapping


def run(seed: int, segments):
    data = read_mapping(default_case_path())[0]
    data["particles"][0]["seed"] = seed
    if segments is not None:
        data["walls"][1] = {"type": "mesh", "name": "tube", "material": "table1", "shape": "drum",
                            "size": {"radius": data["walls"][1]["radius"], "length": 1.3, "segments": segments,
                                     "caps": False}}
    sim = build_simulation(load_case(data))
    sim.run(0.6)
    height = float(np.sort(sim.positions[:, 2] + sim.radii)[-50:].mean())
    pile = pile_run("epsd", count=1000, seed=seed, setup=PileSetup(tube_segments=segments))
    return height, pile.angle.angle if pile.angle is not None else float("nan")


def main():
    seeds = int(sys.argv[1]) if len(sys.argv) > 1 else 4
    rows = {None: [], 96: []}
    for seed in range(1, seeds + 1):
        for segments in (None, 96):
            h, a = run(seed, segments)
            rows[segments].append((h, a))
            print(f"seed {seed} {'cylinder' if segments is None else 'mesh 96':9s} height {h:.5f} m  angle {a:.2f} deg",
                  flush=True)
    for segments, label in ((None, "cylinder"), (96, "mesh 96")):
        arr = np.array(rows[segments])
        print(f"{label:9s} height {arr[:, 0].mean():.5f} +- {arr[:, 0].std(ddof=1):.5f} m; "
              f"angle {arr[:, 1].mean():.2f} +- {arr[:, 1].std(ddof=1):.2f} deg (seed-to-seed sd)")
    cyl, mesh = np.array(rows[None]), np.array(rows[96])
    print(f"mesh / cylinder height: {mesh[:, 0].mean() / cyl[:, 0].mean():.4f}; angle difference "
          f"{mesh[:, 1].mean() - cyl[:, 1].mean():+.2f} deg")


if __name__ == "__main__":
    main()
