"""What every device adapter does around its life: closed by `with`, closed at interpreter exit,
and its counters as a dict.

`DeviceLifecycle` is a mixin for an adapter with `close()` (which never raises) and counter
attributes named in its `STATS`. `OpenDevices` holds the adapters opened and not closed yet
(weakly: it keeps none open) and closes them at interpreter exit, when nothing else would
write zero force to a device left open.
"""

from __future__ import annotations

import atexit
import weakref


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
