"""A fake of `forcedimension_core.dhd` (forcedimension-core 1.0.0, DHD SDK 3.16): the functions
`devices/forcedimension.py` calls, with the binding's names, signatures and return conventions.

Mirrored from forcedimension_core/dhd/__init__.py of the 1.0.0 wheel:
* open() / openID(index) / openSerial(serial) return the device ID (>= 0) or -1;
  close(ID=-1), enableForce(enable, ID=-1), setMax*(limit, ID=-1), stop(ID=-1) return 0 or -1;
* getPosition(out, ID=-1), getOrientationRad(out, ID=-1) write out[0..2] and
  getOrientationFrame(out, ID=-1) out[i][j] (always, as the binding copies the C values out
  whatever the return code: zeros on failure), returning 0 or TIMEGUARD (1) on success and -1
  on failure;
* the set* commands' values go through c_double argtypes: an int or float each, anything else
  (a numpy float32, None, a string) is a ctypes.ArgumentError;
* getGripperGap(out, ID=-1) writes a `ctypes.c_double` (anything else is a ctypes.ArgumentError,
  as ctypes raises for the real argtypes);
* setForce(f, ID=-1), setForceAndTorque(f, t, ID=-1), setForceAndTorqueAndGripperForce(f, t, fg,
  ID=-1) return 0 or MOTOR_SATURATED (2) on success, -1 otherwise;
* getSystemType(ID=-1) returns the DeviceType (an int enum) and raises ValueError on failure
  (the binding wraps -1 in DeviceType(), which is no member) and for a type id the enum lacks
  (a model newer than the binding); getSystemName(ID=-1) a str or None;
  getSerialNumber(ID=-1) an int or -1; getButtonMask(ID=-1) an int; has*(ID=-1) bools;
  getMax*(ID=-1) the limit set or -1.0 when none; getDeviceCount() a count or -1;
* errorGetLast() the last ErrorNum, errorGetLastStr() its text; ID=-1 is the default device
  (the last opened).

The hardware behind it (`Hardware`) is scriptable: its pose, wrist, gripper gap, buttons; and
how it fails: `fail` (names of functions that return -1 with ErrorNum.COM, "communication
error"), `raise_in` (names of functions that raise OSError), `unplug()` / `plug()` (every call
on an ID opened before the unplug fails for good; opening works again after plug), and
`garbage` (readings replaced by NaN or None). Every command that reached the device is kept in
`wire` as (force, torque, gripper force) in the device frame, after the SDK's own limits.
"""

from __future__ import annotations

import ctypes
import math

TIMEGUARD, MOTOR_SATURATED = 1, 2
NO_ERROR, COM, NO_DEVICE_FOUND, INVALID_INDEX = 0, 2, 5, 15
ERROR_TEXT = {NO_ERROR: "no error", COM: "communication error", NO_DEVICE_FOUND: "no device found",
              INVALID_INDEX: "invalid index"}

OMEGA3, OMEGA7_RIGHT, SIGMA7_RIGHT, FALCON = 33, 35, 104, 60
DEVICE_TYPES = {0, 63, 33, 34, 36, 35, 37, 81, 82, 91, 206, 104, 105, 203, 108, 109, 60}
"""forcedimension_core.constants.DeviceType's values (1.0.0)."""
MODELS = {  # type: (name, wrist, active wrist, gripper, active gripper)
    OMEGA3: ("omega.3", False, False, False, False),
    OMEGA7_RIGHT: ("omega.7", True, False, True, True),
    SIGMA7_RIGHT: ("sigma.7", True, True, True, True),
    FALCON: ("Falcon", False, False, False, False),
}


class Hardware:
    """One device on the USB bus."""

    def __init__(self, kind=OMEGA7_RIGHT, serial=1234, max_force=12.0):
        self.kind, self.serial = kind, serial
        self.rated_force = max_force  # what the motors can do; a command past it saturates
        self.position = [0.0, 0.0, 0.0]
        self.frame = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
        self.angles = [0.0, 0.0, 0.0]
        self.gap = 0.03
        self.buttons = 0
        self.present = True
        self.generation = 0  # +1 per unplug: IDs opened before stay dead
        self.force_enabled = False
        self.wire: list[tuple] = []
        self.limits = {"force": -1.0, "torque": -1.0, "gripper": -1.0}
        self.command_hook = None  # called inside a set* command, before it reaches the device


class FakeDHD:
    """The `dhd` module's functions over a list of `Hardware` (see the module docstring)."""

    def __init__(self, *hardware: Hardware):
        self.hardware = list(hardware) or [Hardware()]
        self.handles: dict[int, tuple[Hardware, int]] = {}  # ID -> (device, generation when opened)
        self.default_id = -1
        self.next_id = 0
        self.last_error = NO_ERROR
        self.fail: set[str] = set()
        self.raise_in: set[str] = set()
        self.garbage = None  # None, "nan" or "none": what the readings become
        self.calls: list[str] = []
        self.closed_ids: list[int] = []

    # -- fault machinery ------------------------------------------------------------------------

    def unplug(self, n=0):
        hw = self.hardware[n]
        hw.present = False
        hw.generation += 1

    def plug(self, n=0):
        self.hardware[n].present = True

    def _enter(self, name: str, ID: int):
        """The device an ID names, or None (and the last error set) when the call fails."""
        self.calls.append(name)
        if name in self.raise_in:
            raise OSError(f"{name}: libusb I/O error")
        if name in self.fail:
            self.last_error = COM
            return None
        i = self.default_id if ID == -1 else ID
        if i not in self.handles:
            self.last_error = INVALID_INDEX
            return None
        hw, generation = self.handles[i]
        if not hw.present or generation != hw.generation:
            self.last_error = COM
            return None
        self.last_error = NO_ERROR
        return hw

    def _value(self, v):
        return {None: v, "nan": math.nan, "none": None}[self.garbage]

    # -- errors ---------------------------------------------------------------------------------

    def errorGetLast(self) -> int:
        return self.last_error

    def errorGetLastStr(self) -> str:
        return ERROR_TEXT.get(self.last_error, "error")

    def getSDKVersion(self):
        return (3, 17, 1, 0)

    # -- opening --------------------------------------------------------------------------------

    def getDeviceCount(self) -> int:
        self.calls.append("getDeviceCount")
        if "getDeviceCount" in self.fail:
            self.last_error = COM
            return -1
        return sum(1 for hw in self.hardware if hw.present)

    def _open_hw(self, hw) -> int:
        if hw is None or not hw.present:
            self.last_error = NO_DEVICE_FOUND
            return -1
        device_id = self.next_id
        self.next_id += 1
        self.handles[device_id] = (hw, hw.generation)
        self.default_id = device_id
        self.last_error = NO_ERROR
        return device_id

    def open(self) -> int:
        self.calls.append("open")
        if "open" in self.fail:
            self.last_error = COM
            return -1
        present = [hw for hw in self.hardware if hw.present]
        return self._open_hw(present[0] if present else None)

    def openID(self, index: int) -> int:
        self.calls.append("openID")
        present = [hw for hw in self.hardware if hw.present]
        if not 0 <= index < len(present):
            self.last_error = INVALID_INDEX
            return -1
        return self._open_hw(present[index])

    def openSerial(self, serial: int) -> int:
        self.calls.append("openSerial")
        return self._open_hw(next((hw for hw in self.hardware if hw.present and hw.serial == serial), None))

    def close(self, ID: int = -1) -> int:
        self.calls.append("close")
        i = self.default_id if ID == -1 else ID
        if i not in self.handles:
            self.last_error = INVALID_INDEX
            return -1
        hw, _ = self.handles.pop(i)
        self.closed_ids.append(i)
        return 0

    # -- what the device is ---------------------------------------------------------------------

    def getSystemType(self, ID: int = -1):
        hw = self._enter("getSystemType", ID)
        if hw is None:
            raise ValueError("-1 is not a valid DeviceType")  # DeviceType(-1) in the binding
        if hw.kind not in DEVICE_TYPES:
            raise ValueError(f"{hw.kind} is not a valid DeviceType")
        return hw.kind

    def getSystemName(self, ID: int = -1):
        hw = self._enter("getSystemName", ID)
        return None if hw is None else MODELS.get(hw.kind, ("unknown",))[0]

    def getSerialNumber(self, ID: int = -1) -> int:
        hw = self._enter("getSerialNumber", ID)
        return -1 if hw is None else hw.serial

    def _has(self, name, ID, column) -> bool:
        hw = self._enter(name, ID)
        return False if hw is None else MODELS[hw.kind][column]

    def hasWrist(self, ID: int = -1) -> bool:
        return self._has("hasWrist", ID, 1)

    def hasActiveWrist(self, ID: int = -1) -> bool:
        return self._has("hasActiveWrist", ID, 2)

    def hasGripper(self, ID: int = -1) -> bool:
        return self._has("hasGripper", ID, 3)

    def hasActiveGripper(self, ID: int = -1) -> bool:
        return self._has("hasActiveGripper", ID, 4)

    # -- limits and force mode ------------------------------------------------------------------

    def _set_limit(self, name, key, limit, ID) -> int:
        hw = self._enter(name, ID)
        if hw is None:
            return -1
        hw.limits[key] = float(limit)
        return 0

    def setMaxForce(self, limit: float, ID: int = -1) -> int:
        return self._set_limit("setMaxForce", "force", limit, ID)

    def setMaxTorque(self, limit: float, ID: int = -1) -> int:
        return self._set_limit("setMaxTorque", "torque", limit, ID)

    def setMaxGripperForce(self, limit: float, ID: int = -1) -> int:
        return self._set_limit("setMaxGripperForce", "gripper", limit, ID)

    def getMaxForce(self, ID: int = -1) -> float:
        hw = self._enter("getMaxForce", ID)
        return -1.0 if hw is None else hw.limits["force"]

    def getMaxTorque(self, ID: int = -1) -> float:
        hw = self._enter("getMaxTorque", ID)
        return -1.0 if hw is None else hw.limits["torque"]

    def getMaxGripperForce(self, ID: int = -1) -> float:
        hw = self._enter("getMaxGripperForce", ID)
        return -1.0 if hw is None else hw.limits["gripper"]

    def enableForce(self, enable: bool, ID: int = -1) -> int:
        hw = self._enter("enableForce", ID)
        if hw is None:
            return -1
        hw.force_enabled = bool(enable)
        return 0

    def stop(self, ID: int = -1) -> int:
        return self.enableForce(False, ID)

    # -- readings -------------------------------------------------------------------------------

    def getPosition(self, out, ID: int = -1) -> int:
        hw = self._enter("getPosition", ID)
        for j in range(3):  # the binding copies the C values out whatever the return code
            out[j] = self._value(hw.position[j]) if hw is not None else 0.0
        return -1 if hw is None else 0

    def getOrientationRad(self, out, ID: int = -1) -> int:
        hw = self._enter("getOrientationRad", ID)
        for j in range(3):
            out[j] = self._value(hw.angles[j]) if hw is not None else 0.0
        return -1 if hw is None else 0

    def getOrientationFrame(self, out, ID: int = -1) -> int:
        hw = self._enter("getOrientationFrame", ID)
        for i in range(3):
            for j in range(3):
                out[i][j] = self._value(hw.frame[i][j]) if hw is not None else 0.0  # the binding's zeroed buffer
        return -1 if hw is None else TIMEGUARD

    def getGripperGap(self, out, ID: int = -1) -> int:
        if not isinstance(out, ctypes.c_double):
            raise ctypes.ArgumentError("argument 1: TypeError: expected LP_c_double instance")
        hw = self._enter("getGripperGap", ID)
        if hw is None:
            return -1
        v = self._value(hw.gap)
        out.value = math.nan if v is None else v
        return 0

    def getButtonMask(self, ID: int = -1) -> int:
        hw = self._enter("getButtonMask", ID)
        return 0 if hw is None else hw.buttons

    # -- commands -------------------------------------------------------------------------------

    def _command(self, name, f, t, fg, ID) -> int:
        hw = self._enter(name, ID)
        if hw is None:
            return -1
        if hw.command_hook is not None:
            hw.command_hook(f, t, fg)
        for v in (f[0], f[1], f[2], t[0], t[1], t[2], fg):  # the argtypes are c_double: ctypes takes int/float only
            if not isinstance(v, (int, float)):
                raise ctypes.ArgumentError(f"argument: TypeError: wrong type {type(v).__name__}")
        f = [float(f[0]), float(f[1]), float(f[2])]
        t = [float(t[0]), float(t[1]), float(t[2])]
        rc = 0
        for vec, key in ((f, "force"), (t, "torque")):  # the SDK's own limits (negative: none)
            n = math.sqrt(sum(c * c for c in vec))
            lim = hw.limits[key]
            if lim >= 0.0 and n > lim:
                vec[:] = [c * lim / n for c in vec]
        if hw.limits["gripper"] >= 0.0:
            fg = max(-hw.limits["gripper"], min(hw.limits["gripper"], float(fg)))
        if math.sqrt(sum(c * c for c in f)) > hw.rated_force:
            rc = MOTOR_SATURATED
        hw.wire.append((tuple(f), tuple(t), float(fg), hw.force_enabled))
        return rc

    def setForce(self, f, ID: int = -1) -> int:
        return self._command("setForce", f, (0.0, 0.0, 0.0), 0.0, ID)

    def setForceAndTorque(self, f, t, ID: int = -1) -> int:
        return self._command("setForceAndTorque", f, t, 0.0, ID)

    def setForceAndTorqueAndGripperForce(self, f, t, fg: float, ID: int = -1) -> int:
        return self._command("setForceAndTorqueAndGripperForce", f, t, fg, ID)
