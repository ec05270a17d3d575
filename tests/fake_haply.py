"""A fake of the `HaplyHardwareAPI` binding (the `haplyhardwareapi` 0.1.13 wheel): the functions
and classes `devices/haply.py` calls, with the wheel's names, signatures and conventions
(tests/test_haply.py checks them against the installed wheel when it is importable).

Mirrored from the 0.1.13 wheel (a compiled pybind11 module; read with `help()` and by calling it
on a port with nothing behind it):
* `detect_inverse3s()`, `detect_handles()`, `detect_wired_handles()`, `detect_wireless_handles()`
  return lists of serial port names; `get_cpp_version()` a str;
* `SerialStream(port)` opens the port and never raises: a port that cannot be opened prints
  `[err] ... unable to open port` on the process's stderr and gives a stream every call on
  which goes unanswered;
* `Inverse3(stream, timeout=5.0)` keeps a raw pointer to `stream` (the binding does not keep it
  alive: a stream collected first crashes the process; here, a call raises RuntimeError so a
  test sees it); `set_read_timeout(t)`;
* `device_wakeup_dict()` returns {device_id, device_model_number, hardware_version,
  firmware_version, device_id_ext (a uuid.UUID)}; unanswered, the fields are whatever the
  response buffer held (arbitrary numbers) and device_id_ext the nil UUID;
* `end_effector_force(force=[0.0, 0.0, 0.0])` sends the force (N, device frame) and returns
  (position [m], velocity [m/s]) as two lists of 3 floats; unanswered, it returns two lists of
  zeros after the timeout and prints `[err] ... timeout`. It takes a list of any length and
  any float, NaN included: what reaches the motors is whatever it was handed;
* `get_power_status()` a bool (False unanswered), `get_device_id()` the device's UUID;
* `Handle(stream)` (the VerseGrip), `GetVersegripStatus()` a dict {device_id, quaternion
  [w, x, y, z], error_flag, hall_effect_sensor_level, buttons, battery_level}; unanswered
  (after about 1.4 s, no timeout to set) device_id 0, the quaternion zeros, error_flag 99.
Nothing in the binding raises on a device that fails: the answers say it.

The hardware behind it (`Inverse3Hardware`, `GripHardware`) is scriptable: position, velocity,
power, the grip's quaternion and buttons; and how it fails: `silent` (answers nothing, as a
device that hangs or lost power), `unplug()` / `plug()` (streams opened before an unplug stay
dead), `garbage` ("nan" or "none": the readings), `raise_in` (names of calls that raise, which
the real binding never does: the adapter must survive it anyway). Every force that reached an
Inverse3 is kept in its `wire`, as the binding was handed it.
"""

from __future__ import annotations

import math
import uuid
import weakref

WAKEUP_KEYS = ("device_id", "device_model_number", "hardware_version", "firmware_version", "device_id_ext")
GRIP_KEYS = ("device_id", "quaternion", "error_flag", "hall_effect_sensor_level", "buttons", "battery_level")
NO_ANSWER_FLAG = 99
"""error_flag of a VerseGrip status nobody answered (as the wheel gives it)."""


class Inverse3Hardware:
    """One Inverse3 on a serial port."""

    def __init__(self, port="/dev/ttyACM0", device_id=0x049D, serial_uuid="6f1c0d2e-58b4-4a51-9a57-0b2f7d4e3c11"):
        self.port = port
        self.device_id = device_id
        self.uuid = uuid.UUID(serial_uuid)
        self.position = [0.0, -0.12, 0.15]   # m, device frame: in front of the base, above the desk
        self.velocity = [0.0, 0.0, 0.0]      # m/s
        self.powered = True
        self.present = True
        self.silent = False
        self.generation = 0                  # +1 per unplug: streams opened before stay dead
        self.wire: list[list] = []           # every force that reached the motors, as handed over
        self.exchange_hook = None            # called with the force inside end_effector_force, before it lands


class GripHardware:
    """One wireless VerseGrip (its USB transceiver's serial port)."""

    def __init__(self, port="/dev/ttyACM1", device_id=0x2A):
        self.port = port
        self.device_id = device_id
        self.quaternion = [1.0, 0.0, 0.0, 0.0]  # w, x, y, z
        self.buttons = 0
        self.battery_level = 0.9
        self.present = True
        self.silent = False
        self.generation = 0


class FakeHaply:
    """The `HaplyHardwareAPI` module over a list of devices: `.SerialStream`, `.Inverse3`,
    `.Handle`, `.UUID`, the `detect_*` functions (see the module docstring)."""

    __version__ = "0.1.13"

    def __init__(self, *devices, grips=()):
        self.devices = list(devices) if devices else [Inverse3Hardware()]
        self.grips = list(grips)
        self.garbage = None            # None, "nan" or "none": what the readings become
        self.raise_in: set[str] = set()
        self.calls: list[str] = []
        self.printed: list[str] = []   # what the binding would print on stderr
        self.streams_opened = 0
        bus = self
        # the classes as the module has them, bound to this bus
        self.SerialStream = type("SerialStream", (SerialStream,), {"bus": bus})
        self.Inverse3 = type("Inverse3", (Inverse3,), {"bus": bus})
        self.Handle = type("Handle", (Handle,), {"bus": bus})
        self.UUID = UUID

    # -- fault machinery ------------------------------------------------------------------------

    def unplug(self, hw) -> None:
        hw.present = False
        hw.generation += 1

    def plug(self, hw) -> None:
        hw.present = True

    def _enter(self, name: str) -> None:
        self.calls.append(name)
        if name in self.raise_in:
            raise RuntimeError(f"{name}: serial I/O error")

    def _value(self, v):
        return {None: v, "nan": math.nan, "none": None}[self.garbage]

    # -- module functions -----------------------------------------------------------------------

    def detect_inverse3s(self) -> list:
        self._enter("detect_inverse3s")
        return [hw.port for hw in self.devices if hw.present]

    def detect_handles(self) -> list:
        self._enter("detect_handles")
        return [g.port for g in self.grips if g.present]

    def detect_wired_handles(self) -> list:
        self._enter("detect_wired_handles")
        return []

    def detect_wireless_handles(self) -> list:
        self._enter("detect_wireless_handles")
        return [g.port for g in self.grips if g.present]

    def get_cpp_version(self) -> str:
        return "0.2.8"

    def print_cpp_version(self) -> None:
        self.printed.append("0.2.8")


class UUID:
    """The binding's UUID class (what `get_device_id` hands out is a uuid.UUID-like object)."""

    def __init__(self) -> None:
        self._bytes = [0] * 16

    def bytes(self) -> list:
        return list(self._bytes)


class SerialStream:
    """A serial port; a port without a present device behind it gives a dead stream."""

    bus: FakeHaply

    def __init__(self, arg0: str) -> None:
        bus = self.bus
        bus._enter("SerialStream")
        bus.streams_opened += 1
        self.port = arg0
        self.target = next((d for d in (*bus.devices, *bus.grips) if d.port == arg0 and d.present), None)
        self.generation = self.target.generation if self.target is not None else -1
        if self.target is None:
            bus.printed.append(f"[err] unable to open port '{arg0}'")

    def _alive(self):
        """The device behind it when it answers, else None."""
        t = self.target
        if t is None or not t.present or t.generation != self.generation or t.silent:
            return None
        return t


class Inverse3:
    """The Inverse3 over a SerialStream (held by a raw pointer, as the binding does)."""

    bus: FakeHaply

    def __init__(self, stream, timeout: float = 5.0) -> None:
        self.bus._enter("Inverse3")
        self._stream = weakref.ref(stream)  # the binding keeps no reference either
        self.timeout = float(timeout)

    def _device(self, name: str):
        self.bus._enter(name)
        stream = self._stream()
        if stream is None:
            raise RuntimeError("the SerialStream was collected before its Inverse3 (the real binding crashes)")
        hw = stream._alive()
        if hw is None:
            self.bus.printed.append(f"[err] {name}: timeout waiting for header code")
        return hw

    def set_read_timeout(self, t: float) -> None:
        self.bus._enter("set_read_timeout")
        self.timeout = float(t)

    def device_wakeup_dict(self) -> dict:
        hw = self._device("device_wakeup_dict")
        if hw is None:  # the response buffer as it was: arbitrary numbers, the nil UUID
            return {"device_id": 7, "device_model_number": 90, "hardware_version": 185, "firmware_version": 89,
                    "device_id_ext": uuid.UUID(int=0)}
        return {"device_id": hw.device_id, "device_model_number": 1, "hardware_version": 3, "firmware_version": 7,
                "device_id_ext": hw.uuid}

    def end_effector_force(self, force: list = [0.0, 0.0, 0.0]) -> tuple:  # noqa: B006 (the binding's default)
        hw = self._device("end_effector_force")
        if hw is None:
            return [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
        if hw.exchange_hook is not None:
            hw.exchange_hook(force)
        hw.wire.append(list(force))
        v = self.bus._value
        return [v(c) for c in hw.position], [v(c) for c in hw.velocity]

    def get_power_status(self) -> bool:
        hw = self._device("get_power_status")
        return False if hw is None else bool(hw.powered)

    def get_device_id(self) -> object:
        hw = self._device("get_device_id")
        return uuid.UUID(int=0) if hw is None else hw.uuid


class Handle:
    """The VerseGrip over a SerialStream (held by a raw pointer, as the binding does)."""

    bus: FakeHaply

    def __init__(self, arg0) -> None:
        self.bus._enter("Handle")
        self._stream = weakref.ref(arg0)

    def GetVersegripStatus(self) -> dict:
        self.bus._enter("GetVersegripStatus")
        stream = self._stream()
        if stream is None:
            raise RuntimeError("the SerialStream was collected before its Handle (the real binding crashes)")
        g = stream._alive()
        if g is None:
            return {"device_id": 0, "quaternion": [0.0, 0.0, 0.0, 0.0], "error_flag": NO_ANSWER_FLAG,
                    "hall_effect_sensor_level": 0, "buttons": 0, "battery_level": 0.0}
        v = self.bus._value
        return {"device_id": g.device_id, "quaternion": [v(c) for c in g.quaternion], "error_flag": 0,
                "hall_effect_sensor_level": 0, "buttons": g.buttons, "battery_level": g.battery_level}
