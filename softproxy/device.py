"""The device protocol: what the servo loop reads from and sends to a haptic device.

Implementations live in the `devices` package (simulated, HID, replay) and are found by
name through the `softproxy.devices` entry-point group, so the engine never imports them.
A device drives one or more fingers. Each tick the loop calls `read(t, samples)` once and
`send(finger, ...)` once per finger. A device that can also run as compiled code offers
`compiled_io()` (`softproxy.device_kernel`: its read and send as functions a compiled loop
calls itself). Everything is in the device's workspace frame, SI
units; the scene's device mapping turns it into world coordinates.
"""

from __future__ import annotations

import inspect
import math
from numbers import Integral
from typing import Protocol, runtime_checkable

from softproxy.device_guard import check_limits


class DeviceError(RuntimeError):
    """A device failed or disappeared. The servo loop answers it with zero force."""


def _scalar(v) -> float:
    """v as a float; TypeError for anything but a single real number (bool, str, arrays, None)."""
    if isinstance(v, (bool, str, bytes)) or getattr(v, "ndim", 0) != 0:
        raise TypeError(f"not a number: {v!r}")
    return float(v)


class DeviceSample:
    """One finger's reading, mutated in place each tick (no allocation in the hot path).

    All in the device's own frame, SI units; the finger's `offset` and `scale`
    (`FingerParams`) map it to the world: world = offset + scale × device.

    - `t` (s): when the device took it, on the loop's clock.
    - `x`, `y`, `z` (m): the fingertip's position.
    - `qw`, `qx`, `qy`, `qz`: the finger's orientation, a unit quaternion (w first, as
      MuJoCo writes one); devices without one leave the identity.
    - `twist` (rad): the finger's rotation about its own axis, the axis that runs from the
      fingertip back toward the hand (which is the contact normal n when the finger presses
      straight on a surface), right-handed about that axis and counted from wherever the
      device starts (the torsional proxy's α_s, *Simulating human fingers* §7).
    - `buttons`: the device's buttons, one bit each.
    - `valid`: False when the device has no fresh sample for this finger this tick; the
      finger then renders zero force and its proxy only follows the body it touches.
    """

    __slots__ = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "twist", "buttons", "valid")

    def __init__(self) -> None:
        self.t = 0.0
        self.x = self.y = self.z = 0.0
        self.qw, self.qx, self.qy, self.qz = 1.0, 0.0, 0.0, 0.0
        self.twist = 0.0
        self.buttons = 0
        self.valid = False

    def is_finite(self) -> bool:
        """True when every number in the sample is finite (no NaN/Inf from the device)."""
        return math.isfinite(self.x + self.y + self.z + self.qw + self.qx + self.qy + self.qz + self.twist)

    def usable(self) -> bool:
        """True when the sample is valid and every field a finite number. Fields that are
        numbers of another type (int, numpy scalars) are made floats in place, so what the
        engine reads is always a float; a field that is no number (None, str, an array,
        10**400, a number whose conversion raises) or a `valid` that is no single truth value
        marks the sample not valid. Never raises."""
        try:
            return self._usable()
        except Exception:
            try:
                self.valid = False
            except Exception:
                pass
            return False

    def _usable(self) -> bool:
        x, y, z, tw, qw, qx, qy, qz = self.x, self.y, self.z, self.twist, self.qw, self.qx, self.qy, self.qz
        valid = self.valid
        if not (type(x) is float and type(y) is float and type(z) is float and type(tw) is float
                and type(qw) is float and type(qx) is float and type(qy) is float and type(qz) is float):
            try:  # a device handing over ints or numpy scalars is fine; None, str, arrays, 10**400 are not
                x, y, z, tw, qw, qx, qy, qz = (_scalar(v) for v in (x, y, z, tw, qw, qx, qy, qz))
            except Exception:  # (a __float__ of the device's own may raise anything)
                self.valid = False
                return False
            self.x, self.y, self.z, self.twist, self.qw, self.qx, self.qy, self.qz = x, y, z, tw, qw, qx, qy, qz
        if valid is not True:  # 1 and numpy's True say valid too; None, str, arrays, 10**400 do not
            if not ((isinstance(valid, Integral) or (getattr(valid, "dtype", None) == bool and valid.ndim == 0))
                    and valid == 1):
                self.valid = False
                return False
            self.valid = True
        if not math.isfinite(x + y + z + tw + qw + qx + qy + qz):
            self.valid = False
            return False
        return True

    def __repr__(self) -> str:
        return (
            f"DeviceSample(t={self.t:.6f}, pos=({self.x:.6g}, {self.y:.6g}, {self.z:.6g}), "
            f"twist={self.twist:.6g}, buttons={self.buttons}, valid={self.valid})"
        )


@runtime_checkable
class Device(Protocol):
    """What the servo loop needs from a device: six members.

    - `fingers` (int ≥ 1): how many fingers the device drives.
    - `max_force` (N), `max_torque` (N·m): what it can render; every send is clamped to
      them (0: renders nothing). Read every tick, so a device may derate mid-run.
    - `read(t, samples)`: fill `samples[i]` (a `DeviceSample`, in place) for each finger
      i at loop time `t` (s). May raise `DeviceError` (that tick renders zero force); a
      sample field that is no number makes that sample invalid (counted in
      `ServoLoop.faults`).
    - `send(finger, fx, fy, fz, tx, ty, tz)`: render a force (N) and a torque (N·m) on one
      finger, along the device's axes (which are the world's: a finger's mapping is an
      offset and a scale, no rotation): the force the fingertip feels, and the torsional
      friction's torque M about the contact normal n as the vector M·n. Always called with
      finite values within both clamps; once per finger per tick.
    - `close()`: stop rendering (zero force first) and release the device; it may be
      called more than once.

    A device may also offer `compiled_io()` (`softproxy.device_kernel`), its read and send as
    compiled functions, so the loop runs blocks of ticks without Python.
    """

    fingers: int
    max_force: float
    max_torque: float

    def read(self, t: float, samples: list[DeviceSample]) -> None: ...

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None: ...

    def close(self) -> None: ...


CALLS = {"read": "t, samples", "send": "finger, fx, fy, fz, tx, ty, tz", "close": ""}
"""The positional arguments the servo loop calls each method of a device with."""


def _refuses(method, arguments: str) -> str | None:
    """The method's signature when it cannot take `arguments` positionally, else None (also
    when it has no signature Python can read: a builtin or an extension's method)."""
    try:
        signature = inspect.signature(method)
    except (TypeError, ValueError):
        return None
    try:
        signature.bind(*arguments.split(", ") if arguments else ())
    except TypeError:
        return str(signature)
    return None


def check_device(device) -> None:
    """TypeError or ValueError naming the device unless it has what `Device` asks for:
    `fingers` an integer ≥ 1, `read`, `send` and `close` callable with the arguments the loop
    passes (`CALLS`: a send of the wrong signature would fail every tick, counted but
    silent), and force and torque limits that are finite numbers
    (`softproxy.device_guard.check_limits`)."""
    name = type(device).__name__
    missing = [m for m in CALLS if not callable(getattr(device, m, None))]
    if missing:
        raise TypeError(f"device {name} is not a softproxy.Device: it has no {' or '.join(m + '()' for m in missing)}")
    for method, arguments in CALLS.items():
        signature = _refuses(getattr(device, method), arguments)
        if signature is not None:
            raise TypeError(f"device {name}: {method} must take ({arguments}), its signature is {method}{signature}")
    fingers = getattr(device, "fingers", None)
    if isinstance(fingers, bool) or not isinstance(fingers, Integral) or fingers < 1:
        raise ValueError(f"device {name}: fingers must be an integer >= 1, got {fingers!r}")
    check_limits(device)
