"""Force Dimension haptic devices (omega, sigma, delta, lambda, Novint Falcon) through the DHD SDK.

`ForceDimensionDevice` implements `softproxy.device.Device` over the `dhd` module of the
`forcedimension-core` binding (`pip install 'softproxy[forcedimension]'`, plus the vendor's
SDK library libdrd). The binding is imported only when a device is opened; tests hand a fake
of the module in (`dhd=`), see tests/fake_dhd.py.

Servo model: polled. DHD has no thread of its own; every servo tick `read` asks the SDK for
the end-effector's position (`getPosition`), the wrist's frame and joint angles
(`getOrientationFrame`, `getOrientationRad`; devices with a wrist), the gripper's gap
(`getGripperGap`; with a gripper) and the buttons (`getButtonMask`), and `send` writes the
force, torque and gripper force (`setForceAndTorqueAndGripperForce` on a device with an
active gripper, `setForceAndTorque` with an active wrist, `setForce` otherwise) - one SDK
write per send. Every call returns 0 (or TIMEGUARD = 1 / MOTOR_SATURATED = 2) on success and
-1 on failure, with the reason in `errorGetLastStr()`.

Frames and units. DHD reports SI units (m, rad, N, N·m) in the device frame: x towards the
operator, y to the right, z up. The engine's workspace frame is z up with the operator
looking along +y: x_engine = y_dhd, y_engine = -x_dhd, z_engine = z_dhd (`DEVICE_TO_ENGINE`,
a rotation). Positions are then scaled by `workspace_scale` and shifted by
`workspace_offset` (m), as HID profiles do; orientations are rotated (the reference pose
stays the identity); forces and torques go back through the transpose, unscaled.

Degrees of freedom. Position on every model; the orientation (a quaternion) and the twist -
the handle's roll, the wrist joint nearest the handle (`getOrientationRad()[2]`) - on
devices with a wrist (omega.6/7, sigma.7, delta.6, lambda.7). A device with a gripper
(omega.7, sigma.7, lambda.7) drives two fingers by default (`gripper = "auto"`): finger 0
(thumb) and finger 1 (index) sit either side of the end-effector along the gripper axis
(`gripper_axis`, a column of the wrist's frame, y by default), `gap / 2` away each (scaled as
positions are). The forces of the two fingers become: the sum, on the end-effector; their
moments about it plus their torques, on an active wrist; and the squeeze, the gripper force
`fg = ((f_index - f_thumb) · axis) / 2`, positive opening the gripper (the convention of
CHAI3D's gripper tool, which hands that value to `dhdSetForceAndTorqueAndGripperForce`).
`gripper = "off"` drives one finger at the end-effector.

Limits. `max_force` / `max_torque` / `max_gripper_force` default to the model's rated
force (MODEL_LIMITS, the figures CHAI3D's Force Dimension driver gives each model), lowered to
the SDK's own limit when one is set (`getMaxForce() >= 0`), and may only be lowered further.
They are handed to the SDK too (`setMaxForce`, `setMaxTorque`, `setMaxGripperForce`), so the
library clamps again whatever this adapter does. Every send is finite and within the limits:
a non-finite wrench becomes zero (counted in `nan_sends`); the sum of two fingers' forces is
clamped again (each finger is clamped by the engine, their sum may be twice that).

Stalls. DHD keeps rendering the last command until it gets another, so a loop that stops
sending (a pause in the host, a hung tick, an application stopped in a debugger) would leave
its last force on the hand. A watchdog thread (the adapter's own, every `stall_ms` / 4)
replaces a non-zero command older than `stall_ms` (50 ms; the OpenHaptics command timeout's
figure) by zero force (counted in `stall_zeroes`); the loop's next send renders again. The
controller's own watchdog (`dhdSetWatchdog`) would also cover a dead process, but it needs
expert mode, not every model has it, and what it leaves disabled after tripping is not
documented: it is not used.

Failure and recovery (as `devices/hid.py`). A call that returns -1, or raises, is a failure:
that read or send raises DeviceError naming the device and the SDK's reason, and the loop
renders zero force. From then on no force is written: every read first writes zero force
(and, every REOPEN_INTERVAL_S of its clock, closes and reopens the device, which must be the
same model and serial number as before); once that goes through, samples are invalid until
one reads clean, and forces render again after it (`recoveries`). A reading that is not a
finite number (or a frame that is no rotation) makes that sample invalid, never a force.
`close()` always tries zero force (CLOSE_ZERO_ATTEMPTS writes), then disables the force
(`enableForce(False)`) and closes the device; it never raises. `read`, `send` and `close` take
one lock, so a close from another thread cannot let a command land after its zero, and once
closed only zero is ever written. A device left open is closed at interpreter exit (`atexit`).

Configuration: `from_config` takes a scene's [device] table (`type = "forcedimension"`),
`from_argument` serves `--device forcedimension[:index=0,gripper=off,...]`. `availability()`
says what `softproxy devices` prints about the backend.
"""

from __future__ import annotations

import contextlib
import ctypes
import importlib
import io
import math
import threading
import time

from softproxy.device import DeviceError, DeviceSample

from . import device_config as config
from .device_frame import frame_in_engine, is_rotation
from .lifecycle import DeviceLifecycle, OpenDevices, start_stall_watchdog
from .recovery import CLOSE_ZERO_ATTEMPTS, REOPEN_INTERVAL_S, FaultRecovery  # noqa: F401 (this adapter's constants too)
from .vendor_binding import availability_row, missing_binding

NAME = "Force Dimension"
INSTALL_HINT = "pip install 'softproxy[forcedimension]'"
SDK_HINT = ("install the Force Dimension SDK (libdrd, from forcedimension.com) and set FDSDK to its folder "
            "or copy libdrd.so* to /usr/local/lib")
STALL_MS = 50.0
"""Default of `stall_ms`: a non-zero command older than this (ms) is replaced by zero force."""
MAX_GAP_M = 0.2
"""A gripper gap beyond this (m) is no reading of a hand-held gripper: the sample is invalid."""
TIMEGUARD, MOTOR_SATURATED = 1, 2
"""DHD's non-error return codes besides 0 (forcedimension_core.constants)."""

DEVICE_TO_ENGINE = ((0.0, 1.0, 0.0), (-1.0, 0.0, 0.0), (0.0, 0.0, 1.0))
"""Rows: the engine's x, y, z in DHD's frame (x towards the operator, y right, z up)."""

# DHD device type ids (forcedimension_core.constants.DeviceType) -> (model, force N, torque N·m, gripper N).
# The figures of CHAI3D 3.x's Force Dimension driver (src/devices/CDeltaDevices.cpp, its per-model
# specifications): delta.3 20 N; delta.6 20 N, 0.2 N·m; omega.3/.6 12 N; omega.7 12 N, gripper 8 N;
# sigma.7 12 N, 0.2 N·m, gripper 8 N; Falcon 8 N. Models that table lacks take a sibling's: sigma.3
# and lambda.3 the omega.3's, lambda.7 the sigma.7's. A limit of 0 on a DOF the device cannot drive
# (a passive wrist) renders nothing there.
MODEL_LIMITS = {
    63: ("delta.3", 20.0, 0.0, 0.0),
    33: ("omega.3", 12.0, 0.0, 0.0),
    34: ("omega.6", 12.0, 0.0, 0.0),
    36: ("omega.6 (left)", 12.0, 0.0, 0.0),
    35: ("omega.7", 12.0, 0.0, 8.0),
    37: ("omega.7 (left)", 12.0, 0.0, 8.0),
    206: ("sigma.3", 12.0, 0.0, 0.0),
    104: ("sigma.7", 12.0, 0.2, 8.0),
    105: ("sigma.7 (left)", 12.0, 0.2, 8.0),
    203: ("lambda.3", 12.0, 0.0, 0.0),
    108: ("lambda.7", 12.0, 0.2, 8.0),
    109: ("lambda.7 (left)", 12.0, 0.2, 8.0),
    60: ("Novint Falcon", 8.0, 0.0, 0.0),
}
# DHD device type ids -> (stiffness N/m, damping N·s/m): the most a coupling renders stably on
# the model, CHAI3D 3.x's m_maxLinearStiffness and m_maxLinearDamping (chai3d/chai3d,
# src/devices/CDeltaDevices.cpp: delta.3, omega.3/.6/.7 5000 N/m, 30 N·s/m; sigma.7 4000 N/m,
# 30 N·s/m; src/devices/CFalconDevice.cpp: Falcon 3000 N/m, 20 N·s/m). Siblings as MODEL_LIMITS.
MODEL_STIFFNESS = {63: (5000.0, 30.0), 33: (5000.0, 30.0), 34: (5000.0, 30.0), 36: (5000.0, 30.0),
                   35: (5000.0, 30.0), 37: (5000.0, 30.0), 206: (5000.0, 30.0), 203: (5000.0, 30.0),
                   104: (4000.0, 30.0), 105: (4000.0, 30.0), 108: (4000.0, 30.0), 109: (4000.0, 30.0),
                   60: (3000.0, 20.0)}
UNKNOWN_STIFFNESS = (3000.0, 20.0)
"""A type id not in MODEL_STIFFNESS: the lowest figures of the table (the Falcon's)."""
UNKNOWN_LIMITS = ("unknown model", 5.0, 0.0, 0.0)
"""A type id not in MODEL_LIMITS (a newer model, a custom controller): a conservative force, no torque."""

_OPEN = OpenDevices()
"""Devices opened and not closed yet: closed (zero force, forces disabled) at interpreter exit."""


_AXES = {"x": 0, "y": 1, "z": 2}


# --- the binding ---------------------------------------------------------------------------------

def load_binding():
    """The `forcedimension_core.dhd` module, or DeviceError (one line) naming what to install.
    The binding loads libdrd when imported and writes to stderr when it cannot: that is kept
    out of the user's terminal, the message says it instead."""
    said = io.StringIO()
    try:
        with contextlib.redirect_stderr(said):
            return importlib.import_module("forcedimension_core.dhd")
    except ModuleNotFoundError as exc:
        raise missing_binding(exc, "forcedimension_core", NAME, INSTALL_HINT) from None
    except (ImportError, OSError) as exc:
        # the binding raises the same ImportError whatever went wrong and writes the reason to
        # stderr: libdrd not found, found but not loadable (libusb), or older than it needs
        why = " ".join(line.strip() for line in said.getvalue().splitlines() if line.strip()) or str(exc)
        raise DeviceError(f"the Force Dimension SDK library was not found or cannot load ({why}): "
                          f"{SDK_HINT}") from None


def availability(dhd=None) -> dict:
    """What `softproxy devices` reports: binding installed, SDK found, devices seen (never raises)."""
    row, dhd = availability_row("forcedimension", dhd, load_binding)
    if dhd is None:
        return row
    try:
        version = dhd.getSDKVersion()
        row["sdk_version"] = ".".join(str(int(v)) for v in version)
    except Exception:
        pass
    try:
        n = int(dhd.getDeviceCount())
    except Exception as exc:
        row["message"] = f"cannot count devices: {exc}"
        return row
    if n < 0:
        row["message"] = f"cannot count devices: {_last_error(dhd)}"
        return row
    row["devices"] = n
    row["message"] = f"{n} device(s) connected" + ("" if n else " (check the USB cable, power and udev rule)")
    return row


def _last_error(dhd) -> str:
    try:
        return str(dhd.errorGetLastStr()) or "no reason given"
    except Exception as exc:
        return f"no reason given ({type(exc).__name__})"


def _clamp_norm(v: list, limit: float) -> list:
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return [c * (limit / n) for c in v] if n > limit else v


def _to_engine(v) -> list:
    m = DEVICE_TO_ENGINE
    return [m[i][0] * v[0] + m[i][1] * v[1] + m[i][2] * v[2] for i in range(3)]


def _to_device(v) -> list:
    m = DEVICE_TO_ENGINE
    return [m[0][j] * v[0] + m[1][j] * v[1] + m[2][j] * v[2] for j in range(3)]


def quaternion_from_matrix(r) -> tuple[float, float, float, float] | None:
    """(w, x, y, z) of a rotation matrix (rows), or None when `r` is no rotation (not orthonormal
    within 1e-3, or a reflection): garbage from a device must not become an orientation."""
    if not is_rotation(r):
        return None
    tr = r[0][0] + r[1][1] + r[2][2]
    if tr > 0.0:
        s = 2.0 * math.sqrt(tr + 1.0)
        q = (0.25 * s, (r[2][1] - r[1][2]) / s, (r[0][2] - r[2][0]) / s, (r[1][0] - r[0][1]) / s)
    elif r[0][0] > r[1][1] and r[0][0] > r[2][2]:
        s = 2.0 * math.sqrt(1.0 + r[0][0] - r[1][1] - r[2][2])
        q = ((r[2][1] - r[1][2]) / s, 0.25 * s, (r[0][1] + r[1][0]) / s, (r[0][2] + r[2][0]) / s)
    elif r[1][1] > r[2][2]:
        s = 2.0 * math.sqrt(1.0 + r[1][1] - r[0][0] - r[2][2])
        q = ((r[0][2] - r[2][0]) / s, (r[0][1] + r[1][0]) / s, 0.25 * s, (r[1][2] + r[2][1]) / s)
    else:
        s = 2.0 * math.sqrt(1.0 + r[2][2] - r[0][0] - r[1][1])
        q = ((r[1][0] - r[0][1]) / s, (r[0][2] + r[2][0]) / s, (r[1][2] + r[2][1]) / s, 0.25 * s)
    n = math.sqrt(sum(c * c for c in q))
    return tuple(c / n for c in q)


class ForceDimensionDevice(DeviceLifecycle, FaultRecovery):
    """One Force Dimension device: one finger, or two on a gripper (see the module docstring)."""

    STATS = ("sends", "nan_sends", "saturated", "invalid_samples", "failures", "errors", "reopens", "recoveries",
             "stall_zeroes")

    def __init__(self, dhd=None, *, index: int | None = None, serial: int | None = None, gripper: str = "auto",
                 gripper_axis: str = "y", workspace_scale: float = 1.0, workspace_offset=(0.0, 0.0, 0.0),
                 max_force: float | None = None, max_torque: float | None = None,
                 max_gripper_force: float | None = None, stall_ms: float = STALL_MS, clock=time.monotonic,
                 label: str | None = None) -> None:
        """Open the device: the one at enumeration `index`, the one with `serial`, or the first
        available. `dhd`: the binding's module (a fake in tests); None loads the real one.
        `stall_ms`: the stall watchdog's limit (0: no watchdog)."""
        if gripper not in ("auto", "on", "off"):
            raise ValueError(f"gripper must be \"auto\", \"on\" or \"off\", got {gripper!r}")
        if gripper_axis not in _AXES:
            raise ValueError(f"gripper_axis must be \"x\", \"y\" or \"z\" (the wrist frame's axis), got {gripper_axis!r}")
        scale, offset = config.check_workspace(workspace_scale, workspace_offset)
        for name, value in (("index", index), ("serial", serial)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, int) or value < 0):
                raise ValueError(f"{name} must be an integer >= 0, got {value!r}")
        if not (config.finite(stall_ms) and 0 <= stall_ms <= 1000):
            raise ValueError(f"stall_ms must be a number of milliseconds in [0, 1000] (0: no watchdog), got {stall_ms!r}")
        self._dhd = load_binding() if dhd is None else dhd
        self.stall_s = stall_ms / 1000.0
        self.stall_zeroes = 0
        self._last_write = time.monotonic()  # when a command last went out (host clock, s)
        self.index, self.serial_wanted = index, serial
        self.workspace_scale, self.workspace_offset = scale, offset
        self._axis = _AXES[gripper_axis]
        self._init_recovery(clock)
        self.closed = False
        # read/send/close from different threads (a loop closed from another thread): one at a
        # time, so no command can land between close()'s zero and the forces being disabled
        self._lock = threading.RLock()
        self.sends = self.nan_sends = self.saturated = 0
        self.invalid_samples = self.errors = 0
        self.last_command: tuple | None = None  # (force, torque, gripper force) last written, device frame

        self._id = self._open_handle()
        try:
            dhd_ = self._dhd
            kind = int(dhd_.getSystemType(self._id))
            self.system_type = kind
            self.model, cap_f, cap_t, cap_g = MODEL_LIMITS.get(kind, UNKNOWN_LIMITS)
            self.max_stiffness, self.max_damping = MODEL_STIFFNESS.get(kind, UNKNOWN_STIFFNESS)
            name = dhd_.getSystemName(self._id)
            self.system_name = name if isinstance(name, str) else self.model
            self.serial = int(dhd_.getSerialNumber(self._id))
            self.has_wrist = bool(dhd_.hasWrist(self._id))
            active_wrist = bool(dhd_.hasActiveWrist(self._id))
            has_gripper = bool(dhd_.hasGripper(self._id))
            self.active_gripper = bool(dhd_.hasActiveGripper(self._id))
            cap_t = cap_t if active_wrist else 0.0
            cap_g = cap_g if self.active_gripper else 0.0
            for getter, cap in (("getMaxForce", "f"), ("getMaxTorque", "t"), ("getMaxGripperForce", "g")):
                sdk = getattr(dhd_, getter)(self._id) if hasattr(dhd_, getter) else -1.0
                if config.finite(sdk) and sdk >= 0.0:  # a limit the SDK enforces already: never above it
                    if cap == "f":
                        cap_f = min(cap_f, float(sdk))
                    elif cap == "t":
                        cap_t = min(cap_t, float(sdk))
                    else:
                        cap_g = min(cap_g, float(sdk))
        except DeviceError:
            self._release()
            raise
        except Exception as exc:
            self._release()
            raise DeviceError(f"{NAME} device: cannot read what it is ({type(exc).__name__}: {exc})") from None
        if gripper == "on" and not has_gripper:
            self._release()
            raise ValueError(f"gripper=on: this {self.system_name} has no gripper")
        self.fingers = 2 if has_gripper and gripper != "off" else 1
        self.active_wrist = active_wrist
        self.label = label or f"{self.system_name} #{self.serial}"
        for name, value, cap in (("max_force", max_force, cap_f), ("max_torque", max_torque, cap_t),
                                 ("max_gripper_force", max_gripper_force, cap_g)):
            if value is not None and not (config.finite(value) and 0.0 <= value <= cap):
                self._release()
                raise ValueError(f"{name} must be a finite number in [0, {cap:g}] ({self.system_name}'s limit), "
                                 f"got {value!r}")
        self.max_force = float(cap_f if max_force is None else max_force)
        self.max_torque = float(cap_t if max_torque is None else max_torque)
        self.max_gripper_force = float(cap_g if max_gripper_force is None else max_gripper_force)
        self._identity = (self.system_type, self.serial)
        self._wrench = [[0.0] * 6 for _ in range(self.fingers)]  # engine frame, per finger
        self._p = [0.0, 0.0, 0.0]
        self._frame = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        self._angles = [0.0, 0.0, 0.0]
        self._gap = ctypes.c_double(0.0)
        self._axis_e = [0.0, 0.0, 0.0]  # the gripper axis (engine frame, unit) of the last valid sample
        self._half_gap = 0.0            # half the gripper's gap (m, unscaled) of the last valid sample
        try:
            self._start()
        except DeviceError:
            self._release()
            raise
        _OPEN.add(self)
        if self.stall_s > 0.0:
            start_stall_watchdog(self, "softproxy-dhd-watchdog")

    # -- opening ------------------------------------------------------------------------------

    def _open_handle(self) -> int:
        """An SDK device id, or DeviceError with the SDK's reason."""
        dhd = self._dhd
        try:
            if self.index is not None:
                device_id = dhd.openID(self.index)
            elif self.serial_wanted is not None:
                device_id = dhd.openSerial(self.serial_wanted)
            else:
                device_id = dhd.open()
        except Exception as exc:
            raise DeviceError(f"cannot open a {NAME} device: {type(exc).__name__}: {exc}") from None
        if not isinstance(device_id, int) or device_id < 0:
            which = (f" at index {self.index}" if self.index is not None else
                     f" with serial {self.serial_wanted}" if self.serial_wanted is not None else "")
            raise DeviceError(f"cannot open a {NAME} device{which}: {_last_error(dhd)} (`softproxy devices` "
                              "lists what the SDK sees; on Linux the USB device needs a udev rule, docs/devices.md)")
        return device_id

    def _start(self) -> None:
        """Hand the limits to the SDK, enable forces, and write zero force: the device renders nothing yet."""
        dhd, i = self._dhd, self._id
        self._call("setting the force limit", dhd.setMaxForce, self.max_force, i)
        if self.active_wrist:
            self._call("setting the torque limit", dhd.setMaxTorque, self.max_torque, i)
        if self.active_gripper:
            self._call("setting the gripper force limit", dhd.setMaxGripperForce, self.max_gripper_force, i)
        self._call("enabling forces", dhd.enableForce, True, i)
        self._write((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, "writing zero force")

    def _release(self) -> None:
        try:
            self._dhd.close(self._id)
        except Exception:
            pass

    def _call(self, what: str, fn, *args):
        """fn(*args); a negative return or an exception is a DeviceError naming `what` (not counted)."""
        try:
            rc = fn(*args)
        except Exception as exc:
            raise DeviceError(f"{NAME} device: {what} failed ({type(exc).__name__}: {exc})") from None
        if isinstance(rc, int) and rc < 0:
            raise DeviceError(f"{NAME} device: {what} failed ({_last_error(self._dhd)})")
        return rc

    # -- failure and recovery ----------------------------------------------------------------

    def _fail(self, what: str, why: str) -> DeviceError:
        """Enter (or stay in) the failed state; the DeviceError to raise."""
        self.errors += 1
        self._enter_failure()
        plan = self._with_last_reopen(f"retrying, zero force first, reopening every {REOPEN_INTERVAL_S:g} s")
        self._fault = f"{self.label}: failed while {what} ({why}); rendering zero force; {plan}"
        return DeviceError(self._fault)

    def _try_reopen(self) -> None:
        """Close the device and open it again; it must be the same model and serial number."""
        self._release()
        try:
            device_id = self._open_handle()
        except DeviceError as exc:
            self.last_reopen_error = str(exc)
            return
        try:
            identity = (int(self._dhd.getSystemType(device_id)), int(self._dhd.getSerialNumber(device_id)))
        except Exception as exc:
            identity = (None, str(exc))
        self._id = device_id
        if identity != self._identity:
            self._release()
            self.last_reopen_error = (f"the device opened is not the same one (type, serial {identity}, "
                                      f"expected {self._identity})")
            return
        try:
            self._start()
        except DeviceError as exc:
            self.last_reopen_error = str(exc)
            return
        self._reopened()

    def _recover(self) -> bool:
        """While failed: reopen when due, then get zero force through; True when it went."""
        self._reopen_when_due()
        try:
            self._write((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, "writing zero force")
        except DeviceError:
            return False
        self._fault = None
        return True

    # -- the Device protocol -----------------------------------------------------------------

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        with self._lock:
            self._read(t, samples)

    def _read(self, t: float, samples: list[DeviceSample]) -> None:
        self._refuse_unless_ready()
        dhd, i = self._dhd, self._id
        p, frame, angles, gap = self._p, self._frame, self._angles, self._gap
        try:
            rc = dhd.getPosition(p, i)
            if rc >= 0 and self.has_wrist:
                rc = dhd.getOrientationFrame(frame, i)
                if rc >= 0:
                    rc = dhd.getOrientationRad(angles, i)
            if rc >= 0 and self.fingers == 2:
                rc = dhd.getGripperGap(gap, i)
            buttons = dhd.getButtonMask(i) if rc >= 0 else 0
        except Exception as exc:
            raise self._fail("reading", f"{type(exc).__name__}: {exc}") from None
        if not isinstance(rc, int) or rc < 0:
            raise self._fail("reading", _last_error(dhd))
        valid = self._fill(t, samples, buttons)
        if not valid:
            self.invalid_samples += 1
        if valid:  # back: a clean sample ends a failure
            self._fresh_sample()

    def _fill(self, t: float, samples: list[DeviceSample], buttons) -> bool:
        """The samples from the readings in place; False (every sample invalid) when a reading is
        no finite number or the frame no rotation."""
        try:
            p = [float(v) for v in self._p]
            r = [[float(v) for v in row] for row in self._frame] if self.has_wrist else None
            twist = float(self._angles[2]) if self.has_wrist else 0.0
            gap = float(self._gap.value) if self.fingers == 2 else 0.0
        except (TypeError, ValueError, OverflowError, IndexError):
            p, r, twist, gap = [math.nan] * 3, None, math.nan, math.nan
        ok = all(math.isfinite(v) for v in p) and math.isfinite(twist) and math.isfinite(gap) and abs(gap) <= MAX_GAP_M
        q = (1.0, 0.0, 0.0, 0.0)
        mr = None
        if ok and r is not None:
            mr, r_e = frame_in_engine(DEVICE_TO_ENGINE, r)  # the wrist's frame seen from the engine
            q = quaternion_from_matrix(r_e)
            ok = q is not None
            q = q or (1.0, 0.0, 0.0, 0.0)
        k = self.workspace_scale
        pe = _to_engine(p) if ok else [0.0, 0.0, 0.0]
        centre = [k * pe[j] + self.workspace_offset[j] for j in range(3)]
        if ok and self.fingers == 2:
            axis = mr if r is not None else DEVICE_TO_ENGINE  # the wrist frame's axis, in engine coordinates
            self._axis_e = [axis[j][self._axis] for j in range(3)]
            self._half_gap = max(gap, 0.0) / 2.0
        tip = [k * self._half_gap * a for a in self._axis_e]
        for n, s in enumerate(samples[:self.fingers]):
            side = 0.0 if self.fingers == 1 else (-1.0 if n == 0 else 1.0)  # thumb, then index
            s.t = t
            s.x, s.y, s.z = (centre[j] + side * tip[j] for j in range(3))
            s.qw, s.qx, s.qy, s.qz = q
            s.twist = twist if ok else 0.0
            s.buttons = buttons if isinstance(buttons, int) and buttons >= 0 else 0
            s.valid = ok
        return ok

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        with self._lock:
            self._send(finger, fx, fy, fz, tx, ty, tz)

    def _send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        w = (fx, fy, fz, tx, ty, tz)
        if not self._count_send(finger, w):
            w = (0.0,) * 6  # the motors get zero
        self._wrench[finger] = [float(v) for v in w]
        if self._await_fresh:  # failed, or back without a clean sample yet: no force
            if self._fault is not None:
                raise DeviceError(self._fault)
            self._write((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, "writing zero force after a failure")
            return
        force, torque, grip = self._command()
        self._write(force, torque, grip, "sending a force")

    def _command(self):
        """The fingers' wrenches (engine frame) as the device's force, torque (device frame) and
        gripper force, each within its limit."""
        ws = self._wrench
        force = [sum(w[j] for w in ws) for j in range(3)]
        torque = [sum(w[3 + j] for w in ws) for j in range(3)]
        grip = 0.0
        if self.fingers == 2:
            a, h = self._axis_e, self._half_gap
            f0, f1 = ws[0], ws[1]
            d = [f1[j] - f0[j] for j in range(3)]
            grip = 0.5 * (d[0] * a[0] + d[1] * a[1] + d[2] * a[2])
            # moments of the fingers' forces about the end-effector: arms ∓h·a, so h·(a × (f1 - f0))
            torque = [torque[0] + h * (a[1] * d[2] - a[2] * d[1]), torque[1] + h * (a[2] * d[0] - a[0] * d[2]),
                      torque[2] + h * (a[0] * d[1] - a[1] * d[0])]
        force = _clamp_norm(_to_device(force), self.max_force)
        torque = _clamp_norm(_to_device(torque), self.max_torque) if self.max_torque > 0.0 else [0.0, 0.0, 0.0]
        g = self.max_gripper_force
        grip = g if grip > g else -g if grip < -g else grip
        if not all(math.isfinite(v) for v in (*force, *torque, grip)):
            # finite fingers can still overflow: their sum, difference or moment is inf, and a
            # clamp of inf (inf * 0) or a product with a zero axis component is NaN
            self.nan_sends += 1
            return [0.0, 0.0, 0.0], [0.0, 0.0, 0.0], 0.0
        return force, torque, grip

    def _write(self, force, torque, grip: float, what: str) -> None:
        """One SDK write of the whole command; a failure is a DeviceError (and the failed state).
        Once closed, only zero goes out (a send the close interrupted in the same thread)."""
        if self.closed and (any(force) or any(torque) or grip):
            raise DeviceError(f"{self.label}: device is closed")
        dhd, i = self._dhd, self._id
        try:
            if self.active_gripper:
                rc = dhd.setForceAndTorqueAndGripperForce(force, torque, grip, i)
            elif self.active_wrist:
                rc = dhd.setForceAndTorque(force, torque, i)
            else:
                rc = dhd.setForce(force, i)
        except Exception as exc:
            raise self._fail(what, f"{type(exc).__name__}: {exc}") from None
        if not isinstance(rc, int) or rc < 0:
            raise self._fail(what, _last_error(dhd))
        if rc == MOTOR_SATURATED:
            self.saturated += 1
        self.last_command = (tuple(force), tuple(torque), grip)
        self._last_write = time.monotonic()

    def _watch_once(self, now: float | None = None) -> None:
        """The stall watchdog's check: a non-zero command older than `stall_s` (host clock, `now`
        in tests) becomes zero force. Waits for the lock at most `stall_s`: a call stuck in the
        SDK holds it, and then nothing written from here would get through either."""
        if self.closed or not self._lock.acquire(timeout=self.stall_s):
            return
        try:
            cmd = self.last_command
            now = time.monotonic() if now is None else now
            if self.closed or cmd is None or now - self._last_write <= self.stall_s:
                return
            if not (any(cmd[0]) or any(cmd[1]) or cmd[2]):
                return
            try:
                self._write((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, "writing zero force after the loop stalled")
            except DeviceError:
                return  # failed: the next read reports it and keeps writing zero
            self.stall_zeroes += 1
        finally:
            self._lock.release()

    def close(self) -> None:
        """Zero force first, whatever happened before (up to CLOSE_ZERO_ATTEMPTS writes, the second on
        a reopened device), then forces disabled and the device closed. Never raises."""
        with self._lock:
            self._close()

    def _close(self) -> None:
        if self.closed:
            return
        self.closed = True
        _OPEN.discard(self)

        def write_zero() -> bool:
            self._write((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, "writing zero force on close")
            return True

        self._zero_on_close(write_zero)
        try:
            self._dhd.enableForce(False, self._id)
        except Exception:
            pass
        self._release()

    def __repr__(self) -> str:
        return (f"ForceDimensionDevice({self.label!r}, fingers={self.fingers}, max_force={self.max_force:g}, "
                f"max_torque={self.max_torque:g}, max_gripper_force={self.max_gripper_force:g})")

    # -- configuration -----------------------------------------------------------------------

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>", dhd=None, clock=None) -> "ForceDimensionDevice":
        """Build from a scene's [device] table; errors name the field.

            type = "forcedimension"
            index = 0                     # optional: the device at this enumeration index, else the first
            serial = 12345                # optional: the device with this serial number
            gripper = "auto"              # "auto" (two fingers when it has a gripper), "on", "off"
            gripper_axis = "y"            # the wrist frame's axis the gripper opens along
            workspace_scale = 1.0         # positions x this
            workspace_offset = [0, 0, 0]  # m, added to positions
            max_force_N = 5.0             # lower the model's limits (never raise them)
            max_torque_Nm = 0.1
            max_gripper_force_N = 3.0
            stall_ms = 50                 # a force not renewed for this long is replaced by zero (0: never)
        """
        config.check_table(cfg, source)
        table = config.check_type(cfg, source, "forcedimension")  # each field as softproxy.schema declares it
        kwargs = config.given(table, cfg, {
            "index": "index", "serial": "serial", "gripper": "gripper", "gripper_axis": "gripper_axis",
            "workspace_scale": "workspace_scale", "workspace_offset": "workspace_offset", "max_force_N": "max_force",
            "max_torque_Nm": "max_torque", "max_gripper_force_N": "max_gripper_force", "stall_ms": "stall_ms"})
        if "index" in kwargs and "serial" in kwargs:
            raise ValueError(f"{source}: device.index and device.serial both choose a device: give one")
        if isinstance(kwargs.get("gripper"), bool):
            kwargs["gripper"] = "on" if kwargs["gripper"] else "off"
        if clock is not None:
            kwargs["clock"] = clock
        return config.construct(source, cls, dhd, **kwargs)

    @classmethod
    def from_argument(cls, argument: str, scene=None, *, dhd=None, clock=None) -> "ForceDimensionDevice":
        """`--device forcedimension:key=value,...` (or `forcedimension:INDEX,...`): the keys of
        `from_config`, vectors separated by ':' (`workspace_offset=0:0:0.05`). When the scene's
        own [device] is a Force Dimension one, the argument overrides its fields."""
        source = f"--device forcedimension:{argument}"
        cfg, parts = config.argument_table(argument, scene, "forcedimension")
        if parts and "=" not in parts[0] and parts[0] not in ("first", "auto"):
            parts[0] = f"index={parts[0]}"
        config.argument_items(cfg, [p for p in parts if p not in ("first", "auto")], source, usage="key=value items",
                              strings=("gripper", "gripper_axis", "type"), integers=("index", "serial"))
        return cls.from_config(cfg, source=source, dhd=dhd, clock=clock)
