"""The device protocol: what the servo loop reads from and sends to a haptic device.

Implementations live in the `devices` package (simulated, HID, replay) and are found by
name through the `softproxy.devices` entry-point group, so the engine never imports them.
A device drives one or more fingers. Each tick the loop calls `read(t, samples)` once and
`send(finger, ...)` once per finger. Everything is in the device's workspace frame, SI
units; the scene's device mapping turns it into world coordinates.
"""

from __future__ import annotations

import math
from typing import Protocol, runtime_checkable


class DeviceError(RuntimeError):
    """A device failed or disappeared. The servo loop answers it with zero force."""


class DeviceSample:
    """One finger's reading, mutated in place each tick (no allocation in the hot path).

    position: x, y, z (m); orientation: unit quaternion qw, qx, qy, qz of the finger;
    twist: rotation of the finger about its own axis (rad), the α_s of seed 002 §7;
    buttons: bit field; valid: False when the device has no fresh sample this tick.
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

    def copy_from(self, other: "DeviceSample") -> None:
        for name in DeviceSample.__slots__:
            setattr(self, name, getattr(other, name))

    def __repr__(self) -> str:
        return (
            f"DeviceSample(t={self.t:.6f}, pos=({self.x:.6g}, {self.y:.6g}, {self.z:.6g}), "
            f"twist={self.twist:.6g}, buttons={self.buttons}, valid={self.valid})"
        )


@runtime_checkable
class Device(Protocol):
    """What the servo loop needs from a device.

    `fingers`: how many fingers the device drives. `max_force` (N) and `max_torque` (N·m)
    are what it can render; the loop clamps to them (0 = renders nothing).
    `read` fills one sample per finger for time `t` (s, the loop's clock) and may raise
    DeviceError. `send` renders a force (N) and a torque (N·m) on one finger, both in the
    device frame; it is always called with finite values within the clamps.
    """

    fingers: int
    max_force: float
    max_torque: float

    def read(self, t: float, samples: list[DeviceSample]) -> None: ...

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None: ...

    def close(self) -> None: ...
