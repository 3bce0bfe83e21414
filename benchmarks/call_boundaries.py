"""Does the state depend on how a run's steps are cut into kernel calls? It should not.

    python benchmarks/call_boundaries.py        # prints one hash per call length; all should agree

The scene is the two-material mixture of ``benchmarks/result_hashes.py`` (3,000 spheres poured into
a cylinder, EPSD with Marshall twisting), stepped 1,024 steps in calls of 64, 16 and 4 steps on
one thread.
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

from result_hashes import mixture_simulation, state_hash  # noqa: E402


def main() -> int:
    from rollingdem.threads import fix_threads

    fix_threads(1)
    hashes = {}
    for call in (64, 16, 4):
        sim = mixture_simulation()
        for _ in range(1024 // call):
            sim.run(steps=call)  # one kernel call each: run's first chunk is 64 steps
        hashes[call] = state_hash(sim)
        print(f"calls of {call:3d} steps: {hashes[call]}", flush=True)
    same = len(set(hashes.values())) == 1
    print("equal" if same else "DIFFERENT")
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
