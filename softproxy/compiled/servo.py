"""The servo tick as compiled code: a block of ticks, device and MuJoCo included, in one call.

`run_ticks` runs n ticks without returning to the interpreter and without the GIL: pacing
(sleep, then spin to the deadline), the device's read (its cfunc, `softproxy.device_kernel`),
the samples into the finger records, MuJoCo's first half-step, every finger
(`finger.tick`), the sends (the device's cfunc), the wrenches into xfrc_applied, MuJoCo's
second half-step, and the tick's statistics and watchdog. A device written in Python cannot
be called from here; `ServoLoop` then runs the same pieces one tick at a time, `begin_tick`
and `end_tick` around its own read and sends, so both paths share every line of the tick
but the device I/O.

The loop's scalar state is one `LOOP` record (`loop`, an array of one): loop time, period, the watchdog, the fault
counters, the device's last error codes, a `stop` flag another thread may set to end a
block early (the kernel reads it every tick), a `halt` flag that makes every later send zero
(the loop is closing: only zero may reach the device), and, while `profile` is set, the time of each
stage of the last tick (`STAGES`; the device's stages only in a compiled block). Tick statistics go into the ring buffers of
`softproxy.servo.TickStats` (durations in s) and its counters [count, misses].
"""

from __future__ import annotations

import numpy as np

from softproxy.compiled import carry, finger, handoff
from softproxy.compiled.kernel import kernel
from softproxy.compiled.native import mj_step1, mj_step2, monotonic_ns, sleep_until_ns

STAGES = ("device read", "mj_step1", "fingers", "device sends", "wrenches + mj_step2")
"""The stages of a tick, in order, as `stage_ns` times them (`LOOP.profile`)."""
READ_STAGE, STEP1_STAGE, FINGERS_STAGE, SENDS_STAGE, STEP2_STAGE = range(len(STAGES))

LOOP = np.dtype([
    ("t", np.float64),  # loop time (s) of the next tick
    ("period", np.float64),  # s
    ("period_ns", np.int64),
    ("ticks", np.int64),
    ("every", np.int64),  # haptic ticks per MuJoCo step (1: one rate; more: `softproxy.compiled.carry`)
    ("phase", np.int64),  # haptic ticks into the current MuJoCo step
    ("threaded", np.bool_),  # two rates, MuJoCo in its own thread (`softproxy.compiled.handoff`)
    ("next_ns", np.int64),  # CLOCK_MONOTONIC deadline of the next paced tick
    ("spin_ns", np.int64),  # a paced tick sleeps until this long before its deadline, then spins
    ("overrun_ns", np.int64),  # a tick longer than this trips the watchdog (when watching)
    ("fmax", np.float64), ("tmax", np.float64),  # the device's force (N) and torque (N·m) limits
    ("stall_code", np.int64), ("stall_ns", np.int64),  # the device's "no answer" code and its wait
    ("read_code", np.int64), ("send_code", np.int64),  # the device's last error codes (0: none yet)
    ("device_error", np.int64), ("invalid_sample", np.int64), ("overrun", np.int64),
    ("send_error", np.int64), ("unsafe_output", np.int64),  # softproxy.servo.FAULTS, in order
    ("safe_next", np.bool_),  # the watchdog asks for one tick of zero force
    ("watching", np.bool_),  # the overrun watchdog is on
    ("audit", np.bool_),  # measure every proxy's depth inside the shapes (slow)
    ("stop", np.bool_),  # set from outside: end the block after the current tick
    ("halt", np.bool_),  # set by close(): every send from now on is zero, whoever makes it
    ("passivity", np.bool_),  # the passivity controller dissipates what the coupling would create
    ("profile", np.bool_),  # time the stages of each tick into stage_ns
    ("mark", np.int64),  # when the last stage ended (ns), while profiling
    ("stage_ns", np.int64, (len(STAGES),)),  # the last tick's stages (ns), while profiling
], align=True)
"""A servo loop's scalar state, one record."""

COUNT, MISSES = 0, 1
"""Slots of TickStats' counters."""


@kernel
def _stage(L, k):
    """While profiling: stage k ended now; its time since the last mark into stage_ns[k]."""
    if L.profile:
        now = monotonic_ns()
        L.stage_ns[k] = now - L.mark
        L.mark = now


@kernel(entry=True)
def pace(loop):
    """Wait for the next paced tick's deadline: sleep until `spin_ns` before it, then spin
    (a sleep can overshoot by a millisecond on a busy machine; the spin cannot)."""
    L = loop[0]
    deadline = L.next_ns
    if deadline - monotonic_ns() > L.spin_ns:
        sleep_until_ns(deadline - L.spin_ns)
    while monotonic_ns() < deadline:
        pass


@kernel(entry=True)
def paced_done(loop, counters):
    """After a paced tick: a miss when it ended after the next deadline; next deadline."""
    L = loop[0]
    if monotonic_ns() > L.next_ns + L.period_ns:
        counters[MISSES] += 1
    L.next_ns += L.period_ns


@kernel(entry=True)
def begin_tick(loop, samples, ok, mj, sh, fingers, cr):
    """The tick up to the sends: this tick's samples (SAMPLE rows; `ok` False when the read
    failed) into the finger records, mj_step1 (on the first tick of a MuJoCo step; with two
    rates the local model then takes MuJoCo's state, and every tick carries the shapes near
    the fingers forward: `softproxy.compiled.carry`), then every finger (`finger.tick`). A
    sample the device marked not valid is an invalid_sample fault. `mj`, `sh`, `fingers`:
    the bundles of `softproxy.compiled.layout` (MjViews, Shapes, FingerTables); with two
    rates `sh` reads the local model's poses and `cr` is that model (`Carried`; None with
    one rate: numba then compiles this tick without any of it)."""
    L = loop[0]
    safe = L.safe_next
    L.safe_next = False
    FD, device_of = fingers.rows.data, fingers.device_of
    for i in range(FD.shape[0]):
        fd = FD[i]
        if not ok:
            fd.in_valid = False
            continue
        s = samples[device_of[i]]
        if not s.valid:
            fd.in_valid = False
            L.invalid_sample += 1
            continue
        fd.in_pos[:] = s.x, s.y, s.z
        fd.in_quat[:] = s.qw, s.qx, s.qy, s.qz
        fd.in_twist = s.twist
        fd.in_valid = True
    if cr is None:
        mj_step1(mj.m, mj.d)
    else:
        H = L.every * L.period
        if L.threaded:  # MuJoCo's newest state, if one came; the shapes carried to now
            interval = handoff.take(cr.handoff)
            if interval >= 0.0:
                carry.snapshot(cr, interval if interval > 0.0 else H, H, L.ticks == 0)
            tau = (monotonic_ns() - cr.handoff.ctl[handoff.SEEN_STAMP]) * 1e-9
            carry.carry(cr, fingers, min(max(tau, 0.0), carry.FADE_STEPS * H), H)
        else:
            if L.phase == 0:
                mj_step1(mj.m, mj.d)
                carry.snapshot(cr, H, H, L.ticks == 0)
            carry.carry(cr, fingers, L.phase * L.period, H)
    _stage(L, STEP1_STAGE)
    refused, unsafe, coupled = finger.tick(mj, sh, fingers, L.period, safe, L.audit, L.fmax, L.tmax, L.passivity, cr)
    if cr is not None:  # the bodies answer the sent wrenches in the local model
        carry.respond(cr, fingers.rows.data, fingers.ws, coupled, L.period, L.every * L.period)
    L.invalid_sample += refused
    L.unsafe_output += unsafe
    _stage(L, FINGERS_STAGE)


@kernel(entry=True)
def end_tick(loop, mj, fingers, stats, start_ns, cr):
    """The tick after the sends: on the last tick of a MuJoCo step the wrenches into
    xfrc_applied (averaged over the step's haptic ticks) and mj_step2; loop time, and the
    tick's duration since `start_ns` into the statistics; an overrun (while watching) makes
    the next tick render zero."""
    L = loop[0]
    if cr is None:
        finger.write_wrenches(mj.xfrc, mj.xipos, fingers.wrench, fingers.bodies, fingers.counts, 1.0)
        mj_step2(mj.m, mj.d)
    elif L.threaded:  # MuJoCo's thread averages them over its step
        handoff.add_wrenches(cr.handoff, fingers.wrench, fingers.bodies[finger.TOUCHED], fingers.counts)
    else:
        L.phase += 1
        if L.phase >= L.every:  # MuJoCo's step: the wrenches averaged over its haptic ticks
            finger.write_wrenches(mj.xfrc, mj.xipos, fingers.wrench, fingers.bodies, fingers.counts, 1.0 / L.phase)
            mj_step2(mj.m, mj.d)
            L.phase = 0
    _stage(L, STEP2_STAGE)
    L.t += L.period
    L.ticks += 1
    elapsed = monotonic_ns() - start_ns
    if L.watching and elapsed > L.overrun_ns:
        L.overrun += 1
        L.safe_next = True
    counters = stats.counters
    k = counters[COUNT] % stats.durations.shape[0]
    stats.durations[k] = elapsed * 1e-9
    stats.periods[k] = L.period
    counters[COUNT] += 1


@kernel(nogil=True, entry=True)
def run_ticks(loop, read, send, device, mj, sh, fingers, stats, n, paced, cr):
    """Up to n ticks (fewer if `L.stop` is set), paced in real time or not; returns how many
    ran. `read`/`send`: the device's cfuncs over its `device` (DeviceIO: its state, SAMPLE
    rows and limits, read every tick); `cr`: the local model of two rates, or None. A read
    that fails renders no finger (each holds) and
    counts a device_error; one that stalled waits the device's stall time first."""
    L = loop[0]
    samples, limits, io = device.samples, device.limits, device.io
    FD, device_of = fingers.rows.data, fingers.device_of
    rows = samples.shape[0]
    done = 0
    while done < n and not L.stop and not L.halt:
        if paced:
            pace(loop)
        start = monotonic_ns()
        L.mark = start
        code = read(io, L.t, device.samples_at, rows)
        L.fmax = limits[0]  # a device that derates mid-run is obeyed from this tick on
        L.tmax = limits[1]
        _stage(L, READ_STAGE)
        if code != 0:
            L.device_error += 1
            L.read_code = code
            if code == L.stall_code:
                sleep_until_ns(start + L.stall_ns)
        begin_tick(loop, samples, code == 0, mj, sh, fingers, cr)
        for i in range(FD.shape[0]):
            fd = FD[i]
            if L.halt:  # closing from another thread: this block may send nothing but zero
                code = send(io, device_of[i], 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            else:
                (fx, fy, fz), (tx, ty, tz) = fd.sent_force, fd.sent_torque
                code = send(io, device_of[i], fx, fy, fz, tx, ty, tz)
            if code != 0:
                L.send_error += 1
                L.send_code = code
        _stage(L, SENDS_STAGE)
        end_tick(loop, mj, fingers, stats, start, cr)
        if paced:
            paced_done(loop, stats.counters)
        done += 1
    return done
