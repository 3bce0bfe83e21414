"""The progress bar of ``Simulation.run(progress=True)``."""

from __future__ import annotations

import sys

from tqdm import tqdm


def clock(seconds: float) -> str:
    """``m:ss`` or ``h:mm:ss``."""
    m, sec = divmod(int(round(seconds)), 60)
    h, m = divmod(m, 60)
    return f"{h}:{m:02d}:{sec:02d}" if h else f"{m}:{sec:02d}"


class Progress:
    """tqdm bar over simulated time with steps/s and time left. Until the first chunk of steps is
    back it says "compiling" (the first call compiles the step loop, or loads it from Numba's
    cache), and the rate and the time left count only the chunks after it; ``warm``: the step loop
    has run before, so the first chunk counts too and nothing is said of compiling."""

    def __init__(self, sim, steps, label, warm=False):
        self.total_time = steps * sim.dt
        self.label = label
        self.bar = tqdm(total=round(self.total_time, 12), desc=label if warm else f"{label} (compiling)", unit="s(sim)",
                        unit_scale=False, mininterval=0.5 if sys.stderr.isatty() else 10.0,
                        bar_format="{desc}: {percentage:3.0f}%|{bar}| t={n:.4g}/{total:.4g} s [{elapsed}{postfix}]")
        self.dt = sim.dt
        self.total_steps = steps
        self.warm = warm
        self.done = 0
        self.steps = 0  # after the first chunk
        self.wall = 0.0

    def update(self, sim, todo, elapsed):
        self.done += todo
        if self.done == todo and not self.warm:  # the first chunk: compile time, not the stepping rate
            self.bar.set_description_str(self.label, refresh=False)
        else:
            self.steps += todo
            self.wall += elapsed
        if self.steps:
            rate = self.steps / max(self.wall, 1e-9)
            left = max(self.total_steps - self.done, 0) / rate
            self.bar.set_postfix_str(f"{rate:,.0f} steps/s, {clock(left)} left", refresh=False)
        self.bar.update(min(todo * self.dt, self.bar.total - self.bar.n))

    def close(self):
        self.bar.close()
