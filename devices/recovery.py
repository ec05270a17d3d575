"""The failed state the hardware adapters share: a failure counted once, the device reopened
every REOPEN_INTERVAL_S of its clock while failed, recovered on its next valid sample; and, for
an adapter that writes zero force itself on close, up to CLOSE_ZERO_ATTEMPTS tries of it.

`FaultRecovery` is a mixin. The adapter says what a failure is (`_fail`, which calls
`_enter_failure`), how to reopen (`_try_reopen`) and when it is back (its `_recover` calls
`_reopen_when_due`, its read calls `_fresh_sample` on a valid sample); this class keeps the
state between them and its counters (`failures`, `reopens`, `recoveries`), and starts a read
with `_refuse_unless_ready` (the adapter's `closed` and `label` named there).
"""

from __future__ import annotations

from softproxy.device import DeviceError

REOPEN_INTERVAL_S = 0.2
"""While failed, the device is closed and opened again every this many seconds of its clock:
often enough that a replugged device is back at once for a person, rarely enough that opening
(milliseconds) does not take every tick."""
CLOSE_ZERO_ATTEMPTS = 3
"""Writes of zero force `close()` tries before it gives up (the second on a reopened device)."""


class FaultRecovery:
    """Failed -> reopened -> back, for an adapter with a `_try_reopen()` and a clock (s)."""

    def _init_recovery(self, clock) -> None:
        """Working, nothing counted yet; `clock()` (s) times the reopens."""
        self._clock = clock
        self._fault: str | None = None  # while failed: the message read (and send) raise
        self._await_fresh = False       # from a failure to the next valid sample: no force is written
        self._next_reopen = 0.0         # clock time of the next reopen attempt (s)
        self.last_reopen_error = ""     # why the last reopen failed ("" once one succeeded)
        self.failures = self.reopens = self.recoveries = 0

    def _refuse_unless_ready(self) -> None:
        """Where a read begins: DeviceError if the device is closed, or failed and not back now
        (`_recover`), with the failure's message."""
        if self.closed:
            raise DeviceError(f"{self.label}: device is closed")
        if self._fault is not None and not self._recover():
            raise DeviceError(self._fault)

    def _enter_failure(self) -> bool:
        """Failed from now on (or still): True when it worked until now, which is counted as a
        new failure and plans the first reopen REOPEN_INTERVAL_S from now."""
        if self._await_fresh:
            return False
        self._await_fresh = True
        self.failures += 1
        self._next_reopen = self._clock() + REOPEN_INTERVAL_S
        return True

    def _with_last_reopen(self, plan: str) -> str:
        """`plan`, followed by why the last reopen failed, if one did."""
        return f"{plan} (last reopen: {self.last_reopen_error})" if self.last_reopen_error else plan

    def _reopen_when_due(self) -> None:
        """While failed: `_try_reopen()` once REOPEN_INTERVAL_S has passed since the last try."""
        now = self._clock()
        if now >= self._next_reopen:
            self._next_reopen = now + REOPEN_INTERVAL_S
            self._try_reopen()

    def _reopened(self) -> None:
        """A reopen succeeded (counted); the device is not back until its next valid sample."""
        self.last_reopen_error = ""
        self.reopens += 1

    def _fresh_sample(self) -> None:
        """A valid sample: it ends a failure (counted in `recoveries`)."""
        if self._await_fresh:
            self._await_fresh = False
            self.recoveries += 1

    def _zero_on_close(self, write_zero, can_reopen: bool = True) -> None:
        """Zero force on close, whatever happened before: up to CLOSE_ZERO_ATTEMPTS calls of
        `write_zero()` until one returns True (False or an exception: it did not go through), the
        second on a reopened device when `can_reopen`. Never raises."""
        for attempt in range(CLOSE_ZERO_ATTEMPTS):
            try:
                if attempt == 1 and can_reopen:
                    self._try_reopen()
                if write_zero():
                    return
            except Exception:
                pass
