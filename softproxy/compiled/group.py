"""Several compiled devices in one block of servo ticks: `run_group_ticks`.

`softproxy.device_group.DeviceGroup` drives several devices as one; when every member offers
its read and send as cfuncs (`softproxy.device_kernel`: the simulated and replay devices) the
servo loop runs the group here, a block of ticks without Python or the GIL, as
`servo.run_ticks` does for one device, and with the group's own rules: each member reads
its own rows of the loop's SAMPLE array; a member whose read fails has its rows marked not
valid (its fingers hold, zero force) while the others render, and the tick is a device_error
only when every member failed; the guard clamps to the largest member's limits, then each
send to its own member's (as `DeviceGroup.send`); only zero once the loop is closing. The
numbers are the Python group path's, bit for bit (`tests/test_multidevice.py`).
"""

from __future__ import annotations

import math

import numpy as np

from softproxy.compiled.guard import MAX_LIMIT
from softproxy.compiled.kernel import kernel
from softproxy.compiled.native import monotonic_ns, sleep_until_ns
from softproxy.compiled.servo import READ_STAGE, SENDS_STAGE, _stage, begin_tick, end_tick, pace, paced_done

SAMPLE_BYTES = 88
"""Bytes of one SAMPLE row (`softproxy.device_kernel.SAMPLE`): a member's rows start at its first row × this."""


@kernel
def clamp_length(lim, x, y, z):
    """(x, y, z) scaled, direction kept, to length ≤ lim; zero when lim is no number in
    [0, MAX_LIMIT] (a member whose limits turned to garbage renders nothing)."""
    if not 0.0 <= lim <= MAX_LIMIT:
        return 0.0, 0.0, 0.0
    n2 = x * x + y * y + z * z
    if n2 > lim * lim:
        s = lim / math.sqrt(n2)
        return x * s, y * s, z * s
    return x, y, z


@kernel(nogil=True, entry=True)
def run_group_ticks(loop, reads, sends, members, limits, samples, samples_at, mj, sh, fingers, stats, n, paced, cr):
    """Up to n ticks (fewer if `L.stop` is set) of a group of compiled devices; returns how
    many ran. `reads`, `sends`: the members' cfuncs (tuples); `members`: an int64 table, one
    row per member: [state address, first row, rows, stall code, stall ns, failed reads,
    last read code, last send code]; `limits`: the members' [max_force, max_torque] arrays
    (tuple), read every tick; `samples`: the group's SAMPLE rows, at `samples_at`."""
    L = loop[0]
    FD, device_of = fingers.rows.data, fingers.device_of
    m = members.shape[0]
    owner = np.empty(samples.shape[0], dtype=np.int64)  # the member of each row
    for k in range(m):
        for r in range(members[k, 1], members[k, 1] + members[k, 2]):
            owner[r] = k
    done = 0
    while done < n and not L.stop and not L.halt:
        if paced:
            pace(loop)
        start = monotonic_ns()
        L.mark = start
        failed = 0
        stall = 0
        fmax = 0.0
        tmax = 0.0
        for k in range(m):
            first, rows = members[k, 1], members[k, 2]
            code = reads[k](np.uintp(members[k, 0]), L.t, samples_at + np.uintp(first * SAMPLE_BYTES), rows)
            lim = limits[k]
            if 0.0 <= lim[0] <= MAX_LIMIT and lim[0] > fmax:  # the largest member's limits (DeviceGroup.max_force)
                fmax = lim[0]
            if 0.0 <= lim[1] <= MAX_LIMIT and lim[1] > tmax:
                tmax = lim[1]
            if code != 0:  # this member's fingers hold; the others render
                failed += 1
                members[k, 5] += 1
                members[k, 6] = code
                for r in range(first, first + rows):
                    samples[r].valid = False
                if code == members[k, 3] and members[k, 4] > stall:
                    stall = members[k, 4]
        L.fmax = fmax
        L.tmax = tmax
        _stage(L, READ_STAGE)
        if stall:  # a member that did not answer: its wait, as one device's
            sleep_until_ns(start + stall)
        if failed == m:
            L.device_error += 1
        begin_tick(loop, samples, failed < m, mj, sh, fingers, cr)
        for i in range(FD.shape[0]):
            fd = FD[i]
            row = device_of[i]
            k = owner[row]
            j = row - members[k, 1]
            if L.halt:  # closing from another thread: only zero from here on
                code = sends[k](np.uintp(members[k, 0]), j, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            else:
                lim = limits[k]
                fx, fy, fz = clamp_length(lim[0], fd.sent_force[0], fd.sent_force[1], fd.sent_force[2])
                tx, ty, tz = clamp_length(lim[1], fd.sent_torque[0], fd.sent_torque[1], fd.sent_torque[2])
                code = sends[k](np.uintp(members[k, 0]), j, fx, fy, fz, tx, ty, tz)
            if code != 0:
                L.send_error += 1
                members[k, 7] = code
        _stage(L, SENDS_STAGE)
        end_tick(loop, mj, fingers, stats, start, cr)
        if paced:
            paced_done(loop, stats.counters)
        done += 1
    return done
