"""`ServoLoop`: the haptic tick, its timing, its statistics and its watchdog.

One tick (../shared/DESIGN.md): read the device; MuJoCo's first half-step (bodies where
they are now); each proxy follows its body (α_c, eqs 41–42); god-object, force, torsion for
every finger; -F and -M·n onto the touched bodies; F and M to the device; MuJoCo's second
half-step. `tick()` can be called from another application's loop (lockstep, no threads);
`run(..., realtime=True)` paces the ticks itself, sleeping then spinning to hold the period.

`compiled=True` runs every finger's part of the tick as one compiled call
(`softproxy.compiled`, the same answers to the last bit); the fingers' outputs are written
back after each tick, the rest by `sync()`, which the loop calls before sensors, `on_tick`
and `stop()`.

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
from softproxy.device_guard import guard_wrench
from softproxy.finger import SoftFingerProxy
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
                 overrun_watchdog: bool | None = None, compiled: bool = False, handle_signals: bool = True) -> None:
        if not (math.isfinite(rate_hz) and MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ):
            raise ValueError(f"rate_hz must be between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g}, got {rate_hz!r}")
        check_device(device)
        for f in fingers:
            if f.params.device_finger >= device.fingers:
                raise ValueError(f"finger {f.params.name!r} uses device finger {f.params.device_finger}, "
                                 f"but the device drives {device.fingers}")
        self.world = world
        self.fingers = fingers
        self.device = device
        self.rate_hz = float(rate_hz)
        self.period = 1.0 / self.rate_hz
        world.timestep = self.period
        self.samples = [DeviceSample() for _ in range(device.fingers)]
        self._pairs = [(f, self.samples[f.params.device_finger]) for f in fingers]  # each finger's sample
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
        self.compiled = None
        """The `CompiledFingers` running the fingers when `compiled=True` (else None): the same
        tick as compiled code, answers equal to the last bit, primitive shapes only."""
        if compiled:
            from softproxy.compiled.engine import CompiledFingers  # numba is imported only when asked for

            self.compiled = CompiledFingers(world, fingers, device)

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
        if self.compiled is not None:
            self.compiled.pack()

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
        if self.compiled is not None:
            world.begin_step(refresh_shapes=False)  # the compiled fingers read MuJoCo's poses
            self._compiled_fingers(ok, safe, dt)
            if self.sensors:
                self.compiled.sync()
        else:
            world.begin_step()
            self._fingers(ok, safe, dt)
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
        """Every finger's part of the tick, in Python: update (or hold), wrench, device send."""
        world = self.world
        for f, s in self._pairs:
            if not ok or not s.usable():
                if ok:
                    self.faults["invalid_sample"] += 1
                f.hold()
            else:
                if not f.update(s.x, s.y, s.z, s.twist, dt):
                    self.faults["invalid_sample"] += 1
                if safe:  # the watchdog's zero-force tick: the proxy moved, nothing is rendered
                    f.clear_output()
                elif not math.isfinite(f.fx + f.fy + f.fz + f.tx + f.ty + f.tz):
                    self.faults["unsafe_output"] += 1  # parameters at their extremes: neither body nor hand gets it
                    f.clear_output()
                if f.body >= 0:
                    world.push(f.body, -f.fx, -f.fy, -f.fz, f.px, f.py, f.pz, -f.tx, -f.ty, -f.tz)
            if self.audit:
                f.audit()
            self._send(f, safe)

    def _compiled_fingers(self, ok: bool, safe: bool, dt: float) -> None:
        """`_fingers` in one compiled call; then each device finger is sent what it computed."""
        compiled = self.compiled
        invalid, unsafe = compiled.run(self.samples, ok, safe, self.audit, dt)
        self.faults["invalid_sample"] += invalid
        if unsafe:
            self.faults["unsafe_output"] += unsafe
        device = self.device
        for f, sent in zip(self.fingers, compiled.sent):
            try:
                device.send(f.params.device_finger, *sent)
            except Exception as exc:
                self._send_failed(exc)

    def _send(self, f: SoftFingerProxy, safe: bool) -> None:
        """Send the finger's force and torque, clamped to the finger's and the device's limits
        (`guard_wrench`: zero, and a fault, for anything not finite); zero if safe or invalid."""
        device = self.device
        if safe or not f.valid:
            fx = fy = fz = tx = ty = tz = 0.0
        else:
            try:
                good, fx, fy, fz, tx, ty, tz = guard_wrench(f.fx, f.fy, f.fz, f.tx, f.ty, f.tz, f.max_force,
                                                            f.max_torque, device.max_force, device.max_torque)
            except TypeError:  # a device limit that is no number at all
                good = False
                fx = fy = fz = tx = ty = tz = 0.0
            if not good:
                self.faults["unsafe_output"] += 1
        try:
            device.send(f.params.device_finger, fx, fy, fz, tx, ty, tz)
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
                        self.sync()
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
                    self.sync()
                    on_tick(self)
        finally:
            self.paced = False
            self._watching = self.overrun_watchdog is True
            if gc_was_enabled:
                gc.enable()
            self.stop()

    def sync(self) -> None:
        """Compiled loops: bring every attribute of the fingers up to date (a tick writes back
        only its outputs: force, torque, contact point, body, P, valid). No-op in Python."""
        if self.compiled is not None:
            self.compiled.sync()

    def stop(self) -> None:
        """The safe state: zero force to every finger first, then no finger wrench left on the
        bodies. Termination signals wait until the zero force is sent (`termination.deferred`)."""
        with termination.deferred():
            for f in self.fingers:
                self._send(f, True)
            if self.compiled is not None:  # the Python objects take the whole state back first
                self.compiled.sync()
                self.compiled.clear_wrenches()
            self.world.clear_wrenches()
            for f in self.fingers:
                f.clear_output()
            if self.compiled is not None:
                self.compiled.pack()

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
