"""Is the servo process still there? The viewer watches it and closes itself once it is gone.

A viewer whose servo process died (killed, crashed) has nothing left to show; left alone it
would draw on forever. `ServoWatch(pid).gone()` costs a few µs, so the viewer asks it at
every display-loop turn (and every 0.1 s of a long sleep) and is gone within ~0.1 s.

How: a pidfd (Linux >= 5.3) becomes readable when the process ends, and cannot be fooled by
a later process reusing the pid; where there is none, `kill(pid, 0)`. When the servo
process is the viewer's own parent (as `softproxy run` starts it), a changed `getppid()`
says so too: the viewer was handed to another parent because its own died.
"""

from __future__ import annotations

import os
import select
import time


class ServoWatch:
    """Watches process `pid` (None or <= 1: watches nothing, `gone()` is always False)."""

    def __init__(self, pid: int | None) -> None:
        self.pid = int(pid) if pid is not None and int(pid) > 1 else None
        self._fd: int | None = None
        self._dead = False
        self._is_parent = self.pid is not None and self.pid == os.getppid()
        if self.pid is None:
            return
        try:
            self._fd = os.pidfd_open(self.pid)
        except ProcessLookupError:
            self._dead = True
        except (AttributeError, OSError):  # no pidfd here (old kernel, not Linux): kill(pid, 0)
            self._fd = None

    def gone(self) -> bool:
        """True once the watched process has ended (and from then on)."""
        if self.pid is None:
            return False
        if not self._dead:
            self._dead = self._ended()
        return self._dead

    def sleep(self, seconds: float, slice_s: float = 0.1) -> bool:
        """Sleep `seconds`, looking every `slice_s` s; True (at once) if the process is gone."""
        end = time.monotonic() + seconds
        while True:
            if self.gone():
                return True
            rest = end - time.monotonic()
            if rest <= 0.0:
                return False
            time.sleep(min(rest, slice_s))

    def _ended(self) -> bool:
        if self._is_parent and os.getppid() != self.pid:
            return True
        if self._fd is not None:
            readable, _, _ = select.select([self._fd], [], [], 0)
            return bool(readable)
        try:
            os.kill(self.pid, 0)
        except ProcessLookupError:
            return True
        except PermissionError:  # someone else's process: it exists
            return False
        return False

    def close(self) -> None:
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None
