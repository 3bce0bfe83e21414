"""Cold and warm compile time of an engine module (default: Hertz-Mindlin, history, EPSD).

Both caches empty (fresh ROLLINGDEM_CACHE_DIR and NUMBA_CACHE_DIR in a temporary folder): a
process compiles the step loop that a scene of ``spheres`` spheres takes (default 600: the
threaded loop; 2: the serial loop), with the precompile helper unless ROLLINGDEM_PRECOMPILE=0.
Then a second process loads it from the caches. KEY=VALUE arguments name another contact law, as
``ContactModel`` takes them (normal=linear rolling=rrlinear); ``--mesh`` adds a mesh wall (the
module with the mesh passes, as a drum, silo or hopper takes).

usage: python benchmarks/cold_compile.py [spheres] [KEY=VALUE ...] [--mesh]
"""

import os
import subprocess
import sys
import tempfile

mesh = "--mesh" in sys.argv
args = [a for a in sys.argv[1:] if "=" not in a and a != "--mesh"]
law = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a) or {"normal": "hertz", "rolling": "epsd"}
spheres = int(args[0]) if args else 600
caches = tempfile.mkdtemp(prefix="rollingdem-cold-")
os.environ["ROLLINGDEM_CACHE_DIR"] = os.path.join(caches, "kernels")
os.environ["NUMBA_CACHE_DIR"] = os.path.join(caches, "numba")
MEASURE = f"""
import time
tic = time.perf_counter()
from rollingdem import ContactModel
from rollingdem.bench import compile_time
t = compile_time(ContactModel(**{law!r}), {spheres}, mesh={mesh})
print(f"{{time.perf_counter() - tic:.2f}} {{t:.2f}}")
"""
for label in ("cold", "warm"):
    out = subprocess.run([sys.executable, "-c", MEASURE], capture_output=True, text=True, check=True).stdout.split()
    print(f"{label}: {float(out[1]):.2f} s to compile or load and run one step, {float(out[0]):.2f} s with the import "
          f"({spheres} spheres, {law}{', a mesh wall' if mesh else ''})")
