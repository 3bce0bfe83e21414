"""The one module that imports Numba's CUDA target (docs/gpu.md).

rollingdem's GPU kernels are thin CUDA kernels around the same compiled functions the CPU engine
runs (``rollingdem.engine.codegen``' generated module): numba-cuda compiles a ``numba.njit`` function
called from a CUDA kernel as a device function, so the contact laws have one source. Everything
that touches ``numba.cuda`` is here, so that a change of CUDA binding (numba-cuda-mlir, Warp) is a
change of this file: availability and its error messages, kernel compilation, device memory, the
simulator, and compiling to PTX without a device.

Kernels take the engine's records (``rollingdem.engine.layout``): named tuples of arrays. The CUDA
simulator (``NUMBA_ENABLE_CUDASIM=1``) passes a named tuple into a kernel unchanged, so its arrays
stay NumPy arrays that the compiled functions accept; a bare array argument would be wrapped, so
kernels take arrays only inside records.
"""

from __future__ import annotations

import os

import numpy as np

from rollingdem.errors import ParameterError

#: compute capabilities the PTX check compiles for: A100 (8.0) and H100/H200 (9.0)
PTX_TARGETS = ((8, 0), (9, 0))
INSTALL_HINT = 'install the GPU extra: pip install "rollingdem[cuda]"'


def simulated() -> bool:
    """Whether Numba's CUDA simulator stands in for a device (``NUMBA_ENABLE_CUDASIM=1``)."""
    return os.environ.get("NUMBA_ENABLE_CUDASIM", "0") not in ("", "0")


def cuda_module():
    """``numba.cuda`` as numba-cuda provides it; a ParameterError naming what is missing."""
    try:
        import numba_cuda  # noqa: F401  (numba-cuda, not Numba's deprecated built-in target)
        from numba import cuda  # optional: the GPU backend only
    except ImportError as error:
        if simulated():
            from numba import cuda  # the simulator needs no numba-cuda

            return cuda
        raise ParameterError(f"backend 'cuda' needs numba-cuda, which is not installed ({error}); "
                             f"{INSTALL_HINT}") from None
    return cuda


def require():
    """``numba.cuda``, checked to have a device (or the simulator): otherwise one line that says
    what is missing, the driver or the device."""
    cuda = cuda_module()
    if simulated():
        return cuda
    try:
        ok = cuda.is_available()
    except Exception as error:  # the driver library itself failed to load
        raise ParameterError(f"backend 'cuda' found no usable CUDA driver ({type(error).__name__}: "
                             f"{str(error).strip().splitlines()[0] if str(error).strip() else ''}); it needs an "
                             "NVIDIA GPU with its driver, or NUMBA_ENABLE_CUDASIM=1 for the slow simulator") from None
    if not ok:
        why = "no CUDA driver library was found" if not _driver_found(cuda) else "the driver lists no CUDA device"
        raise ParameterError(f"backend 'cuda' has no GPU to run on: {why}; it needs an NVIDIA GPU with its "
                             "driver, or NUMBA_ENABLE_CUDASIM=1 for the slow simulator")
    return cuda


def _driver_found(cuda) -> bool:
    try:
        cuda.cudadrv.driver.driver.get_device_count()
    except Exception:
        return False
    return True


def kernel(function):
    """``function`` as a CUDA kernel (compiled at its first launch, for the arguments' types)."""
    return require().jit(function)


def launch(compiled, count: int, *args) -> None:
    """Run ``compiled`` on ``count`` threads (one per item), in blocks of up to 128 (the simulator
    runs a block's threads as Python threads: it gets blocks of at most 32)."""
    if count <= 0:
        return
    block = min(32 if simulated() else 128, count)
    compiled[(count + block - 1) // block, block](*args)


def device_zeros(shape, dtype):
    """A zeroed array on the device (a host array in the simulator)."""
    if simulated():
        return np.zeros(shape, dtype=dtype)
    return cuda_module().to_device(np.zeros(shape, dtype=dtype))


def to_device(record, copy: bool = False):
    """A record's arrays on the device (a record of device arrays); the simulator keeps the host
    record, so that the compiled functions run on NumPy arrays, or a copy of it (``copy``): arrays
    that the kernels may change without changing the host's."""
    if simulated():
        return type(record)(*(a.copy() for a in record)) if copy else record
    cuda = cuda_module()
    return type(record)(*(cuda.to_device(a) for a in record))


def synchronize() -> None:
    """Wait for the device to finish the work launched so far (the simulator has none pending)."""
    if not simulated():
        cuda_module().synchronize()


def to_host(device_record, host_record) -> None:
    """Copy a device record's arrays back into the host record's arrays, in place."""
    if simulated():
        return
    for d, h in zip(device_record, host_record):
        d.copy_to_host(h)


def array_to_host(device_array) -> np.ndarray:
    """A device array's values on the host (the simulator's is a host array already)."""
    if simulated() or isinstance(device_array, np.ndarray):
        return device_array
    return device_array.copy_to_host()


def compile_ptx(function, argument_types, cc) -> str:
    """PTX for ``function`` (a kernel body) at compute capability ``cc``, through NVIDIA's NVVM from
    PyPI (``nvidia-cuda-nvcc-cu12``): no device, driver or NVRTC needed. numba-cuda asks the current
    device for the capability of each device function it compiles, and NVRTC for the capabilities
    it may target; here it is told ``cc`` for both, for the duration."""
    import numba_cuda  # noqa: F401
    from numba.cuda import compile_ptx as compile_function  # optional: the GPU backend only
    from numba.cuda import config, dispatcher  # optional: the GPU backend only

    class _Device:
        compute_capability = tuple(cc)

    saved = dispatcher.get_current_device, config.FORCE_CUDA_CC
    dispatcher.get_current_device = lambda: _Device
    config.FORCE_CUDA_CC = tuple(cc)
    try:
        ptx, _ = compile_function(function, argument_types, cc=tuple(cc))
    finally:
        dispatcher.get_current_device, config.FORCE_CUDA_CC = saved
    return ptx
