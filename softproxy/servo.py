"""`ServoLoop`: the haptic tick, its timing, its statistics and its watchdog.

One tick (../shared/DESIGN.md): read the device; MuJoCo's first half-step (bodies where
they are now); each proxy follows its body (α_c, eqs 41–42); god-object, force, torsion for
every finger; -F and -M·n onto the touched bodies; F and M to the device; MuJoCo's second
half-step. `tick()` can be called from another application's loop (lockstep, no threads);
`run(..., realtime=True)` paces the ticks itself, sleeping then spinning to hold the period.

Every finger's part of the tick is one compiled call (`softproxy.compiled.finger.tick`) on
the loop's table of finger records (`softproxy.finger_rows`); the fingers' attributes are
views of that table, so they read what the tick computed with nothing to copy back.

The watchdog answers every fault with zero force for that tick and a count in `faults`:
a device that raises, a NaN/invalid sample, a tick that overran its period badly (then the
next tick renders zero). `stop()` (and leaving `run`) sends zero force to every finger.
The overrun watchdog guards real time: by default it watches only `run(realtime=True)`, so a
lockstep run in simulated time (an application calling `tick()`, tests, benchmarks,
`softproxy run` without `--realtime`) gives the same result however loaded the machine is.
"""

from __future__ import annotations

import atexit
import gc
import math
import time
import weakref

import numpy as np

from softproxy import termination
from softproxy.device import Device, DeviceSample, check_device
from softproxy.compiled import finger as kernel
from softproxy.compiled.dispatch import entry
from softproxy.device_guard import as_limit
from softproxy.finger import SoftFingerProxy
from softproxy.finger_rows import FingerRows
from softproxy.world import World

MIN_RATE_HZ, MAX_RATE_HZ = 10.0, 100_000.0
"""The servo rates a loop runs at (Hz)."""
FAULTS = ("device_error", "invalid_sample", "overrun", "send_error", "unsafe_output")
"""What `ServoLoop.faults` counts; each fault renders zero force on the fingers it touched.
unsafe_output: a finger computed a wrench that is not finite (parameters at their extremes),
or the device's limits were not numbers it can be clamped to (`softproxy.device_guard`)."""


class TickStats:
    """Preallocated ring buffers of tick duration and period (s); counters of misses."""

    def __init__(self, capacity: int = 1 << 16) -> None:
        self.duration = np.zeros(capacity)
        self.period = np.zeros(capacity)
        self.capacity = capacity
        self.count = 0
        self.misses = 0

    def record(self, duration: float, period: float) -> None:
        i = self.count % self.capacity
        self.duration[i] = duration
        self.period[i] = period
        self.count += 1

    def durations(self) -> np.ndarray:
        """The recorded durations (s), oldest first (at most `capacity`)."""
        n = min(self.count, self.capacity)
        if self.count <= self.capacity:
            return self.duration[:n].copy()
        i = self.count % self.capacity
        return np.concatenate([self.duration[i:], self.duration[:i]])

    def summary_us(self) -> dict:
        """Tick duration p50 / p99 / max in µs."""
        d = self.durations()
        if d.size == 0:
            return {"p50": None, "p99": None, "max": None}
        p50, p99 = np.percentile(d, [50, 99])
        return {"p50": round(float(p50) * 1e6, 2), "p99": round(float(p99) * 1e6, 2), "max": round(float(d.max()) * 1e6, 2)}


_open_loops: "weakref.WeakSet[ServoLoop]" = weakref.WeakSet()
"""Loops started and not yet closed: the exit hook closes them (zero force) at interpreter exit."""


@atexit.register
def _close_open_loops() -> None:
    for loop in list(_open_loops):
        loop.close()


class ServoLoop:
    """Couples fingers to a world through one device at a fixed rate (Hz).

    Use it as `with ServoLoop(...) as loop:` (or call `close()`): leaving sends zero force and
    closes the device. A loop left open is closed by an exit hook when the interpreter exits,
    and while a loop is open SIGTERM and SIGHUP (where still at their defaults) end the
    program through SystemExit, so the hook and every `finally` on the way run
    (`softproxy.termination`; `handle_signals=False` leaves the signals alone).
    """

    def __init__(self, world: World, fingers: list[SoftFingerProxy], device: Device, rate_hz: float = 1000.0,
                 overrun_factor: float = 3.0, stats_capacity: int = 1 << 16, audit: bool = False,
                 overrun_watchdog: bool | None = None, handle_signals: bool = True) -> None:
        if not (math.isfinite(rate_hz) and MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ):
            raise ValueError(f"rate_hz must be between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g}, got {rate_hz!r}")
        check_device(device)
        for f in fingers:
            if f.params.device_finger >= device.fingers:
                raise ValueError(f"finger {f.params.name!r} uses device finger {f.params.device_finger}, "
                                 f"but the device drives {device.fingers}")
            if f.god.shapes is not world.shapes:
                raise ValueError(f"finger {f.params.name!r} touches shapes of its own, not the world's: "
                                 "build it over world.shapes")
        self.world = world
        self.fingers = fingers
        self.device = device
        self.rate_hz = float(rate_hz)
        self.period = 1.0 / self.rate_hz
        world.timestep = self.period
        self.samples = [DeviceSample() for _ in range(device.fingers)]
        self.stats = TickStats(stats_capacity)
        self.faults = dict.fromkeys(FAULTS, 0)
        self.overrun_limit = overrun_factor * self.period
        self.overrun_watchdog = overrun_watchdog
        """True: a tick that overran `overrun_factor` periods makes the next render zero. None
        (default): only inside `run(realtime=True)`, so an application ticking in lockstep gets
        the same results however loaded the machine is. False: never."""
        self._watching = overrun_watchdog is True
        self.paced = False  # True while run(realtime=True) paces the ticks
        self.audit = audit
        self.t = 0.0
        self.ticks = 0
        self._safe_next = False  # the watchdog asks for one tick of zero force
        self._started = False
        self.closed = False
        self.handle_signals = handle_signals
        self._signals = None  # this loop's claim on softproxy.termination's handlers: its release
        self.last_device_error = ""  # what the device said when it last failed to read
        self.last_send_error = ""  # ... and to send
        self.sensors = []  # fingertip sensor channels (softproxy.fingertip_sensors): tick(loop) each tick
        self.rows = FingerRows.gather(fingers) if fingers else FingerRows(world.shapes, 0)
        """The fingers' records, one table: the fingers are views of its rows."""
        # the records as flat buffers: a sample is written in, and what is sent read out, with
        # plain item stores and loads (a numpy field access costs more than the copies it saves)
        raw = self.rows.F.view(np.ndarray).view(np.uint8)
        self._floats = memoryview(raw).cast("d")
        self._bytes = memoryview(raw)
        size = self.rows.F.dtype.itemsize
        at = {name: self.rows.F.dtype.fields[name][1] for name in ("in_x", "in_valid", "sent_fx")}
        self._io = [((i * size + at["in_x"]) // 8, i * size + at["in_valid"], (i * size + at["sent_fx"]) // 8,
                     f.params.device_finger) for i, f in enumerate(fingers)]
        self._compile()

    def _compile(self) -> None:
        """Compile (or load from numba's cache) the tick now, not inside the first tick, and
        keep its entry point (`softproxy.compiled.dispatch`): one call on copies of everything
        the tick writes."""
        world, rows = self.world, self.rows
        s = world.shapes
        args = (s.S.copy(), s.T, None if s.C is None else s.C.copy(), s.xpos, s.xmat, s.cvel, rows.F.copy(),
                rows.near.copy(), self.period, False, False, 1.0, 1.0, rows.scratch.copy(), world.wrench.copy(),
                world.bodies.copy(), world.counts.copy())
        self._tick_kernel = entry(kernel.tick, args, "the servo tick")
        self._tick_kernel(*args)

    def start(self) -> None:
        """Place every proxy at its finger's first device position (pushed out of any shape)."""
        if self.closed:
            raise RuntimeError("this ServoLoop is closed (its device too): build a new one")
        self._started = True
        _open_loops.add(self)
        if self.handle_signals and self._signals is None and termination.install():
            self._signals = weakref.finalize(self, termination.uninstall)  # also if dropped unclosed
        try:
            self.device.read(self.t, self.samples)
        except Exception:
            self.faults["device_error"] += 1
            for f in self.fingers:
                f.placed = False
            return
        for f in self.fingers:
            s = self.samples[f.params.device_finger]
            if not s.usable():
                f.placed = False  # placed at its first good sample instead
            else:
                f.place(s.x, s.y, s.z)

    def tick(self) -> None:
        """One servo tick at loop time `self.t`; advances time by one period."""
        if not self._started or self.closed:
            self.start()
        start = time.perf_counter()
        dt = self.period
        world = self.world
        device = self.device
        samples = self.samples
        ok = True
        try:
            device.read(self.t, samples)
        except Exception as exc:  # a device that fails must not take the loop (and a motor) with it
            self.faults["device_error"] += 1
            self.last_device_error = str(exc) or type(exc).__name__
            ok = False
        safe = self._safe_next
        self._safe_next = False
        world.begin_step()
        self._fingers(ok, safe, dt)
        self._sends()
        for ch in self.sensors:
            ch.tick(self)
        world.end_step()
        self.t += dt
        self.ticks += 1
        duration = time.perf_counter() - start
        if duration > self.overrun_limit and self._watching:
            self.faults["overrun"] += 1
            self._safe_next = True
        self.stats.record(duration, dt)

    def _fingers(self, ok: bool, safe: bool, dt: float) -> None:
        """Every finger's part of the tick: this tick's samples into the finger records, then
        one compiled call (update or hold, wrench, the device guard)."""
        floats, flags, samples = self._floats, self._bytes, self.samples
        unusable = 0
        for k, valid, _, j in self._io:
            s = samples[j]
            if ok and s.usable():  # every field is now a finite float
                floats[k] = s.x
                floats[k + 1] = s.y
                floats[k + 2] = s.z
                floats[k + 3] = s.twist
                floats[k + 4] = s.qw
                floats[k + 5] = s.qx
                floats[k + 6] = s.qy
                floats[k + 7] = s.qz
                flags[valid] = 1
            else:
                flags[valid] = 0
                unusable += ok
        world, rows, device = self.world, self.rows, self.device
        shapes = world.shapes
        refused, unsafe = self._tick_kernel(shapes.S, shapes.T, shapes.C, shapes.xpos, shapes.xmat, shapes.cvel, rows.F,
                                      rows.near, dt, safe, bool(self.audit), as_limit(device.max_force),
                                      as_limit(device.max_torque), rows.scratch, world.wrench, world.bodies,
                                      world.counts)
        if unusable or refused:
            self.faults["invalid_sample"] += unusable + refused
        if unsafe:
            self.faults["unsafe_output"] += unsafe

    def _sends(self) -> None:
        """Each device finger is sent what the tick computed for it (guarded, clamped)."""
        floats, device = self._floats, self.device
        for _, _, k, j in self._io:
            try:
                device.send(j, floats[k], floats[k + 1], floats[k + 2], floats[k + 3], floats[k + 4], floats[k + 5])
            except Exception as exc:
                self._send_failed(exc)

    def _send_failed(self, exc: Exception) -> None:
        self.faults["send_error"] += 1
        self.last_send_error = str(exc) or type(exc).__name__

    def run(self, ticks: int, realtime: bool = False, on_tick=None, spin_s: float = 1.5e-3) -> None:
        """Run `ticks` ticks: lockstep (as fast as possible, deterministic) or paced in real time.

        Paced: the loop sleeps only when more than `spin_s` remains before the next tick and
        spins for the rest (a sleep can overshoot by a millisecond on a busy machine), and
        Python's cyclic garbage collector is paused for the run (a collection is a pause of
        its own). At 1 kHz that means one core spinning, as a haptic servo thread does.
        `on_tick(loop)` is called after every tick, outside the timed region. Zero force is
        sent to every finger when the run ends, however it ends.
        """
        gc_was_enabled = gc.isenabled()
        try:
            if not realtime:
                for _ in range(ticks):
                    self.tick()
                    if on_tick is not None:
                        on_tick(self)
                return
            period = self.period
            self.paced = True
            self._watching = self.overrun_watchdog is not False
            gc.disable()
            next_start = time.perf_counter()
            for _ in range(ticks):
                now = time.perf_counter()
                if next_start - now > spin_s:
                    time.sleep(next_start - now - spin_s)
                while time.perf_counter() < next_start:
                    pass
                self.tick()
                if time.perf_counter() > next_start + period:
                    self.stats.misses += 1
                next_start += period
                if on_tick is not None:
                    on_tick(self)
        finally:
            self.paced = False
            self._watching = self.overrun_watchdog is True
            if gc_was_enabled:
                gc.enable()
            self.stop()

    def stop(self) -> None:
        """The safe state: zero force to every finger first, then no finger wrench left on the
        bodies. Termination signals wait until the zero force is sent (`termination.deferred`)."""
        with termination.deferred():
            device = self.device
            for f in self.fingers:
                try:
                    device.send(f.params.device_finger, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
                except Exception as exc:
                    self._send_failed(exc)
            self.world.clear_wrenches()
            for f in self.fingers:
                f.clear_output()

    def close(self) -> None:
        """`stop()`, then close the device; the loop cannot tick again. Safe to call twice."""
        if self.closed:
            return
        with termination.deferred():
            self.closed = True
            _open_loops.discard(self)
            try:
                self.stop()
            finally:
                try:
                    self.device.close()
                except Exception as exc:  # the zero force went out first; say what closing said
                    self.last_device_error = f"closing the device: {exc or type(exc).__name__}"
                if self._signals is not None:
                    self._signals()

    def __enter__(self) -> "ServoLoop":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
