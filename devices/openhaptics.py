"""3D Systems Touch / Touch X (and other OpenHaptics HD devices) through the pyOpenHaptics binding.

`OpenHapticsDevice` implements `softproxy.device.Device` for one finger over pyOpenHaptics
(`pip install 'softproxy[openhaptics]'`, plus the OpenHaptics SDK's libHD and the device
driver): `HapticDevice(callback=..., device_name=...)`, the `hd` module's `get_transform`,
`get_gimbals`, `get_buttons`, `set_force`, and the `hd_callback` decorator. The binding is
imported only when a device is opened; tests hand in a fake (`binding=`, tests/fake_openhaptics.py).

Servo model: OpenHaptics runs its own scheduler thread at 1 kHz and calls the application
back inside a haptic frame; forces may only be set there. The servo tick does NOT run inside
that callback: the servo loop keeps its own clock and thread (real-time pacing, compiled
blocks, the overrun watchdog, zero force on every way out), and a tick - MuJoCo included -
can take longer than the scheduler's 1 ms budget, which would make the scheduler miss its
frames. Instead the two exchange values without ever waiting for each other, through two
latest-value slots, each one tuple replaced by a single reference assignment (atomic in
Python; no lock, so neither side blocks on the other beyond the interpreter lock a Python
callback needs anyway):
* the callback reads the pose, gimbal angles and buttons and publishes them, stamped with
  its clock, in `_latest`; `read` takes the newest one (stale after `stale_ms`: invalid);
* `send` publishes the force, stamped, in `_command`; the callback renders it only while the
  device is armed (a valid sample since the last failure) and the command is younger than
  `command_timeout_ms` (50 ms): a servo loop that stops sending - stalled, crashed, killed
  between ticks - leaves zero force, not its last force, on the device.
The callback never raises (an exception inside it would end its scheduling): what goes wrong
there is recorded, the force zeroed, and `read` reports it.

The interpreter lock. pyOpenHaptics' callback is Python: it needs the lock, and the servo
loop holds it while it ticks and while its compiled pacing spins. Left alone the callback gets
in only when the loop's Python code notices a waiting thread (every 5 ms): measured with the
fake scheduler at 1 kHz beside a paced 1 kHz loop on a 2-core machine, it ran about 100 times
a second. So `read` hands the lock over once per tick (`yield_gil`, a `time.sleep(0)`): the
callback then ran 1000 times a second (once per tick), for a tick median about 3x longer (the
callback's own work now falls inside the tick) on that machine, loaded.

Frames and units. OpenHaptics reports millimetres in its frame - x right, y up, z towards the
operator - and a column-major 4x4 transform; the engine's workspace frame is z up with the
operator looking along +y: x_engine = x_hd, y_engine = -z_hd, z_engine = y_hd
(`DEVICE_TO_ENGINE`). Positions are converted to metres, scaled by `workspace_scale` and
offset by `workspace_offset` (m), as HID profiles do; the stylus orientation is rotated into
the engine frame (reference pose: identity); the twist is the stylus roll, the third gimbal
angle (rad). Forces (N) go back through the transpose. The Touch renders force only (3 DOF):
`max_torque` is 0, torques are dropped.

Limits. `max_force` defaults to the device's nominal maximum continuous force as the SDK
reports it (HD_NOMINAL_MAX_CONTINUOUS_FORCE, read through the binding's `_get_doublev`), and
may be raised up to its nominal maximum force (HD_NOMINAL_MAX_FORCE) for short contacts;
when the SDK gives neither, MODEL_LIMITS (3D Systems' specifications) by model name.

Failure and recovery (as `devices/hid.py`): an exception from the binding, the callback's
error, or no sample from the scheduler for FAIL_AFTER_S (an HD error ends the callback's
scheduling) is a failure: `read` raises DeviceError naming the device, the command is zeroed
and the device disarmed (the callback renders zero). While failed, every REOPEN_INTERVAL_S of
its clock the device is closed (scheduler stopped, device disabled) and opened again; the
failure ends when the callback runs again, and forces render again after a valid sample.
`close()` marks the device closed (every frame that sees it renders zero), disarms and zeroes
the command, waits (at most CLOSE_WAIT_S) for a frame begun after that to render zero - a frame
already under way may still write the old force - then stops the scheduler and disables the
device; it never raises. A device left open is closed at interpreter exit (`atexit`), before
the scheduler's thread could call into an interpreter being torn down.

Opening. pyOpenHaptics 1.0.1 misses a failed hdInitDevice (it compares the handle with an error
code): the open then fails later, on a call without a device, or returns HD_INVALID_HANDLE as the
id; both are reported as hdInitDevice failing, naming what to check.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import io
import math
import time
import types

from softproxy.device import DeviceError, DeviceSample

from . import device_config as config
from .device_frame import frame_in_engine, is_rotation
from .lifecycle import DeviceLifecycle, OpenDevices
from .recovery import REOPEN_INTERVAL_S, FaultRecovery  # noqa: F401 (this adapter's constant too)
from .vendor_binding import availability_row, missing_binding

NAME = "OpenHaptics"
INSTALL_HINT = "pip install 'softproxy[openhaptics]'"
SDK_HINT = ("install the OpenHaptics SDK for your platform and the Touch device driver from 3D Systems "
            "(libHD.so must be on the library path, e.g. /usr/lib)")
FAIL_AFTER_S = 0.1
"""No sample from the scheduler for this long (s) is a failure: its callback is no longer scheduled."""
CLOSE_WAIT_S = 0.05
"""Longest `close()` waits for the callback to render zero force before stopping the scheduler."""
DEVICE_TO_ENGINE = ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))
"""Rows: the engine's x, y, z in OpenHaptics' frame (x right, y up, z towards the operator)."""
HD_NOMINAL_MAX_FORCE, HD_NOMINAL_MAX_CONTINUOUS_FORCE = 0x2603, 0x2604
"""hdGetDoublev parameters (hd_define), used when the binding does not export them."""
HD_INVALID_HANDLE = 0xFFFFFFFF
"""What hdInitDevice returns when it fails. pyOpenHaptics 1.0.1 compares the handle with the error
code HD_BAD_HANDLE instead, so it hands this on as the device's id (its None is never seen)."""
OPEN_HINT = ("is it connected, set up in Touch Setup under that name, and readable by you? "
             "see docs/devices.md")

# model name (lower case, as hdGetString(HD_DEVICE_MODEL_TYPE) says it) -> (peak N, continuous N);
# 3D Systems' specifications: Touch 3.3 N peak, 0.88 N continuous; Touch X 7.9 N, 1.75 N; their
# predecessors the PHANTOM Omni and Desktop alike.
MODEL_LIMITS = {
    "touch x": (7.9, 1.75),
    "phantom desktop": (7.9, 1.75),
    "touch": (3.3, 0.88),
    "phantom omni": (3.3, 0.88),
}
# model name -> (stiffness N/m, damping N·s/m): the most a coupling renders stably, CHAI3D
# 3.x's m_maxLinearStiffness and m_maxLinearDamping (chai3d/chai3d, src/devices/CPhantomDevices.cpp:
# Touch 400 N/m, 4 N·s/m; PHANTOM Omni 700, 5; PHANTOM Desktop 1000, 5). The Touch X takes the
# PHANTOM Desktop's, its predecessor (as in MODEL_LIMITS).
MODEL_STIFFNESS = {
    "touch x": (1000.0, 5.0),
    "phantom desktop": (1000.0, 5.0),
    "touch": (400.0, 4.0),
    "phantom omni": (700.0, 5.0),
}
UNKNOWN_STIFFNESS = (400.0, 4.0)
"""A model not in MODEL_STIFFNESS: the Touch's, the lowest."""
UNKNOWN_LIMITS = (3.3, 0.88)
"""A model not in MODEL_LIMITS and no limit from the SDK: the Touch's, the smallest device."""

_OPEN = OpenDevices()
"""Devices opened and not closed yet: closed at interpreter exit (zero force, scheduler stopped), while
their scheduler still runs - its thread calls into Python, which must not happen in an interpreter
being torn down."""




def load_binding():
    """The binding as a namespace (`hd`, `HapticDevice`, `hd_callback`), or DeviceError (one line)
    naming what to install. pyOpenHaptics loads libHD when imported (an OSError without it)."""
    try:
        with contextlib.redirect_stdout(io.StringIO()):
            hd = importlib.import_module("pyOpenHaptics.hd")
            device = importlib.import_module("pyOpenHaptics.hd_device")
            callback = importlib.import_module("pyOpenHaptics.hd_callback")
    except ModuleNotFoundError as exc:
        raise missing_binding(exc, "pyOpenHaptics", NAME, INSTALL_HINT) from None
    except (ImportError, OSError, NameError) as exc:  # NameError: the binding knows no libHD for this platform
        raise DeviceError(f"the OpenHaptics SDK library was not found ({type(exc).__name__}: {exc}): "
                          f"{SDK_HINT}") from None
    return types.SimpleNamespace(hd=hd, HapticDevice=device.HapticDevice, hd_callback=callback.hd_callback)


def availability(binding=None) -> dict:
    """What `softproxy devices` reports: binding installed, SDK found (never raises). OpenHaptics
    cannot enumerate devices without opening one: its devices are the names set in Touch Setup."""
    row, binding = availability_row("openhaptics", binding, load_binding)
    if binding is None:
        return row
    row["message"] = ("devices are not listed (OpenHaptics opens them by the name set in Touch Setup, "
                      "\"Default Device\" unless renamed)")
    return row


def _by_model(table: dict, model: str, unknown: tuple) -> tuple:
    """The entry of `table` (keys: lower-case model names) for `model`, else `unknown`."""
    m = model.strip().lower()
    for name, figures in table.items():  # "touch x" before "touch"
        if m.startswith(name) or name in m:
            return figures
    return unknown


def model_stiffness(model: str) -> tuple[float, float]:
    """(stiffness N/m, damping N·s/m) the model renders stably (MODEL_STIFFNESS)."""
    return _by_model(MODEL_STIFFNESS, model, UNKNOWN_STIFFNESS)


def _model_limits(model: str) -> tuple[float, float]:
    return _by_model(MODEL_LIMITS, model, UNKNOWN_LIMITS)


def _quaternion(r) -> tuple | None:
    """(w, x, y, z) of a rotation matrix (rows), None when it is no rotation (within 1e-3)."""
    if not is_rotation(r):
        return None
    w = math.sqrt(max(0.0, 1.0 + r[0][0] + r[1][1] + r[2][2])) / 2.0
    x = math.copysign(math.sqrt(max(0.0, 1.0 + r[0][0] - r[1][1] - r[2][2])) / 2.0, r[2][1] - r[1][2])
    y = math.copysign(math.sqrt(max(0.0, 1.0 - r[0][0] + r[1][1] - r[2][2])) / 2.0, r[0][2] - r[2][0])
    z = math.copysign(math.sqrt(max(0.0, 1.0 - r[0][0] - r[1][1] + r[2][2])) / 2.0, r[1][0] - r[0][1])
    n = math.sqrt(w * w + x * x + y * y + z * z)
    return (w / n, x / n, y / n, z / n)


class OpenHapticsDevice(DeviceLifecycle, FaultRecovery):
    """One OpenHaptics device (Touch, Touch X): one finger, 3-DOF force (see the module docstring)."""

    fingers = 1
    max_torque = 0.0
    STATS = ("sends", "nan_sends", "invalid_samples", "stale_samples", "failures", "reopens", "recoveries",
             "callback_ticks", "callback_zeroed")

    def __init__(self, binding=None, *, device_name: str = "Default Device", workspace_scale: float = 1.0,
                 workspace_offset=(0.0, 0.0, 0.0), max_force: float | None = None, stale_ms: float = 20.0,
                 command_timeout_ms: float = 50.0, yield_gil: bool = True, clock=time.monotonic,
                 sleep=time.sleep, label: str | None = None) -> None:
        """Open the device configured as `device_name` in Touch Setup. `binding`: a namespace with
        the binding's `hd`, `HapticDevice` and `hd_callback` (a fake in tests); None loads it.
        `sleep` is how `close()` waits for the scheduler (tests step a fake scheduler in it)."""
        if not isinstance(device_name, str) or not device_name.strip():
            raise ValueError(f"device_name must be the name of a device in Touch Setup, got {device_name!r}")
        scale, offset = config.check_workspace(workspace_scale, workspace_offset)
        for name, v in (("stale_ms", stale_ms), ("command_timeout_ms", command_timeout_ms)):
            if not (config.finite(v) and 0 < v <= 1000):
                raise ValueError(f"{name} must be a number of milliseconds in (0, 1000], got {v!r}")
        self._binding = load_binding() if binding is None else binding
        self._hd = self._binding.hd
        self.device_name = device_name
        self.workspace_scale, self.workspace_offset = scale, offset
        self.stale_s = stale_ms / 1000.0
        self.yield_gil = bool(yield_gil)
        self.command_timeout_s = command_timeout_ms / 1000.0
        self._init_recovery(clock)
        self._sleep = sleep
        self.label = label or f"{NAME} {device_name!r}"
        self.closed = False
        self.sends = self.nan_sends = self.invalid_samples = self.stale_samples = 0
        self.callback_ticks = 0      # callbacks run (scheduler thread)
        self.callback_zeroed = 0     # callbacks that rendered zero because the command was too old
        self.last_force: tuple | None = None  # the last force the callback set (device frame, N)
        # the two slots (see the module docstring): replaced whole, never mutated
        self._latest: tuple | None = None     # (time, x, y, z mm, r00..r22, g0, g1, g2, buttons)
        self._command: tuple | None = None    # (fx, fy, fz N device frame, time)
        self._armed = False                   # the callback renders commands only while armed
        self._zero_after_close = False        # a frame begun after close() rendered zero
        self._callback_error: str | None = None
        self._ticks_at_fail = 0
        # the callback as the scheduler calls it; this reference keeps the C function pointer alive
        self._callback = self._binding.hd_callback(self._servo_callback)
        self._device = self._open()
        self._opened_at = self._clock()
        self.model = self._read_model()
        self.max_stiffness, self.max_damping = model_stiffness(self.model)
        peak, continuous = self._read_limits()
        if max_force is not None and not (config.finite(max_force) and 0.0 <= max_force <= peak):
            self._shutdown()
            raise ValueError(f"max_force must be a finite number in [0, {peak:g}] ({self.model}'s peak force), "
                             f"got {max_force!r}")
        self.peak_force = peak
        self.max_force = float(continuous if max_force is None else max_force)
        _OPEN.add(self)

    # -- opening and closing -----------------------------------------------------------------

    def _open(self):
        """A started HapticDevice with our callback scheduled, or DeviceError."""
        try:
            with contextlib.redirect_stdout(io.StringIO()):  # the binding prints as it opens
                device = self._binding.HapticDevice(callback=self._callback, device_name=self.device_name)
        except NameError as exc:  # pyOpenHaptics loads libHD on Linux and Windows only
            raise DeviceError(f"the OpenHaptics SDK library was not found (pyOpenHaptics loads libHD on Linux "
                              f"and Windows only; {exc}): {SDK_HINT}") from None
        except Exception as exc:
            # a failed hdInitDevice goes on unnoticed by the binding until a call without a device
            # fails (hdGetString's NULL: "'NoneType' object has no attribute 'decode'"). The
            # scheduler is the process's: stop it only if no other device of ours runs on it
            if not any(d is not self for d in _OPEN):
                self._stop_scheduler()
            raise DeviceError(f"cannot open {NAME} device {self.device_name!r}: hdInitDevice failed or the "
                              f"device did not answer ({type(exc).__name__}: {exc}); {OPEN_HINT}") from None
        if getattr(device, "id", None) in (None, HD_INVALID_HANDLE):  # failed hdInitDevice, as 1.0.1 and as meant
            self._stop(device)
            raise DeviceError(f"cannot open {NAME} device {self.device_name!r}: hdInitDevice failed ({OPEN_HINT})")
        return device

    def _stop_scheduler(self) -> None:
        """Stop a scheduler an unfinished HapticDevice may have started."""
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                self._hd.stop_scheduler()
        except Exception:
            pass

    def _stop(self, device) -> None:
        """HapticDevice.close() is hdStopScheduler then hdDisableDevice: done as two steps, so a
        scheduler that fails to stop still leaves the device disabled."""
        self._stop_scheduler()
        try:
            with contextlib.redirect_stdout(io.StringIO()):
                self._hd.close_device(device.id)
        except Exception:
            pass

    def _read_model(self) -> str:
        try:
            model = self._hd.get_model()
            return model if isinstance(model, str) and model else "unknown model"
        except Exception:
            return "unknown model"

    def _read_limits(self) -> tuple[float, float]:
        """(peak, continuous) force (N): the SDK's nominal figures, else the model table."""
        table = _model_limits(self.model)
        get = getattr(self._hd, "_get_doublev", None)
        found = []
        for code, name in ((HD_NOMINAL_MAX_FORCE, "HD_NOMINAL_MAX_FORCE"),
                           (HD_NOMINAL_MAX_CONTINUOUS_FORCE, "HD_NOMINAL_MAX_CONTINUOUS_FORCE")):
            try:
                v = float(get(getattr(self._hd, name, code), ctypes.c_double).value)
            except Exception:
                v = math.nan
            found.append(v if math.isfinite(v) and 0.0 < v <= 100.0 else None)
        peak = found[0] if found[0] is not None else table[0]
        continuous = found[1] if found[1] is not None else table[1]
        return peak, min(continuous, peak)

    def _shutdown(self) -> None:
        self._armed = False
        self._command = None
        self._stop(self._device)

    # -- the scheduler's side ----------------------------------------------------------------

    def _servo_callback(self) -> None:
        """Runs in the OpenHaptics scheduler thread, inside a frame, at 1 kHz. Never raises."""
        hd = self._hd
        try:
            m = hd.get_transform()
            g = hd.get_gimbals()
            b = hd.get_buttons()
            now = self._clock()
            # column-major: m[3] is the translation, m[c][r] the rotation's row r, column c
            self._latest = (now, m[3][0], m[3][1], m[3][2], m[0][0], m[1][0], m[2][0], m[0][1], m[1][1], m[2][1],
                            m[0][2], m[1][2], m[2][2], g[0], g[1], g[2], b)
            closing = self.closed  # read before the command: a frame that saw it renders zero
            cmd = self._command
            if not closing and cmd is not None and self._armed and now - cmd[3] <= self.command_timeout_s:
                force = [cmd[0], cmd[1], cmd[2]]
            else:
                if cmd is not None and self._armed and not closing:
                    self.callback_zeroed += 1
                force = [0.0, 0.0, 0.0]
            hd.set_force(force)
            self.last_force = tuple(force)
            if closing:
                self._zero_after_close = True
            self.callback_ticks += 1
        except BaseException as exc:  # nothing may escape into the scheduler
            self._callback_error = f"{type(exc).__name__}: {exc}"
            try:
                closing = self.closed
                hd.set_force([0.0, 0.0, 0.0])
                self.last_force = (0.0, 0.0, 0.0)
                if closing:
                    self._zero_after_close = True
            except BaseException:
                pass

    # -- failure and recovery ----------------------------------------------------------------

    def _fail(self, why: str) -> DeviceError:
        """Enter (or stay in) the failed state: disarmed, no command; the DeviceError to raise."""
        self._armed = False
        self._command = None
        self._enter_failure()  # a new failure when it worked until now (or never had a valid sample)
        self._ticks_at_fail = self.callback_ticks
        plan = self._with_last_reopen(f"rendering zero force; reopening every {REOPEN_INTERVAL_S:g} s")
        self._fault = f"{self.label}: {why}; {plan}"
        return DeviceError(self._fault)

    def _try_reopen(self) -> None:
        self._stop(self._device)
        self._latest = None
        self._callback_error = None
        try:
            self._device = self._open()
        except DeviceError as exc:
            self.last_reopen_error = str(exc)
            return
        self._ticks_at_fail = self.callback_ticks
        self._opened_at = self._clock()
        self._reopened()

    def _recover(self) -> bool:
        """While failed: reopen when due; True once the callback has run again since (rendering zero)."""
        self._reopen_when_due()
        if self._callback_error is not None or self.callback_ticks <= self._ticks_at_fail:
            return False
        self._fault = None
        return True

    # -- the Device protocol -----------------------------------------------------------------

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        if self.closed:
            raise DeviceError(f"{self.label}: device is closed")
        if self.yield_gil:
            time.sleep(0)  # the interpreter lock to the scheduler's callback, once per tick
        if self._fault is not None and not self._recover():
            raise DeviceError(self._fault)
        if self._callback_error is not None:
            why, self._callback_error = self._callback_error, None
            raise self._fail(f"failed in the scheduler callback ({why})")
        now = self._clock()
        latest = self._latest
        since = now - (latest[0] if latest is not None else self._opened_at)
        if since > FAIL_AFTER_S:
            raise self._fail(f"no sample from the OpenHaptics scheduler for {since * 1000:.0f} ms "
                             "(an HD error ends its callback)")
        s = samples[0]
        s.t = t
        ok = latest is not None and since <= self.stale_s
        if latest is not None and not ok:
            self.stale_samples += 1
        if ok:
            ok = self._fill(s, latest)
        s.valid = ok
        if not ok:
            self.invalid_samples += 1
        elif not self._armed and not self.closed:  # a valid sample arms the device: the first, and after a failure
            self._fresh_sample()
            self._armed = True

    def _fill(self, s: DeviceSample, latest: tuple) -> bool:
        """The sample from the callback's reading; False when a value is no finite number or the
        stylus frame no rotation."""
        try:
            v = [float(x) for x in latest[1:16]]
            buttons = latest[16]
        except (TypeError, ValueError, OverflowError):
            return False
        if not all(math.isfinite(x) for x in v):
            return False
        m = DEVICE_TO_ENGINE
        p = [v[0] / 1000.0, v[1] / 1000.0, v[2] / 1000.0]  # mm -> m
        q = _quaternion(frame_in_engine(m, [v[3:6], v[6:9], v[9:12]])[1])
        if q is None:
            return False
        k, o = self.workspace_scale, self.workspace_offset
        s.x, s.y, s.z = (k * (m[j][0] * p[0] + m[j][1] * p[1] + m[j][2] * p[2]) + o[j] for j in range(3))
        s.qw, s.qx, s.qy, s.qz = q
        s.twist = v[14]
        s.buttons = buttons if isinstance(buttons, int) and not isinstance(buttons, bool) and buttons >= 0 else 0
        return True

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        if not self._count_send(finger, (fx, fy, fz)):
            fx = fy = fz = 0.0  # the motors get zero
        if self._fault is not None:
            raise DeviceError(self._fault)
        m = DEVICE_TO_ENGINE  # engine -> device: the transpose
        f = [m[0][j] * fx + m[1][j] * fy + m[2][j] * fz for j in range(3)]
        n = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
        lim = self.max_force
        if n > lim:
            f = [c * (lim / n) for c in f]
        self._command = (float(f[0]), float(f[1]), float(f[2]), self._clock())  # one assignment: the slot

    def close(self) -> None:
        """Mark closed, disarm and zero the command, wait (at most CLOSE_WAIT_S) for a frame that
        began after that to render zero, then stop the scheduler and disable the device. A frame
        already under way when close() starts may still write the old force: waiting for any
        frame to end would let that one pass for the zero. Never raises."""
        if self.closed:
            return
        self.closed = True  # first: every frame that reads it from now on renders zero
        self._armed = False
        self._command = None
        _OPEN.discard(self)
        try:
            deadline = time.monotonic() + CLOSE_WAIT_S
            while not self._zero_after_close and time.monotonic() < deadline:
                self._sleep(0.001)
        except Exception:
            pass
        self._stop(self._device)

    def __repr__(self) -> str:
        return f"OpenHapticsDevice({self.label!r}, model={self.model!r}, max_force={self.max_force:g})"

    # -- configuration -----------------------------------------------------------------------

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>", binding=None, clock=None,
                    sleep=None) -> "OpenHapticsDevice":
        """Build from a scene's [device] table; errors name the field.

            type = "openhaptics"
            device_name = "Default Device"  # the name in Touch Setup
            workspace_scale = 1.0           # positions x this
            workspace_offset = [0, 0, 0]    # m, added to positions
            max_force_N = 0.88              # default: the continuous force; at most the peak force
            stale_ms = 20                   # a sample older than this is invalid
            command_timeout_ms = 50         # a force older than this is not rendered
        """
        config.check_table(cfg, source)
        table = config.check_type(cfg, source, "openhaptics")  # each field as softproxy.schema declares it
        kwargs = config.given(table, cfg, {"device_name": "device_name", "workspace_scale": "workspace_scale",
                                           "workspace_offset": "workspace_offset", "max_force_N": "max_force",
                                           "stale_ms": "stale_ms", "command_timeout_ms": "command_timeout_ms"})
        if "device_name" in kwargs:
            kwargs["device_name"] = kwargs["device_name"].strip()
        if clock is not None:
            kwargs["clock"] = clock
        if sleep is not None:
            kwargs["sleep"] = sleep
        return config.construct(source, cls, binding, **kwargs)

    @classmethod
    def from_argument(cls, argument: str, scene=None, *, binding=None, clock=None, sleep=None) -> "OpenHapticsDevice":
        """`--device openhaptics:NAME[,key=value...]` (NAME: the device's name in Touch Setup, or
        `default`), keys those of `from_config`, vectors separated by ':'. When the scene's own
        [device] is an OpenHaptics one, the argument overrides its fields."""
        source = f"--device openhaptics:{argument}"
        cfg, parts = config.argument_table(argument, scene, "openhaptics")
        if parts and "=" not in parts[0]:
            name = parts.pop(0)
            cfg["device_name"] = "Default Device" if name.lower() in ("default", "first", "auto") else name
        config.argument_items(cfg, parts, source, usage="NAME[,key=value...]", strings=("device_name", "type"))
        return cls.from_config(cfg, source=source, binding=binding, clock=clock, sleep=sleep)
