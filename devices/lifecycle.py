"""What every device adapter does around its life: closed by `with`, closed at interpreter exit,
its counters as a dict, and the checks and counts every send starts with.

`DeviceLifecycle` is a mixin for an adapter with `close()` (which never raises), `label`,
`fingers`, `closed`, and counter attributes named in its `STATS` (`sends` and `nan_sends`
among them). `OpenDevices` holds the adapters opened and not closed yet
(weakly: it keeps none open) and closes them at interpreter exit, when nothing else would
write zero force to a device left open.
"""

from __future__ import annotations

import atexit
import math
import threading
import time
import weakref

from softproxy.device import DeviceError


class DeviceLifecycle:
    """`with Device(...) as d:` closes it on the way out; `stats()` gives the counters in `STATS`."""

    STATS: tuple[str, ...] = ()
    """Names of the adapter's counter attributes, in the order `stats()` lists them."""

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def stats(self) -> dict:
        """Counters of what the device did."""
        return {name: getattr(self, name) for name in self.STATS}

    def _count_send(self, finger, components) -> bool:
        """The start of every send: DeviceError for a finger the device does not drive or once
        it is closed; counted in `sends`; False (counted in `nan_sends`) when a component is no
        finite number, which the engine promises never to send: the motors get zero then."""
        if isinstance(finger, bool) or not isinstance(finger, int) or not 0 <= finger < self.fingers:
            raise DeviceError(f"{self.label} drives {self.fingers} finger(s) from 0, not finger {finger!r}")
        if self.closed:
            raise DeviceError(f"{self.label}: device is closed")
        self.sends += 1
        try:
            finite = all(math.isfinite(v) for v in components)
        except TypeError:
            finite = False
        if not finite:
            self.nan_sends += 1
        return finite


class OpenDevices(weakref.WeakSet):
    """The devices of one adapter opened and not closed yet (held weakly); `close_all()` runs at
    interpreter exit."""

    def __init__(self) -> None:
        super().__init__()
        atexit.register(self.close_all)

    def close_all(self) -> None:
        """Close every device still open (each `close()` writes zero force first, never raises)."""
        for device in list(self):
            device.close()


def start_stall_watchdog(device, name: str) -> None:
    """Start a device's stall watchdog: a daemon thread that calls `device._watch_once()` every
    `device.stall_s` / 4 s (it zeroes a command not renewed for stall_s), until the device is
    closed or gone. It holds the device weakly, so it keeps no device open."""
    threading.Thread(target=_watch_stalls, args=(weakref.ref(device), device.stall_s / 4.0), name=name,
                     daemon=True).start()


def _watch_stalls(ref, period: float) -> None:
    while True:
        time.sleep(period)
        device = ref()
        if device is None or device.closed:
            return
        try:
            device._watch_once()
        except Exception:
            pass
        del device
