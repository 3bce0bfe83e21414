"""Where a cold compile of an engine module goes: the seconds Numba spends on each compiled function
itself (its callees' compiles taken out), one process, both caches empty, the precompile helper off.

usage: python benchmarks/compile_profile.py [SPHERES=600] [KEY=VALUE ...]   (as benchmarks/cold_compile.py)
"""

import collections
import os
import sys
import tempfile
import time

caches = tempfile.mkdtemp(prefix="rollingdem-profile-")
os.environ["ROLLINGDEM_CACHE_DIR"] = os.path.join(caches, "kernels")
os.environ["NUMBA_CACHE_DIR"] = os.path.join(caches, "numba")
os.environ["ROLLINGDEM_PRECOMPILE"] = "0"

from numba.core import event  # noqa: E402

seconds = collections.defaultdict(float)
open_compiles = []


class Exclusive(event.Listener):
    def on_start(self, ev):
        open_compiles.append((ev.data["dispatcher"].py_func.__qualname__, time.perf_counter()))

    def on_end(self, ev):
        name, start = open_compiles.pop()
        spent = time.perf_counter() - start
        seconds[name] += spent
        if open_compiles:  # the caller's own time excludes this
            seconds[open_compiles[-1][0]] -= spent


event.register("numba:compile", Exclusive())

from rollingdem import ContactModel  # noqa: E402
from rollingdem.bench import compile_time  # noqa: E402

args = [a for a in sys.argv[1:] if "=" not in a]
law = dict(a.split("=", 1) for a in sys.argv[1:] if "=" in a) or {"normal": "hertz", "rolling": "epsd"}
tic = time.perf_counter()
compile_time(ContactModel(**law), int(args[0]) if args else 600)
print(f"{time.perf_counter() - tic:.1f} s in all ({law}); the functions over 0.3 s, each without its callees:")
for name, s in sorted(seconds.items(), key=lambda kv: -kv[1]):
    if s >= 0.3:
        print(f"{s:6.2f} {name}")
