"""Real-time scheduling for a servo thread on Linux: SCHED_FIFO priority and a CPU of its own.

A paced loop misses a deadline when the OS runs something else on its core at the wrong
moment. Robot controllers cure it the same way: run the servo thread under SCHED_FIFO, which
preempts every ordinary task, pinned to one CPU. Both need privileges (root, CAP_SYS_NICE, or
an `rtprio` limit in /etc/security/limits.conf); without them `realtime_thread` changes
nothing and says why.

The pacer sleeps (clock_nanosleep) until `spin_time` before each deadline and spins the
rest. An ordinary thread spins up to 1.5 ms (its sleep can overshoot by a millisecond on a
busy machine), so at 1 kHz and above it spins all the time. A SCHED_FIFO thread must not:
Linux's RT throttling (`/proc/sys/kernel/sched_rt_runtime_us`, 95 % by default) stops a
real-time thread that ran 95 % of a second for the rest of it, which missed ~5 % of the
deadlines (50 ms every second); its sleeps wake within tens of µs, so it spins at most
0.2 ms, and never more than half the period. Where RT throttling is off
(`sysctl kernel.sched_rt_runtime_us=-1`, as on a machine whose servo core is its own) it
spins like an ordinary thread: at 10 kHz a wake-up from a 50 µs sleep comes late more often
than a spinning thread is interrupted (docs/engine-log.md).
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass, field

DEFAULT_PRIORITY = 80
"""SCHED_FIFO priority (1–99): above the kernel's threaded IRQ handlers (50), below its watchdogs (99)."""
SPIN_ORDINARY_S = 1.5e-3
"""How long (s) an ordinary thread's paced tick spins before its deadline, at most."""
SPIN_REALTIME_S = 2e-4
"""How long (s) a SCHED_FIFO or SCHED_RR thread's paced tick spins before its deadline, at most."""


def realtime_policy() -> bool:
    """Whether the calling thread runs under SCHED_FIFO or SCHED_RR."""
    try:
        return os.sched_getscheduler(0) in (os.SCHED_FIFO, os.SCHED_RR)
    except (AttributeError, OSError):
        return False


RT_RUNTIME = "/proc/sys/kernel/sched_rt_runtime_us"
"""Linux's RT throttling: µs of each period real-time threads may run (-1: unlimited)."""


def rt_throttled() -> bool:
    """Whether Linux throttles real-time threads (RT_RUNTIME is not -1); True where unknown."""
    try:
        with open(RT_RUNTIME) as f:
            return int(f.read().strip()) >= 0
    except (OSError, ValueError):
        return True


def spin_time(rate_hz: float) -> float:
    """How long (s) a paced tick of the calling thread spins before its deadline after
    sleeping: SPIN_REALTIME_S, at most half the period, under a real-time policy that Linux
    throttles (a thread spinning 95 % of its core is stopped); else SPIN_ORDINARY_S."""
    if realtime_policy() and rt_throttled():
        return min(SPIN_REALTIME_S, 0.5 / rate_hz)
    return SPIN_ORDINARY_S


@dataclass
class Granted:
    """What the calling thread got: its SCHED_FIFO priority and CPUs (None where a request was
    refused or not made), and one line per refusal."""

    priority: int | None = None
    cpus: set[int] | None = None
    refused: list[str] = field(default_factory=list)

    def __str__(self) -> str:
        got = []
        if self.priority is not None:
            got.append(f"SCHED_FIFO priority {self.priority}")
        if self.cpus is not None:
            got.append(f"CPU {','.join(map(str, sorted(self.cpus)))}")
        text = ", ".join(got) or "ordinary scheduling"
        return text + ("" if not self.refused else f" ({'; '.join(self.refused)})")


def check_priority(priority) -> None:
    """ValueError unless `priority` is a SCHED_FIFO priority (an integer from 1 to 99)."""
    if isinstance(priority, bool) or not (isinstance(priority, int) and 1 <= priority <= 99):
        raise ValueError(f"real-time priority must be an integer from 1 to 99, got {priority!r}")


@contextmanager
def realtime_thread(priority: int | None = DEFAULT_PRIORITY, cpu: int | None = None):
    """Run the calling thread under SCHED_FIFO at `priority` (None: leave the policy) and pinned
    to `cpu` (None: leave the affinity) until the block ends, then restore both. Yields a
    `Granted`; a request the OS refuses is reported there, never raised."""
    if priority is not None:
        check_priority(priority)
    granted = Granted()
    policy = param = affinity = None
    if not hasattr(os, "sched_setscheduler"):
        granted.refused.append("this OS has no SCHED_FIFO")
        priority = cpu = None
    if priority is not None:
        try:
            policy, param = os.sched_getscheduler(0), os.sched_getparam(0)
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(priority))
            granted.priority = priority
        except (PermissionError, OSError) as exc:
            policy = None
            granted.refused.append(f"SCHED_FIFO refused: {exc.strerror or exc}; needs root, CAP_SYS_NICE "
                                   "or an rtprio limit")
    if cpu is not None:
        try:
            affinity = os.sched_getaffinity(0)
            os.sched_setaffinity(0, {cpu})
            granted.cpus = {cpu}
        except (OSError, ValueError) as exc:
            affinity = None
            granted.refused.append(f"CPU {cpu} refused: {getattr(exc, 'strerror', None) or exc}")
    try:
        yield granted
    finally:
        if affinity is not None:
            os.sched_setaffinity(0, affinity)
        if policy is not None:
            os.sched_setscheduler(0, policy, param)
