"""Where the step loop runs: the backends, behind one protocol, in one registry.

A backend gives the engine a step loop for a state and a contact law's engine module: a callable
with the arguments of the module's ``advance`` (``EngineState.step_loop_args``) that allocates what it
needs at its first use, takes the records where it steps (uploads them), steps up to n steps with
the same ``info`` bookkeeping, and leaves the records on the host again at its end (downloads
them). It also times each phase of a step on the present state (``rollingdem bench``), says how
many bytes it holds on its device, and whether the engine module's CPU step loop must be compiled
for it. ``BACKENDS`` holds them by name; ``backend(name)`` checks a name and this machine.
"""

from __future__ import annotations

import os

from rollingdem.engine.phases import Passes, cpu_phase_seconds
from rollingdem.errors import ParameterError


class Backend:
    """The protocol every backend follows (``CpuBackend``, ``CudaBackend``)."""

    name = ""
    summary = ""
    #: whether it steps on this machine's cores (its engine module's step loop compiled ahead and
    #: cached on disk) rather than on a device, where kernels compile at their first launch
    on_host = True

    def check(self) -> None:
        """Nothing if this machine can step on the backend; else a ParameterError in one line that
        says what is missing."""

    def step_loop(self, state, module):
        """The step loop of ``module`` (an engine module) for ``state``."""
        raise NotImplementedError

    def serial_step_loop(self, state) -> bool | None:
        """Which CPU step loop of the engine module the backend runs, for ``engine_module`` to
        compile it ahead (``advance_serial`` if True, ``advance`` if False), or None for neither."""
        return None

    def phase_seconds(self, state, module, step_inputs, repeats: int, rebuilds_per_step: float) -> dict:
        """Seconds per step of each of ``phases.PHASES`` on the present state, which is left as it
        was; a backend may add phases of its own. ``step_inputs``: (dt, gravity, skin, pair_params)."""
        raise NotImplementedError

    def device_bytes(self, state) -> int:
        """The bytes the backend held on its device at the state's last run (0: none)."""
        return 0

    def note(self) -> str:
        """What a timing on this backend means, for the bench's results ("" if nothing to add)."""
        return ""


class CpuBackend(Backend):
    name = "cpu"
    summary = "Numba threads on this machine's cores"

    def step_loop(self, state, module):
        return module.advance_serial if state.serial() else module.advance

    def serial_step_loop(self, state) -> bool | None:
        return state.serial()

    def phase_seconds(self, state, module, step_inputs, repeats, rebuilds_per_step):
        return cpu_phase_seconds(Passes(state, module, *step_inputs), repeats, rebuilds_per_step)


class CudaBackend(Backend):
    name = "cuda"
    summary = "an NVIDIA GPU (docs/gpu.md)"
    on_host = False

    def check(self) -> None:
        from rollingdem.engine.cuda.target import require  # optional: the GPU backend only

        require()

    def step_loop(self, state, module):
        """One ``CudaStepLoop`` per engine module and state, kept with the state: its kernels
        compile at their first launch."""
        loops = state.backend_data.setdefault(self.name, {})
        loop = loops.get(module.__name__)
        if loop is None:
            from rollingdem.engine.cuda.step_loop import CudaStepLoop  # optional: the GPU backend only

            loop = loops[module.__name__] = CudaStepLoop(module)
        return loop

    def phase_seconds(self, state, module, step_inputs, repeats, rebuilds_per_step):
        """The device's time of each pass on a copy of the state on the device
        (``CudaStepLoop.phase_seconds``), named as the CPU's phases, and the host's share: its time
        to launch a step's kernels, which the device's work overlaps (a step is bound by the host
        where it is the larger), and the step's synchronisation, the read of its flag counts."""
        dt, gravity, skin, pair_params = step_inputs
        state.energy_for(module)
        seconds = self.step_loop(state, module).phase_seconds(repeats, *state.step_loop_args(dt, gravity, skin,
                                                                                           pair_params))
        return {"contact forces": seconds["pairs"],
                "walls": max(seconds["gather"] - seconds["gather without walls"], 0.0),
                "integration and gathering": seconds["gather without walls"],
                "neighbor search": seconds["rebuild"] * rebuilds_per_step,
                "host launches (overlapped)": seconds["launch"],
                "flag read (synchronisation)": seconds["flag read"]}

    def device_bytes(self, state) -> int:
        return max((loop.device_bytes for loop in state.backend_data.get(self.name, {}).values()), default=0)

    def note(self) -> str:
        return (f"on the GPU ({self.name}): each phase timed apart on a copy of the state, the host's launches "
                "overlapping the device's work")


BACKENDS = {b.name: b for b in (CpuBackend(), CudaBackend())}


def register(instance: Backend) -> Backend:
    """Add a backend to the registry under its ``name`` (new): ``Simulation(backend=name)``, case
    files and ``--backend`` then take it."""
    if not instance.name or instance.name in BACKENDS:
        raise ValueError(f"a backend needs a name of its own, not {instance.name!r}")
    BACKENDS[instance.name] = instance
    return instance


def backend(value, name: str = "backend") -> Backend:
    """The backend named ``value``, checked to run on this machine; else one line naming ``name``
    (an unknown backend, or what the machine lacks for it)."""
    if value not in BACKENDS:
        raise ParameterError(f"{name} = {value!r} is not allowed: must be one of {', '.join(BACKENDS)}")
    found = BACKENDS[value]
    found.check()
    return found


def check_backend(value, name: str = "backend") -> str:
    """``value``, checked as ``backend`` checks it."""
    return backend(value, name).name


def default_backend() -> str:
    """The backend of a Simulation not told one: ``ROLLINGDEM_BACKEND``, else ``"cpu"`` (how
    ``rollingdem validate --backend`` reaches the simulations of every experiment and worker)."""
    return check_backend(os.environ.get("ROLLINGDEM_BACKEND", "") or "cpu", "ROLLINGDEM_BACKEND")
