"""The last guard at the device boundary: what reaches a motor is finite and within its clamps.

Every wrench the servo loop sends to a device passes through `guard_wrench` last, whatever
the parameters, the fingertip model or the device's own limits say: a force or torque that
is not finite, a limit that is not a finite number in [0, MAX_LIMIT], becomes zero force and
a counted fault (`unsafe_output`) instead of reaching `send()`. `softproxy.device_guard`
refuses such limits when a loop is built, so the fault is the exception. Also here: the
largest normal force the torsion law takes (P_MAX).
"""

from __future__ import annotations

import math

from softproxy.compiled.kernel import kernel


MAX_LIMIT = 1e6
"""Largest force (N) or torque (N·m) limit a device may declare; more is a broken number."""
MAX_SQUARE = 1e300
"""A |F|² or |M|² above this (or NaN) means the wrench was computed from broken numbers."""


@kernel
def guard_wrench(fx, fy, fz, tx, ty, tz, finger_fmax, finger_tmax, device_fmax, device_tmax):
    """(ok, fx, fy, fz, tx, ty, tz): the wrench scaled, direction kept, into |F| ≤ the smaller
    force limit (N) and |M| ≤ the smaller torque limit (N·m) of the finger and the device;
    ok False and all zero when any input is not finite or any of the four limits is outside
    [0, MAX_LIMIT]. NaN fails every comparison, so each test below passes only on good numbers."""
    f2 = fx * fx + fy * fy + fz * fz
    t2 = tx * tx + ty * ty + tz * tz
    # every limit on its own: a device limit of inf or 1e9 is a broken number, not "no clamp"
    if not (f2 <= MAX_SQUARE and t2 <= MAX_SQUARE and 0.0 <= finger_fmax <= MAX_LIMIT
            and 0.0 <= finger_tmax <= MAX_LIMIT and 0.0 <= device_fmax <= MAX_LIMIT and 0.0 <= device_tmax <= MAX_LIMIT):
        return False, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0
    fmax = finger_fmax if finger_fmax < device_fmax else device_fmax
    tmax = finger_tmax if finger_tmax < device_tmax else device_tmax
    if f2 > fmax * fmax:
        s = fmax / math.sqrt(f2)
        fx, fy, fz = fx * s, fy * s, fz * s
    if t2 > tmax * tmax:
        s = tmax / math.sqrt(t2)
        tx, ty, tz = tx * s, ty * s, tz * s
    return True, fx, fy, fz, tx, ty, tz


P_MAX = 1e6
"""Largest normal force the per-tick functions take (N); larger values are clamped so that
|P|^γ cannot overflow. A million newtons is far beyond any device or fingertip."""
