"""Real-time scheduling for a servo thread on Linux: SCHED_FIFO priority and a CPU of its own.

A paced loop misses a deadline when the OS runs something else on its core at the wrong
moment. Robot controllers cure it the same way: run the servo thread under SCHED_FIFO, which
preempts every ordinary task, pinned to one CPU. Both need privileges (root, CAP_SYS_NICE, or
an `rtprio` limit in /etc/security/limits.conf); without them `realtime_thread` changes
nothing and says why. The pacer sleeps (clock_nanosleep) until shortly before each deadline
and spins only the last `spin_s`, so a FIFO servo thread leaves most of its core to others,
and Linux's RT throttling (`/proc/sys/kernel/sched_rt_runtime_us`, 95 % by default) bounds it.
"""

from __future__ import annotations

import os
from contextlib import contextmanager
from dataclasses import dataclass, field

DEFAULT_PRIORITY = 80
"""SCHED_FIFO priority (1–99): above the kernel's threaded IRQ handlers (50), below its watchdogs (99)."""


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
