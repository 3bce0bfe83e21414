"""Cold and warm compile time of the default kernel (Hertz-Mindlin, history, EPSD).

Both caches empty (fresh ROLLINGDEM_CACHE_DIR and NUMBA_CACHE_DIR in a temporary folder): this
process compiles the step loop that a scene of ``spheres`` spheres takes (default 600: the
threaded loop, as the default case's 1,000 spheres; 2: the serial loop), with the precompile
helper unless ROLLINGDEM_PRECOMPILE=0. Then a second process loads it from the caches.

usage: python benchmarks/cold_compile.py [spheres]
"""

import os
import subprocess
import sys
import tempfile
import time

spheres = int(sys.argv[1]) if len(sys.argv) > 1 else 600
caches = tempfile.mkdtemp(prefix="rollingdem-cold-")
os.environ["ROLLINGDEM_CACHE_DIR"] = os.path.join(caches, "kernels")
os.environ["NUMBA_CACHE_DIR"] = os.path.join(caches, "numba")
MEASURE = f"""
import time
tic = time.perf_counter()
from rollingdem import ContactModel
from rollingdem.bench import compile_time
t = compile_time(ContactModel("hertz", rolling="epsd"), {spheres})
print(f"{{time.perf_counter() - tic:.2f}} {{t:.2f}}")
"""
for label in ("cold", "warm"):
    out = subprocess.run([sys.executable, "-c", MEASURE], capture_output=True, text=True, check=True).stdout.split()
    print(f"{label}: {float(out[1]):.2f} s to compile or load and run one step, {float(out[0]):.2f} s with the import "
          f"({spheres} spheres)")
