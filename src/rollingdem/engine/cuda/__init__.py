"""The GPU backend: the step loop and the neighbor-list rebuild in CUDA kernels around the CPU's own compiled functions."""
