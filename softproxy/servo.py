"""`ServoLoop`: the haptic tick, its timing, its statistics and its watchdog.

One tick (docs/architecture.md): read the device; MuJoCo's first half-step (bodies where
they are now); each proxy follows its body (α_c, eqs 41–42); god-object, force, torsion for
every finger; F and M to the device; -F and -M·n onto the touched bodies; MuJoCo's second
half-step. `tick()` can be called from another application's loop (lockstep, no threads);
`run(..., realtime=True)` paces the ticks itself, sleeping then spinning to hold the period.

The tick is compiled (`softproxy.compiled.servo`). With a device that offers its read and
send as compiled code (`compiled_io()`: the simulated and replay devices) a whole block of
ticks runs in one call, MuJoCo's half-steps included, without the GIL: `run` returns to
Python only between blocks (to call `on_tick`, at most every 100 ms otherwise), so another
thread can draw or log meanwhile (`run_in_thread`). A device written in Python (HID, a
recording wrapper, an application's own) is called from Python each tick, around the same
compiled pieces; so are fingertip sensor channels, which need every tick. The fingers'
attributes are views of the loop's table of finger records, so they read what the tick
computed with nothing to copy back.

The watchdog answers every fault with zero force for that tick and a count in `faults`:
a device that raises, a NaN/invalid sample, a tick that overran its period badly (then the
next tick renders zero). `stop()` (and leaving `run`) sends zero force to every finger, and
so does a MuJoCo error inside the compiled tick before the process exits
(`softproxy.compiled.native`). The overrun watchdog guards real time: by default it watches
only `run(realtime=True)`, so a lockstep run in simulated time (an application calling
`tick()`, tests, benchmarks, `softproxy run` without `--realtime`) gives the same result
however loaded the machine is.
"""

from __future__ import annotations

import atexit
import gc
import math
import threading
import warnings
import weakref

import numpy as np
from numba.core.errors import NumbaExperimentalFeatureWarning

from softproxy import termination
from softproxy.compiled import coupling, native
from softproxy.compiled import group as group_kernel
from softproxy.compiled import servo as kernel
from softproxy.compiled.dispatch import entry
from softproxy.compiled.godobject import WORKSPACE_LIMIT
from softproxy.compiled.layout import DeviceIO, FingerTables, MassMatrix, MjViews, StatRings
from softproxy.local_model import AUTO, LocalModel, every_for_cost, physics_every, step_cost
from softproxy.physics_thread import PhysicsThread
from softproxy.device import Device, check_device, DeviceSample
from softproxy.device_group import DeviceGroup
from softproxy.device_guard import as_limit
from softproxy.device_kernel import SAMPLE, SampleBuffer
from softproxy.finger import SoftFingerProxy
from softproxy.finger_rows import FingerRows
from softproxy.input_error import PLAUSIBLE_REACH_M, implausible
from softproxy.schema import SERVO_RATE_HZ
from softproxy.scheduling import check_priority, realtime_thread, spin_time
from softproxy.world import World

MIN_RATE_HZ, MAX_RATE_HZ = SERVO_RATE_HZ
"""The servo rates a loop runs at (Hz)."""
FAULTS = ("device_error", "invalid_sample", "overrun", "send_error", "unsafe_output")
"""What `ServoLoop.faults` counts; each fault renders zero force on the fingers it touched.
unsafe_output: a finger computed a wrench that is not finite (parameters at their extremes),
or the device's limits were not numbers it can be clamped to (`softproxy.device_guard`)."""
BLOCK_S = 0.1
"""Longest block of compiled ticks `run` runs between two returns to Python (s of loop time):
how long Ctrl-C may wait (a `request_stop` is read every tick)."""
FAST_BLOCK_S = 1.0
"""The same above FAST_RATE_HZ. A return to Python costs ~50 µs (p99 ~100 µs), unboxing the
kernel's arguments: at 10 kHz half a period, so a paced run with 0.1 s blocks missed 2-9×
the deadlines of its pacer alone, with 1 s blocks 2-3× (`softproxy bench latency`)."""
FAST_RATE_HZ = 2000.0


class TickStats:
    """Preallocated ring buffers of tick duration and period (s), and the counts of ticks
    recorded and of deadlines missed; the compiled tick writes them."""

    def __init__(self, capacity: int = 1 << 16) -> None:
        self.duration = np.zeros(capacity)
        self.period = np.zeros(capacity)
        self.capacity = capacity
        self.counters = np.zeros(2, dtype=np.int64)  # [count, misses] (softproxy.compiled.servo)

    @property
    def count(self) -> int:
        """Ticks recorded."""
        return int(self.counters[kernel.COUNT])

    @property
    def misses(self) -> int:
        """Paced ticks that ended after the next tick's deadline."""
        return int(self.counters[kernel.MISSES])

    def durations(self) -> np.ndarray:
        """The recorded durations (s), oldest first (at most `capacity`)."""
        count = self.count
        n = min(count, self.capacity)
        if count <= self.capacity:
            return self.duration[:n].copy()
        i = count % self.capacity
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
_claims: dict[int, "weakref.ref[ServoLoop]"] = {}
"""id(device) -> the loop that drives it, for every loop built and not yet closed: a device
belongs to one open loop at a time (two would send it two forces, and closing one would leave
the other driving a closed device)."""
_claims_lock = threading.Lock()
JOIN_S = 1.0
"""How long `close()` waits (s, beyond the device's stall time) for a servo thread to end its
block before it sends zero force and closes the device regardless."""


def _claim(devices, loop: "ServoLoop") -> None:
    """Make `loop` the one open loop of each of `devices`; ValueError (claiming none) if another
    open loop drives one of them."""
    with _claims_lock:
        for device in devices:
            ref = _claims.get(id(device))
            other = ref() if ref is not None else None
            if other is not None and not other.closed and any(d is device for d in other.devices):
                raise ValueError(f"device {type(device).__name__} is already driven by an open ServoLoop: "
                                 "close that loop (or leave its with block) before building another on it")
        for device in devices:
            _claims[id(device)] = weakref.ref(loop)


def _release(devices, loop: "ServoLoop") -> None:
    """`loop` closed: `devices` are free for another."""
    with _claims_lock:
        for device in devices:
            ref = _claims.get(id(device))
            if ref is not None and ref() in (loop, None):
                del _claims[id(device)]


@atexit.register
def _close_open_loops() -> None:
    for loop in list(_open_loops):
        loop.close()


def _compiled_io(device):
    """The device's `compiled_io()`, or None when it has none, or when its read, send or limits
    are not the ones its compiled_io belongs with (replaced on the instance or in a subclass):
    then the Python call is what the caller asked for, and the limits are read every tick."""
    owner = next((c for c in type(device).__mro__ if "compiled_io" in vars(c)), None)
    if owner is None:
        return None
    for name in ("read", "send", "max_force", "max_torque"):
        if name in vars(device) or getattr(type(device), name, None) is not getattr(owner, name, None):
            return None
    return device.compiled_io()


class _TreeDofs:
    """What `_mass_matrix` points the kernels at, kept alive with the loop: 0..nv-1 as int32."""

    def __init__(self, model) -> None:
        self.dof_index = np.arange(model.nv, dtype=np.int32)


def _mass_matrix(model, data, trees: _TreeDofs) -> MassMatrix:
    """The mass matrix by tree as the implicit coupling solves with it (`layout.MassMatrix`):
    addresses into the model and data, which the loop keeps alive."""
    def at(a):
        return np.uintp(a.ctypes.data)
    return MassMatrix(at(data.qLD), at(data.qLDiagInv), at(model.M_rownnz), at(model.M_rowadr), at(model.M_colind),
                      at(trees.dof_index))


class ServoLoop:
    """Couples fingers to a world through one device, or several, at a fixed rate (Hz).

    Use it as `with ServoLoop(...) as loop:` (or call `close()`): leaving sends zero force and
    closes the device. A loop left open is closed by an exit hook when the interpreter exits,
    and while a loop is open SIGTERM, SIGHUP, SIGQUIT and the other signals whose default
    ends the process (where still at their defaults) end the program through SystemExit, so
    the hook and every `finally` on the way run (`softproxy.termination`;
    `handle_signals=False` leaves the signals alone). A device belongs to one open loop at
    a time (ValueError otherwise).

    Several devices (a list, or a `softproxy.device_group.DeviceGroup`) are read and sent in
    the same tick as one `DeviceGroup`: a finger is driven by finger `device_finger` of device
    `FingerParams.device` (its index in the list), a device that fails zeroes its own fingers
    only (`softproxy.device_group`), and each finger's clamps (`max_force`, `max_torque`) are
    lowered to its own device's limits when the loop is built. One device: every finger's
    `device` is 0.

    The loop sets `world.model.opt.timestep` to its period (1 / rate_hz): MuJoCo takes exactly
    one step per servo tick, which the coupling needs (each tick the proxies follow the bodies
    where that step put them). A model's own timestep is replaced; for a finer MuJoCo step,
    raise the rate.

    Two rates (`physics_rate_hz`, a whole fraction of rate_hz): MuJoCo takes one step of
    1 / physics_rate_hz every rate_hz / physics_rate_hz ticks, with each finger's wrench
    averaged over them, and the ticks in between render against the local model
    (`softproxy.local_model`: the shapes carried forward from MuJoCo's last state, answering
    the fingers' wrenches). For a world whose step costs more than a servo period. A
    real-time run (`run(realtime=True)`) steps MuJoCo in a thread of its own
    (`softproxy.physics_thread`): the servo ticks never wait for a step. Lockstep runs and
    `tick()` step it in the servo thread, deterministically. `physics_rate_hz="auto"`: as fast
    as the world lets MuJoCo go, the highest such rate at which a step (its cost measured
    when the loop is built) takes at most half a core (`local_model.every_for_cost`); the
    rate it chose is `physics_rate_hz` (give that number to repeat a run).
    """

    def __init__(self, world: World, fingers: list[SoftFingerProxy], device: Device | list[Device],
                 rate_hz: float = 1000.0,
                 overrun_factor: float = 3.0, stats_capacity: int = 1 << 16, audit: bool = False,
                 overrun_watchdog: bool | None = None, handle_signals: bool = True, passivity: bool = True,
                 physics_rate_hz: float | str | None = None) -> None:
        if not (math.isfinite(rate_hz) and MIN_RATE_HZ <= rate_hz <= MAX_RATE_HZ):
            raise ValueError(f"rate_hz must be between {MIN_RATE_HZ:g} and {MAX_RATE_HZ:g}, got {rate_hz!r}")
        if isinstance(device, (list, tuple)):
            device = device[0] if len(device) == 1 else DeviceGroup(device)
        check_device(device)
        group = device if isinstance(device, DeviceGroup) else None
        self.devices = list(group.devices) if group is not None else [device]
        """The devices the loop drives (one, or the members of its DeviceGroup `device`)."""
        rows = []  # each finger's row of the device's samples (the group's finger)
        for f in fingers:
            p = f.params
            if group is not None:
                try:
                    rows.append(group.row(p.device, p.device_finger))
                except ValueError as exc:
                    raise ValueError(f"finger {p.name!r}: {exc}") from None
            elif p.device != 0:
                raise ValueError(f"finger {p.name!r} is driven by device {p.device}, but the loop drives one device "
                                 f"(device 0): give the loop a list of devices")
            elif p.device_finger >= device.fingers:
                raise ValueError(f"finger {p.name!r} uses device finger {p.device_finger}, "
                                 f"but the device drives {device.fingers}")
            else:
                rows.append(p.device_finger)
        for f in fingers:
            if f.god.shapes is not world.shapes:
                raise ValueError(f"finger {f.params.name!r} touches shapes of its own, not the world's: "
                                 "build it over world.shapes")
        self.world = world
        self.fingers = fingers
        self.device = device
        self.rate_hz = float(rate_hz)
        self.period = 1.0 / self.rate_hz
        if physics_rate_hz == AUTO:  # as fast as the world lets MuJoCo go
            physics_rate_hz = self.rate_hz / every_for_cost(self.rate_hz, step_cost(world.model, world.data))
        self.physics_every = physics_every(self.rate_hz, physics_rate_hz)
        """Haptic ticks per MuJoCo step: 1 (one rate), or rate_hz / physics_rate_hz."""
        self.physics_rate_hz = self.rate_hz / self.physics_every
        world.timestep = self.period * self.physics_every
        self.state = np.zeros(1, dtype=kernel.LOOP).view(np.recarray)
        """The loop's scalar state (`softproxy.compiled.servo.LOOP`), which the compiled tick
        reads and writes: `t`, `ticks` and `faults` are views of it."""
        st = self.state[0]
        st.period = self.period
        st.period_ns = max(1, int(round(self.period * 1e9)))
        st.every = self.physics_every
        st.overrun_ns = int(overrun_factor * self.period * 1e9)
        self.samples = [DeviceSample() for _ in range(device.fingers)]
        """The device's last samples as `DeviceSample`s (after a block of compiled ticks: its last)."""
        self._sample_rows = SampleBuffer(device.fingers)  # the same samples as SAMPLE rows, what the tick reads
        self.stats = TickStats(stats_capacity)
        self.overrun_watchdog = overrun_watchdog
        """True: a tick that overran `overrun_factor` periods makes the next render zero. None
        (default): only inside `run(realtime=True)`, so an application ticking in lockstep gets
        the same results however loaded the machine is. False: never."""
        st.watching = overrun_watchdog is True
        self.paced = False  # True while run(realtime=True) paces the ticks
        st.passivity = bool(passivity)
        self.audit = audit
        self._started = False
        self.closed = False
        _claim(self.devices, self)  # before compiling; a loop dropped unclosed leaves a dead reference: the device is free
        if group is not None:
            # each finger's clamp lowered to its own device's limits: the loop's guard clamps to
            # the largest device's, and the body must get the reaction of what its device is sent
            for f in fingers:
                member = group.devices[f.params.device]
                f.max_force = min(f.max_force, as_limit(member.max_force))
                f.max_torque = min(f.max_torque, as_limit(member.max_torque))
        self.handle_signals = handle_signals
        self._signals = None  # this loop's claim on softproxy.termination's handlers: its release
        self._unregister_fatal = None  # ... and on the emergency path of a MuJoCo error in a kernel
        self.last_device_error = ""  # what the device said when it last failed to read
        self.last_send_error = ""  # ... and to send
        self.sensors = []  # fingertip sensor channels (softproxy.fingertip_sensors): tick(loop) each tick
        self.rows = FingerRows.gather(fingers) if fingers else FingerRows(world.shapes, 0)
        """The fingers' records, one table: the fingers are views of its rows."""
        self._rows = rows
        self._device_of = np.array(rows, dtype=np.int64)
        self.io = _compiled_io(device)
        """The device's read and send as compiled code (`softproxy.device_kernel.CompiledIO`),
        or None: the device is then called from Python every tick."""
        if self.io is not None:
            if self.io.fingers != device.fingers:
                raise ValueError(f"the device's compiled_io() drives {self.io.fingers} fingers, the device "
                                 f"{device.fingers}: they must agree")
            st.stall_code = self.io.stall_code
            st.stall_ns = int(self.io.stall_s * 1e9)
        self._group_io = None
        """The members' compiled_io(), when the device is a DeviceGroup whose every member has
        one: the group then runs compiled blocks too (`softproxy.compiled.group`)."""
        if group is not None:
            ios = [_compiled_io(d) for d in group.devices]
            if all(io is not None and io.fingers == d.fingers for io, d in zip(ios, group.devices)):
                self._group_io = ios
                self._run_block = self._run_group_block
        # the SAMPLE rows as flat buffers, for a Python device's samples: plain item stores
        raw = self._sample_rows.array.view(np.uint8)
        self._floats = memoryview(raw).cast("d")
        self._bytes = memoryview(raw)
        row = SAMPLE.itemsize
        self._slots = [(j * row // 8, j * row + SAMPLE.fields["valid"][1]) for j in range(device.fingers)]
        # ... and the finger records', for what a Python device is sent: plain item loads
        # (sent_force then sent_torque: six float64 in a row)
        self._sent = memoryview(self.rows.data.view(np.ndarray).view(np.uint8)).cast("d")
        size, at = self.rows.data.dtype.itemsize, self.rows.data.dtype.fields["sent_force"][1]
        self._sent_slots = [((i * size + at) // 8, j) for i, j in enumerate(rows)]
        self.error = None  # what ended a run_in_thread, if it failed
        self._thread = None  # the thread inside run() (or started to run it), while one is
        self._idle = threading.Event()  # clear while run() is in progress, in whatever thread
        self._idle.set()
        self._limit_array = np.zeros(2)  # [max_force, max_torque] for a compiled block whose device keeps none
        self._coupling = coupling.workspace(world.model, len(fingers))  # the implicit coupling's scratch
        self.physics = None
        """With two rates, MuJoCo's thread for real-time runs (`softproxy.physics_thread.
        PhysicsThread`: its steps, late steps, costliest step); None with one rate."""
        self._compile()

    # -- views of the state record ---------------------------------------------------------
    @property
    def t(self) -> float:
        """Loop time (s) of the next tick."""
        return float(self.state[0].t)

    @property
    def sample_rows(self) -> list[int]:
        """Each finger's row of `samples`: its device finger, or with several devices its
        finger of the DeviceGroup (`DeviceGroup.row`); a copy."""
        return list(self._rows)

    @property
    def ticks(self) -> int:
        """Ticks run."""
        return int(self.state[0].ticks)

    @property
    def faults(self) -> dict:
        """Faults counted so far, by kind (`FAULTS`); a copy."""
        st = self.state[0]
        return {name: int(st[name]) for name in FAULTS}

    @property
    def passivity(self) -> bool:
        """The passivity controller (on by default): where a finger's coupling would give the
        hand or the body more energy than it took in (a sampled spring on a stiff wall, say),
        a damper on the relative motion dissipates the excess (`softproxy.compiled.passivity`).
        Off only for experiments; the observer runs either way (`SoftFingerProxy.energy`)."""
        return bool(self.state[0].passivity)

    @passivity.setter
    def passivity(self, on: bool) -> None:
        self.state[0].passivity = bool(on)

    @property
    def audit(self) -> bool:
        """Measure each proxy's depth inside the shapes every tick (slow; a test aid)."""
        return bool(self.state[0].audit)

    @audit.setter
    def audit(self, on: bool) -> None:
        self.state[0].audit = bool(on)

    # -- the compiled pieces ---------------------------------------------------------------
    def _compile(self) -> None:
        """Resolve (compile, or load from numba's cache) the tick's kernels now, not inside the
        first tick, and keep their entry points (`softproxy.compiled.dispatch`) and the bundles
        of arrays they take (`softproxy.compiled.layout`: built once, the same arrays every tick)."""
        world, shapes, data = self.world, self.world.shapes, self.world.data
        m, d = (np.uintp(a) for a in native.addresses(world.model, data))
        model = world.model
        self._trees = _TreeDofs(model)
        self._mj = self._mj_lockstep = MjViews(m, d, data.qvel, data.qacc, data.xfrc_applied, data.xipos,
                                               _mass_matrix(model, data, self._trees))
        self._cr = self._cr_lockstep = None  # the local model of two rates, an argument of the tick's kernels
        self._shapes = shapes.tables
        self.local = None
        """With two rates, the local model the haptic ticks render against between MuJoCo's
        steps (`softproxy.local_model.LocalModel`); None with one rate."""
        if self.physics_every > 1:
            self.local = LocalModel(world)
            mirror = self.local.mirror  # with MuJoCo in its own thread the servo side reads its own copy
            self._mj_threaded = MjViews(m, np.uintp(native.addresses(model, mirror)[1]), mirror.qvel, mirror.qacc,
                                        mirror.xfrc_applied, mirror.xipos, _mass_matrix(model, mirror, self._trees))
            self._cr = self._cr_lockstep = self.local.carried
            self._shapes = self.local.shapes
            self.physics = PhysicsThread(world, self.local, self.period * self.physics_every)
        self._fingers = FingerTables(self.rows.tables, self._device_of, world.wrench, world.bodies, world.counts,
                                     self._coupling)
        stats = self.stats
        self._stats = StatRings(stats.duration, stats.period, stats.counters)
        self._samples = self._sample_rows.array.view(np.recarray)  # fields by attribute, interpreted too
        with_names = "the servo tick"
        self._begin = entry(kernel.begin_tick, (self.state, self._samples, True, self._mj, self._shapes,
                                                self._fingers, self._cr), with_names)
        self._end = entry(kernel.end_tick, (self.state, self._mj, self._fingers, self._stats, 0, self._cr), with_names)
        self._pace = entry(kernel.pace, (self.state,), with_names)
        self._paced_done = entry(kernel.paced_done, (self.state, stats.counters), with_names)
        if self._group_io is not None:
            self._compile_group(with_names)
        if self.io is not None:
            io = self.io
            limits = io.limits if io.limits is not None else self._limit_array
            self._device_io = DeviceIO(io.address, self._samples, np.uintp(self._samples.ctypes.data), limits)
            self._block = entry(kernel.run_ticks, (self.state, io.read, io.send, self._device_io, self._mj,
                                                   self._shapes, self._fingers, self._stats, 1, False, self._cr), with_names)

    def _compile_group(self, with_names: str) -> None:
        """The compiled block of a DeviceGroup of compiled members: their cfuncs, a table of
        their addresses, rows, stall codes and counters, their limits (each member's own
        array, or one the loop fills before every block for a member whose limits are
        constants of its class)."""
        ios, group = self._group_io, self.device
        self._member_limits = [io.limits if io.limits is not None else np.zeros(2) for io in ios]
        self._members = np.array([[int(io.address), group.offsets[k], io.fingers, io.stall_code,
                                   int(io.stall_s * 1e9), 0, 0, 0] for k, io in enumerate(ios)], dtype=np.int64)
        self._group_args = (tuple(io.read for io in ios), tuple(io.send for io in ios), self._members,
                            tuple(self._member_limits), self._samples, np.uintp(self._samples.ctypes.data))
        with warnings.catch_warnings():  # a tuple of cfuncs is typed by numba's "experimental" first-class functions
            warnings.simplefilter("ignore", NumbaExperimentalFeatureWarning)
            self._group_block = entry(group_kernel.run_group_ticks, (self.state, *self._group_args, self._mj,
                                                                     self._shapes, self._fingers, self._stats, 1,
                                                                     False, self._cr), with_names)

    def _run_group_block(self, n: int, paced: bool) -> int:
        """`_run_block` for a DeviceGroup of compiled members: up to n ticks in one call, then
        each member's failures and messages into the group, the samples as DeviceSamples."""
        group, ios, table = self.device, self._group_io, self._members
        for io, limits, member in zip(ios, self._member_limits, group.devices):
            if io.limits is None:  # constants of its class, read here as the Python path does
                limits[0], limits[1] = as_limit(member.max_force), as_limit(member.max_torque)
        st = self.state[0]
        errors_before = int(st.device_error)
        done = self._group_block(self.state, *self._group_args, self._mj, self._shapes, self._fingers, self._stats,
                                 n, paced, self._cr)
        for k, io in enumerate(ios):
            if table[k, 5]:
                group.read_failures[k] += int(table[k, 5])
                table[k, 5] = 0
            if table[k, 6]:
                group.last_errors[k] = io.read_error(int(table[k, 6]))
                table[k, 6] = 0
            if table[k, 7]:
                self.last_send_error = io.read_error(int(table[k, 7]))
                table[k, 7] = 0
        if st.device_error > errors_before:  # every member failed on some tick: as the Python path says it
            self.last_device_error = "; ".join(f"device {k}: {e}" for k, e in enumerate(group.last_errors))
        self._sample_rows.copy_into(self.samples)
        return done

    @property
    def compiled_block(self) -> bool:
        """True when ticks run as compiled blocks (the device gives `compiled_io()`, or is a
        DeviceGroup whose members all do, and no fingertip sensor channel needs Python every tick)."""
        return (self.io is not None or self._group_io is not None) and not self.sensors

    def start(self) -> None:
        """Place every proxy at its finger's first device position (pushed out of any shape)."""
        if self.closed:
            raise RuntimeError("this ServoLoop is closed (its device too): build a new one")
        self._started = True
        _open_loops.add(self)
        if self.handle_signals and self._signals is None and termination.install():
            self._signals = weakref.finalize(self, termination.uninstall)  # also if dropped unclosed
        if self._unregister_fatal is None:
            self._unregister_fatal = native.on_fatal(self._zero_all)
        try:
            self.device.read(self.t, self.samples)
        except Exception:
            self.state[0].device_error += 1
            for f in self.fingers:
                f.placed = False
            return
        usable = self._usable_samples()
        for f, j in zip(self.fingers, self._rows):
            if not usable[j]:
                f.placed = False  # placed at its first good sample instead
            else:
                s = self.samples[j]
                if PLAUSIBLE_REACH_M < max(abs(s.x), abs(s.y), abs(s.z)) <= WORKSPACE_LIMIT:  # (beyond: garbage)
                    warnings.warn(implausible(f"device {type(self.device).__name__} finger {j}: position",
                                              (s.x, s.y, s.z), "m", "in mm? positions are in m, and no desktop "
                                              "device reaches a metre"), stacklevel=2)
                f.place(s.x, s.y, s.z)

    def _usable_samples(self) -> list[bool]:
        """Which of the device's samples are usable (`DeviceSample.usable`); never raises, whatever
        the device put in the list: a slot holding anything but a DeviceSample, or missing
        (the list shortened), is not usable and gets a fresh DeviceSample back for the next read."""
        samples, n = self.samples, len(self._slots)
        usable = [False] * n
        broken = len(samples) != n
        for j in range(min(n, len(samples)) if broken else n):
            try:
                s = samples[j]
                if isinstance(s, DeviceSample):
                    usable[j] = s.usable() is True
                else:
                    broken = True
            except Exception:
                broken = True
        if broken:
            try:
                kept = [s if isinstance(s, DeviceSample) else DeviceSample() for s in list(samples)[:n]]
            except Exception:
                kept = []
            samples[:] = kept + [DeviceSample() for _ in range(n - len(kept))]
        return usable

    def _limits(self) -> None:
        """The device's limits now, as the floats the guard takes: NaN (zero force, a fault)
        for anything that is not a number, a property that raises included."""
        st = self.state[0]
        try:
            st.fmax = as_limit(self.device.max_force)
        except Exception:
            st.fmax = math.nan
        try:
            st.tmax = as_limit(self.device.max_torque)
        except Exception:
            st.tmax = math.nan
        self._limit_array[0], self._limit_array[1] = st.fmax, st.tmax

    def tick(self) -> None:
        """One servo tick at loop time `self.t`; advances time by one period."""
        if not self._started or self.closed:
            self.start()
        if self.compiled_block:
            self._limits()
            self._run_block(1, False)
        else:
            self._python_tick()

    def _run_block(self, n: int, paced: bool) -> int:
        """Up to n compiled ticks in one call (GIL released); then the device's error messages
        and its last samples as DeviceSamples. Returns the ticks run."""
        done = self._block(self.state, self.io.read, self.io.send, self._device_io, self._mj, self._shapes,
                           self._fingers, self._stats, n, paced, self._cr)
        self._after_block()
        return done

    def _after_block(self) -> None:
        st = self.state[0]
        if st.read_code:
            self.last_device_error = self.io.read_error(int(st.read_code))
            st.read_code = 0
        if st.send_code:
            self.last_send_error = self.io.read_error(int(st.send_code))
            st.send_code = 0
        self._sample_rows.copy_into(self.samples)

    def _python_tick(self) -> None:
        """One tick with the device called from Python: read, the compiled tick up to the
        sends, the sends, the sensor channels, the rest of the compiled tick."""
        start = native.monotonic_ns()
        self._limits()  # every tick: a device may derate, or its limits turn to garbage, mid-run
        ok = True
        try:
            self.device.read(self.t, self.samples)
        except Exception as exc:  # a device that fails must not take the loop (and a motor) with it
            self.state[0].device_error += 1
            self.last_device_error = str(exc) or type(exc).__name__
            ok = False
        if ok:
            self._take_samples()
        self._begin(self.state, self._samples, ok, self._mj, self._shapes, self._fingers, self._cr)
        self._sends()
        for ch in self.sensors:
            ch.tick(self)
        self._end(self.state, self._mj, self._fingers, self._stats, start, self._cr)

    def _take_samples(self) -> None:
        """The device's DeviceSamples into the SAMPLE rows the tick reads; a sample that is not
        usable (not valid, a field that is no finite number, no DeviceSample at all) is marked
        not valid."""
        floats, flags = self._floats, self._bytes
        usable = self._usable_samples()
        for (k, valid), s, good in zip(self._slots, self.samples, usable):
            if good:  # every field is now a finite float
                floats[k + 1] = s.x
                floats[k + 2] = s.y
                floats[k + 3] = s.z
                floats[k + 4] = s.qw
                floats[k + 5] = s.qx
                floats[k + 6] = s.qy
                floats[k + 7] = s.qz
                floats[k + 8] = s.twist
                flags[valid] = 1
            else:
                flags[valid] = 0

    def _sends(self) -> None:
        """Each finger's device finger is sent what the tick computed for it (guarded, clamped);
        zero once the loop is closing (`close()` from another thread)."""
        floats, device = self._sent, self.device
        if self.state[0].halt:
            self._zero_sends()
            return
        for k, j in self._sent_slots:
            try:
                device.send(j, floats[k], floats[k + 1], floats[k + 2], floats[k + 3], floats[k + 4], floats[k + 5])
            except Exception as exc:
                self._send_failed(exc)

    def _send_failed(self, exc: Exception) -> None:
        self.state[0].send_error += 1
        self.last_send_error = str(exc) or type(exc).__name__

    def run(self, ticks: int, realtime: bool = False, on_tick=None, spin_s: float | None = None,
            every: int = 1) -> None:
        """Run `ticks` ticks: lockstep (as fast as possible, deterministic) or paced in real time.

        Paced: a tick sleeps only when more than `spin_s` remains before its deadline and
        spins for the rest, and Python's cyclic garbage collector is paused for the run (a
        collection is a pause of its own). `spin_s` None: chosen for the calling thread
        (`softproxy.scheduling.spin_time`): an ordinary thread spins up to 1.5 ms (a sleep
        can overshoot by a millisecond on a busy machine; at 1 kHz one core spinning, as a
        haptic servo thread does), a SCHED_FIFO one at most 0.2 ms (RT throttling).
        `on_tick(loop)` is called after every `every` ticks (and after the last), outside
        the timed region; with compiled blocks a larger `every` leaves more of the run
        compiled. `request_stop()` (from another thread) ends the run after the current
        tick. Zero force is sent to every finger when the run ends, however it ends.
        """
        if every < 1:
            raise ValueError(f"every must be >= 1 tick, got {every!r}")
        me = threading.current_thread()
        running = self._thread
        if running is not None and running is not me and not self._idle.is_set():
            raise RuntimeError(f"this ServoLoop is already running in thread {running.name!r}")
        self._thread = me
        self._idle.clear()
        gc_was_enabled = gc.isenabled()
        st = self.state[0]
        try:
            if not self._started or self.closed:
                self.start()
            if realtime:
                self.paced = True
                st.watching = self.overrun_watchdog is not False
                st.spin_ns = int((spin_time(self.rate_hz) if spin_s is None else spin_s) * 1e9)
                st.next_ns = native.monotonic_ns()
                gc.disable()
            block_s = FAST_BLOCK_S if self.rate_hz > FAST_RATE_HZ else BLOCK_S
            block = every if on_tick is not None else max(1, int(block_s * self.rate_hz))
            left = ticks
            if realtime and self.physics is not None:
                while st.phase != 0 and left > 0:  # the MuJoCo step under way ends in lockstep
                    self.tick()
                    left -= 1
                self.physics.start()
                self._mj, self._cr, st.threaded = self._mj_threaded, self.local.threaded, True
                st.next_ns = native.monotonic_ns()
            while left > 0 and not st.stop and not st.halt:
                n = min(block, left)
                if self.compiled_block:
                    self._limits()  # the kernel reads them every tick (from the device's own state if it keeps them)
                    done = self._run_block(n, realtime)
                else:
                    done = 0
                    while done < n and not st.stop and not st.halt:
                        if realtime:
                            self._pace(self.state)
                        self._python_tick()
                        if realtime:
                            self._paced_done(self.state, self.stats.counters)
                        done += 1
                left -= done
                if on_tick is not None and done:
                    on_tick(self)
        finally:
            st.stop = False
            self.paced = False
            st.watching = self.overrun_watchdog is True
            if gc_was_enabled:
                gc.enable()
            try:
                if st.threaded:  # MuJoCo's thread ends after its step: lockstep goes on from there
                    self._mj, self._cr, st.threaded, st.phase = self._mj_lockstep, self._cr_lockstep, False, 0
                    self.physics.stop()
            finally:
                try:
                    if not st.halt:  # (closing: close() sends the zero once this run is over)
                        self.stop()
                finally:
                    self._idle.set()

    def request_stop(self) -> None:
        """Ask a `run` in progress (in another thread) to end after the tick it is in;
        thread-safe. The run then sends zero force, as every run does when it ends."""
        self.state[0].stop = True

    def run_in_thread(self, ticks: int, realtime: bool = True, on_tick=None, every: int = 1,
                      priority: int | None = None, cpu: int | None = None) -> threading.Thread:
        """`run(...)` in a new thread, started, returned. With a compiled device the ticks run
        without the GIL, so this thread can draw or log meanwhile; it must not touch
        `world.data` (MuJoCo steps it) until the thread has ended: read state in `on_tick`,
        which runs on the servo thread between blocks. A failure in the run is kept in
        `error` and the safe state is sent as always. `close()` (a `with` block's end, an
        exception, a termination signal in the main thread, the exit hook) stops the thread
        before it sends zero force: nothing is sent after `close()` returns. `priority` (SCHED_FIFO, 1–99) and `cpu`
        ask for real-time scheduling of the servo thread (`softproxy.scheduling`); what the OS
        granted is kept in `scheduling`."""
        self.error = None
        self.scheduling = None
        if priority is not None:
            check_priority(priority)  # here, in the caller's thread, not in the servo thread
        running = self._thread
        if running is not None and not self._idle.is_set():
            raise RuntimeError(f"this ServoLoop is already running in thread {running.name!r}")
        if not self._started or self.closed:
            # here, in the caller's (main) thread: only there can the termination signals be
            # taken over, so that SIGTERM and the rest reach `close()`, which stops this thread
            self.start()

        def servo() -> None:
            try:
                if priority is None and cpu is None:
                    self.run(ticks, realtime=realtime, on_tick=on_tick, every=every)
                    return
                with realtime_thread(priority, cpu) as self.scheduling:
                    self.run(ticks, realtime=realtime, on_tick=on_tick, every=every)
            except BaseException as exc:
                self.error = exc
            finally:
                self._idle.set()

        thread = threading.Thread(target=servo, name="softproxy-servo", daemon=True)
        self._thread = thread
        self._idle.clear()  # running from now on: close() waits for this thread's run to end
        thread.start()
        return thread

    def _zero_all(self) -> None:
        """The emergency path (a MuJoCo error inside the compiled tick): zero force to every finger;
        nothing may escape it (the process ends right after)."""
        try:
            self._zero_sends()
        except BaseException:
            pass

    def _zero_sends(self) -> None:
        """Zero force to every finger, each one whatever the others' sends raise: a device's
        error is counted; a BaseException (KeyboardInterrupt, an application's SystemExit out
        of `send`) is raised again once every finger has had its zero."""
        device, first = self.device, None
        for j in self._rows:
            try:
                device.send(j, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
            except Exception as exc:
                self._send_failed(exc)
            except BaseException as exc:
                first = first or exc
        if first is not None:
            raise first

    def _end_run_elsewhere(self) -> None:
        """A run in another thread is asked to end and waited for (its own way out sends zero
        too), up to JOIN_S beyond the device's stall time; past that, noted in
        `last_device_error`, and the caller goes on to the safe state regardless."""
        thread = self._thread
        if thread is None or thread is threading.current_thread() or self._idle.is_set():
            return
        self.state[0].stop = True
        ios = [self.io] if self.io is not None else (self._group_io or [])
        wait = JOIN_S + max((io.stall_s for io in ios), default=0.0)
        if self._idle.wait(wait):
            self.state[0].stop = False  # (the run it asked to end is over: the next run is not stopped)
        else:
            self.last_device_error = (f"the servo thread {thread.name!r} did not end within {wait:g} s: zero force "
                                      "sent from this thread regardless")

    def stop(self) -> None:
        """The safe state: a run in another thread ended first, then zero force to every finger,
        then no finger wrench left on the bodies. Termination signals wait until the zero force
        is sent (`termination.deferred`)."""
        with termination.deferred():
            self._end_run_elsewhere()
            try:
                self._zero_sends()
            finally:
                self.world.clear_wrenches()
                for f in self.fingers:
                    f.clear_output()

    def close(self) -> None:
        """`stop()`, then close the device; the loop cannot tick again. From any thread: a run in
        another thread sends only zero from the moment this is called, and has ended (or been
        waited for JOIN_S) before the zero force goes out, so nothing is sent after `close()`
        returns. Safe to call twice."""
        if self.closed:
            return
        with termination.deferred():
            self.closed = True
            st = self.state[0]
            st.halt = True  # a block running elsewhere sends zero from its next send on, then ends
            st.stop = True
            _open_loops.discard(self)
            try:
                self.stop()
            finally:
                try:
                    self.device.close()
                except Exception as exc:  # the zero force went out first; say what closing said
                    self.last_device_error = f"closing the device: {exc or type(exc).__name__}"
                finally:
                    _release(self.devices, self)
                    if self._signals is not None:
                        self._signals()
                    if self._unregister_fatal is not None:
                        self._unregister_fatal()

    def __enter__(self) -> "ServoLoop":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
