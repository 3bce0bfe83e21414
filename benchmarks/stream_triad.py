"""Memory bandwidth of this machine from cache and from DRAM: python benchmarks/stream_triad.py

A STREAM-like triad ``a = b + s c`` compiled with Numba on all threads, over arrays of 1.6, 8 and
240 MB (3 arrays each: 4.8 MB and 24 MB stay in a large L3 cache, 720 MB come from DRAM), in GB/s
(24 B read and 8 B written per element, as STREAM counts them). A step whose cost is its memory
traffic slows by the ratio of the in-cache to the DRAM figure once its state leaves the cache
(docs/scaling.md).
"""
import time

import numpy as np
from numba import njit, prange


@njit(parallel=True)
def triad(a, b, c, s):
    for i in prange(a.shape[0]):
        a[i] = b[i] + s * c[i]


for n in (200_000, 1_000_000, 30_000_000):
    a = np.zeros(n)
    b = np.ones(n)
    c = np.ones(n)
    triad(a, b, c, 2.0)
    times = []
    for _ in range(max(5, int(3e9 / (32 * n)))):
        tic = time.perf_counter()
        triad(a, b, c, 2.0)
        times.append(time.perf_counter() - tic)
    print(f"{8 * n / 1e6:7.1f} MB per array: triad {32 * n / np.median(times) / 1e9:6.1f} GB/s (median of {len(times)})")
