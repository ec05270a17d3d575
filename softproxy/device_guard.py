"""A device's limits checked where a loop is built: finite numbers in [0, MAX_LIMIT].

The compiled tick's last guard (`softproxy.compiled.guard.guard_wrench`) turns a wrench or a
limit that is not a good number into zero force and a counted fault; `check_limits` refuses
such limits up front, so the fault is the exception, and `as_limit` hands a limit changed
mid-run to the guard as a float.
"""

from __future__ import annotations

import math
from numbers import Real

from softproxy.compiled.guard import MAX_LIMIT


def check_limits(device) -> None:
    """ValueError naming the device unless its `max_force` (N) and `max_torque` (N·m) are
    finite numbers in [0, MAX_LIMIT] (a NaN limit would switch a clamp off)."""
    for name in ("max_force", "max_torque"):
        value = getattr(device, name, None)
        if isinstance(value, bool) or not isinstance(value, Real) or not (
                math.isfinite(value) and 0.0 <= value <= MAX_LIMIT):
            raise ValueError(f"device {type(device).__name__}: {name} must be a number in [0, {MAX_LIMIT:g}], "
                             f"got {value!r}")


def as_limit(value) -> float:
    """A device limit as the float the compiled guard takes: NaN (which `guard_wrench` refuses)
    when it is not a number at all (a device may change its limits after it was checked)."""
    if type(value) is float:
        return value
    if isinstance(value, bool) or not isinstance(value, Real):
        return math.nan
    try:
        return float(value)
    except OverflowError:
        return math.nan
