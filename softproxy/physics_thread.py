"""Two rates in two threads: MuJoCo stepping at the physics rate beside a real-time servo loop.

`ServoLoop.run(realtime=True)` on a loop with two rates (`physics_rate_hz`) runs MuJoCo in a
`PhysicsThread` for the length of the run: `softproxy.compiled.handoff.run_physics`, compiled
and without the GIL, steps the world on its own schedule and hands its state to the servo
thread and takes the fingers' wrenches back through the lock-free handoff; the servo thread
never waits for it. Lockstep runs (`run(realtime=False)`, `tick()`) step MuJoCo in the servo
thread every `physics_every` ticks instead, deterministically.
"""

from __future__ import annotations

import threading
import time

import numpy as np

from softproxy.compiled import handoff as kernel
from softproxy.compiled import native
from softproxy.compiled.dispatch import entry
from softproxy.local_model import LocalModel, mj_arrays

FIRST_STATE_S = 5.0
"""How long `start` waits for MuJoCo's first published state (s) before it gives up."""


class PhysicsThread:
    """MuJoCo's thread for one run: `start()` before the servo ticks, `stop()` after (joins,
    clears the wrenches it left in xfrc_applied). Its counters: `steps`, `late` (steps that
    started more than a step after they were due: the world fell behind real time),
    `max_cost_s` (the most a step's mj_step1 + mj_step2 took)."""

    def __init__(self, world, local: LocalModel, period_s: float) -> None:
        self.world, self.local = world, local
        self.period_ns = max(1, int(round(period_s * 1e9)))
        m, d = (np.uintp(a) for a in native.addresses(world.model, world.data))
        self._state = mj_arrays(world.data)
        self._sums = np.zeros((world.model.nbody, 2, 6))
        self._args = (m, d, self._state, local.handoff, world.data.xfrc_applied, local.moving, self.period_ns)
        self._run = entry(kernel.run_physics, (*self._args, 0, self._sums), "MuJoCo's thread")
        self._thread: threading.Thread | None = None
        self.error: BaseException | None = None

    @property
    def ctl(self) -> np.ndarray:
        return self.local.handoff.ctl

    def start(self) -> None:
        """Start stepping now; return once MuJoCo's first state is published."""
        ctl = self.ctl
        seq = int(self.local.handoff.seq[0])
        ctl[kernel.STOP] = ctl[kernel.TAKEN] = 0  # the servo side starts afresh from this run's first state
        ctl[kernel.SEEN] = seq
        start_ns = native.monotonic_ns()

        def body() -> None:
            try:
                self._run(*self._args, start_ns, self._sums)
            except BaseException as exc:  # noqa: BLE001 (kept for the servo side to raise)
                self.error = exc

        self._thread = threading.Thread(target=body, name="softproxy-physics", daemon=True)
        self._thread.start()
        deadline = time.monotonic() + FIRST_STATE_S
        while int(self.local.handoff.seq[0]) <= seq + 1 and self._thread.is_alive():
            if time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"MuJoCo's thread published no state in {FIRST_STATE_S:g} s")
            time.sleep(1e-4)

    def stop(self) -> None:
        """Stop after the current step and wait for it; the wrenches it applied are cleared."""
        self.ctl[kernel.STOP] = 1
        if self._thread is not None:
            self._thread.join()
            self._thread = None
        self.world.data.xfrc_applied[self.local.moving] = 0.0
        if self.error is not None:
            raise RuntimeError(f"MuJoCo's thread failed: {self.error}") from self.error

    @property
    def steps(self) -> int:
        return int(self.ctl[kernel.STEPS])

    @property
    def late(self) -> int:
        return int(self.ctl[kernel.LATE])

    @property
    def max_cost_s(self) -> float:
        return float(self.ctl[kernel.MAX_COST_NS]) * 1e-9
