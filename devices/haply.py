"""Haply Inverse3 (with a wireless VerseGrip) through the `HaplyHardwareAPI` binding.

`HaplyDevice` implements `softproxy.device.Device` for one finger over the binding of the
`haplyhardwareapi` wheel (`pip install 'softproxy[haply]'`; a compiled wheel with its own
serial driver, no vendor service or SDK to install). The binding is imported only when a
device is opened; tests hand in a fake (`binding=`, tests/fake_haply.py).

Calls used (0.1.13): `detect_inverse3s()`, `detect_handles()` (ports); `SerialStream(port)`;
`Inverse3(stream, timeout)`, its `device_wakeup_dict()`, `set_read_timeout(s)`,
`end_effector_force([fx, fy, fz])` -> (position, velocity) and `get_power_status()`;
`Handle(stream)` and its `GetVersegripStatus()` -> {device_id, quaternion [w, x, y, z],
error_flag, buttons, ...}. What the wheel does, found by calling it (a compiled module with
no stubs; docs/devices.md): nothing raises when the device fails - a port that cannot be
opened, a call not answered within the timeout, print a line on the process's stderr and
return zeros (two zero vectors from `end_effector_force`, error_flag 99 and a zero quaternion
from `GetVersegripStatus`, arbitrary numbers from `device_wakeup_dict`); `Inverse3` and
`Handle` keep a raw pointer to their stream, which must outlive them (this adapter holds
each pair together and drops them together); calls release the interpreter lock;
`end_effector_force` takes any list, NaN included, and hands it to the motors.

Servo model: polled, as Force Dimension's. The Inverse3 answers every force it is sent with its
position and velocity (Haply: "force in newtons (N), and returns its position in meters (m) and
velocity in meters per second (m/s)", docs.haply.co, Developing with Inverse3): `read` sends
the current command again and takes the answer; `send` sends the new force - two exchanges a
tick. An exchange answered by two zero vectors was not answered (the end-effector cannot sit
at the origin, on the base's mounting plate). The serial timeout is `timeout_ms` (20 ms;
opening waits OPEN_TIMEOUT_S for the wake-up), so a device that stops answering costs one
tick that long, not the binding's default 5 s.

The VerseGrip answers only when asked and its call blocks until it does (about 1.4 s when it
does not; it has no timeout to set), so it is read by a thread of its own into a latest-value
slot, one tuple replaced by one assignment, as the OpenHaptics adapter does; `read` takes the
newest. A grip reading older than `grip_stale_ms` (100 ms) makes the sample invalid (zero
force): the finger's frame would be a stale one. A status with an error flag, a quaternion
that is no unit quaternion, or another grip's device id is dropped (counted in
`grip_errors`); after REOPEN_INTERVAL_S of such, the thread opens the grip's port again.
`grip = "auto"` uses the first VerseGrip `detect_handles()` finds (none: position only, the
identity frame), `"off"` none, a port that one. The wired VerseGrip (Quill), which speaks
another protocol (RequestStatus / Receive with callbacks), is not supported.

Frames and units. The Inverse3 reports metres, m/s and takes newtons in a right-handed frame
whose origin is on the flat face of the base's mounting plate (docs.haply.co, Developing with
Inverse3): z up (Haply's wall sample pushes +z below a plane), y away from the operator, x to
the operator's right (Haply's samples place the cursor at y < 0, between the base and the
operator). That is the engine's frame already (z up, the operator looking along +y):
DEVICE_TO_ENGINE is the identity, kept as a constant so that the mapping is written once.
Positions are scaled by `workspace_scale` and offset by `workspace_offset` (m) as the other
adapters do; the VerseGrip's quaternion (w, x, y, z, reference pose the identity) is the
finger's frame; the twist is its rotation about the grip's `twist_axis` (swing-twist
decomposition), unwrapped across samples and counted from the first; its buttons pass
through. The Inverse3 renders force only: `max_torque` is 0, torques are dropped. The
velocity of the last valid sample (engine frame, scaled, m/s) is kept in `velocity`.

Limits. The binding reports no force limit of the device, and Haply's published force
figures could not be consulted when this adapter was written: `max_force` defaults to
DEFAULT_MAX_FORCE_N (2 N, the force limit Isaac Lab's Inverse3 adapter applies by default,
isaaclab/devices/haply/se3_haply.py `limit_force = 2.0`) and may be set up to
FORCE_CEILING_N (3.3 N, the "Inverse3 continuous force limit per axis" a published Inverse3
driver uses); replace both by Haply's datasheet figures when they are at hand. A reading
farther than MAX_REACH_M from the origin is no reading of this arm (the wheel's own default
link lengths, `Inverse3.adjust_lengths`, 0.14 + 0.165 m arms and a 0.0765 m extension, reach
0.38 m) and makes the sample invalid. Every command is finite and within `max_force`.

Stalls. A non-zero command not renewed by `send` for `stall_ms` (50 ms) is replaced by zero
force by a watchdog thread (`stall_zeroes`), as the Force Dimension adapter does: what the
Inverse3's firmware does with its last force when commands stop is not documented.

Failure and recovery. An exchange not answered, or a call that raises, is a failure: that read
or send raises DeviceError naming the device, one zero force is tried on the link, and the
link is dropped; from then on nothing but zero force goes out. Every REOPEN_INTERVAL_S of its
clock the device is opened again - port detected again unless given, wake-up, a zero-force
exchange that must be answered - and must be the same Inverse3 (device id and UUID from the
wake-up) as before; samples are invalid until one reads clean, and forces render again after
it (`recoveries`). `close()` tries zero force (CLOSE_ZERO_ATTEMPTS exchanges, the second on a
reopened device), stops the grip's thread and drops the links; it never raises. `read`,
`send`, the watchdog and `close` take one lock, so a close from another thread cannot let a
command land after its zero, and once closed only zero is ever written. A device left open
is closed at interpreter exit (`atexit`).

Configuration: `from_config` takes a scene's [device] table (`type = "haply"`), `from_argument`
serves `--device haply[:PORT|INDEX][,key=value...]`. `availability()` says what
`softproxy devices` prints (the Inverse3s and VerseGrips detected, by port).
"""

from __future__ import annotations

import importlib
import math
import os
import threading
import time
import weakref

from softproxy.device import DeviceError, DeviceSample

from . import device_config as config
from .lifecycle import DeviceLifecycle, OpenDevices, start_stall_watchdog
from .recovery import CLOSE_ZERO_ATTEMPTS, REOPEN_INTERVAL_S, FaultRecovery  # noqa: F401 (this adapter's constants too)
from .vendor_binding import availability_row, missing_binding

NAME = "Haply"
INSTALL_HINT = "pip install 'softproxy[haply]'"
PORT_HINT = ("is it plugged in and powered, and is its serial port readable by you (a udev rule or the "
             "dialout group, docs/devices.md)? `softproxy devices` lists the ports found")
STALL_MS = 50.0
"""Default of `stall_ms`: a non-zero command not renewed for this long (ms) is replaced by zero force."""
TIMEOUT_MS = 20.0
"""Default of `timeout_ms`: a serial exchange not answered in this long (ms) is a failure."""
OPEN_TIMEOUT_S = 1.0
"""The serial timeout while the Inverse3 wakes up (s), before `timeout_ms` applies."""
GRIP_STALE_MS = 100.0
"""Default of `grip_stale_ms`: a VerseGrip reading older than this (ms) makes the sample invalid."""
DEFAULT_MAX_FORCE_N = 2.0
"""Default force limit (N): Isaac Lab's Inverse3 adapter's default `limit_force` (see the module docstring)."""
MAX_STIFFNESS_N_PER_M = 1000.0
MAX_DAMPING_NS_PER_M = 5.0
"""The stiffest coupling (N/m) and most damping (N·s/m) a finger may ask of an Inverse3
(`softproxy.stiffness_cap`). Neither the binding nor a Haply figure at hand gives them, and
CHAI3D's tables have no Inverse3: these are CHAI3D's figures for the PHANTOM Desktop
(src/devices/CPhantomDevices.cpp), a desktop impedance arm of like reach and force, between
the Touch's 400 N/m and the Falcon's 3000 N/m; replace them by Haply's when published."""
FORCE_CEILING_N = 3.3
"""Highest `max_force` accepted (N): a published Inverse3 driver's continuous force limit (see the module docstring)."""
MAX_REACH_M = 0.5
"""A position farther than this from the device's origin (m) is no reading of the arm (its reach is 0.38 m)."""
DEVICE_TO_ENGINE = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))
"""Rows: the engine's x, y, z in the Inverse3's frame (x right, y away from the operator, z up)."""
_ZERO = (0.0, 0.0, 0.0)
_AXES = {"x": 0, "y": 1, "z": 2}

_OPEN = OpenDevices()
"""Devices opened and not closed yet: closed (zero force, links dropped) at interpreter exit."""


# --- the binding ---------------------------------------------------------------------------------

def load_binding():
    """The `HaplyHardwareAPI` module, or DeviceError (one line) naming what to install."""
    try:
        return importlib.import_module("HaplyHardwareAPI")
    except ModuleNotFoundError as exc:
        raise missing_binding(exc, "HaplyHardwareAPI", NAME, INSTALL_HINT) from None
    except (ImportError, OSError) as exc:  # a wheel for another platform or Python
        raise DeviceError(f"the {NAME} binding cannot load ({type(exc).__name__}: {exc}): the haplyhardwareapi "
                          f"wheel is built for CPython 3.11 on Linux x86-64; {INSTALL_HINT}") from None


def _ports(fn) -> list[str]:
    """A detect_* function's ports (strings); [] when it fails."""
    try:
        return [p for p in fn() if isinstance(p, str) and p]
    except Exception:
        return []


def availability(binding=None) -> dict:
    """What `softproxy devices` reports: binding installed, the Inverse3s and VerseGrips detected
    by port (never raises). The wheel needs no SDK: `sdk` is True once it imports."""
    row, binding = availability_row("haply", binding, load_binding)
    if binding is None:
        return row
    arms, grips = _ports(binding.detect_inverse3s), _ports(binding.detect_handles)
    row["devices"] = len(arms)
    row["ports"] = {"inverse3": arms, "versegrip": grips}
    row["message"] = (f"{len(arms)} Inverse3 ({', '.join(arms) or 'none'}), {len(grips)} VerseGrip "
                      f"({', '.join(grips) or 'none'})" + ("" if arms else "; check the USB cable, power and udev rule"))
    return row


def _grip_reader(ref) -> None:
    """The VerseGrip's thread: read it again and again into the slot until the device is closed or gone."""
    while True:
        device = ref()
        if device is None or device.closed:
            return
        try:
            good = device._grip_once()
        except Exception:
            good = False
        del device
        if not good:
            time.sleep(0.005)  # a grip that fails at once must not spin this thread


def _three(v) -> list | None:
    """3 finite floats from a binding's answer, else None."""
    try:
        out = [float(v[0]), float(v[1]), float(v[2])]
    except (TypeError, ValueError, OverflowError, IndexError, KeyError):
        return None
    return out if len(v) == 3 and all(math.isfinite(c) for c in out) else None


def _unit_quaternion(q) -> tuple | None:
    """(w, x, y, z) normalised, from a VerseGrip's 4 numbers; None unless they are finite and of
    norm within 10 % of 1 (zeros are the binding's unanswered status)."""
    try:
        w, x, y, z = (float(c) for c in q)
    except (TypeError, ValueError, OverflowError):
        return None
    n = math.sqrt(w * w + x * x + y * y + z * z)
    if not (math.isfinite(n) and 0.9 <= n <= 1.1):
        return None
    return (w / n, x / n, y / n, z / n)


def _wrap(a: float) -> float:
    """`a` (rad) within (-pi, pi]."""
    return a - 2.0 * math.pi * math.ceil((a - math.pi) / (2.0 * math.pi))


class HaplyDevice(DeviceLifecycle, FaultRecovery):
    """One Haply Inverse3, with a VerseGrip when there is one: one finger, 3-DOF force (see the module docstring)."""

    fingers = 1
    max_torque = 0.0
    STATS = ("sends", "nan_sends", "invalid_samples", "failures", "errors", "reopens", "recoveries", "stall_zeroes",
             "grip_stale_samples", "grip_errors", "grip_reopens")

    def __init__(self, binding=None, *, port: str | None = None, index: int | None = None, grip: str = "auto",
                 twist_axis: str = "z", workspace_scale: float = 1.0, workspace_offset=(0.0, 0.0, 0.0),
                 max_force: float | None = None, stall_ms: float = STALL_MS, timeout_ms: float = TIMEOUT_MS,
                 grip_stale_ms: float = GRIP_STALE_MS, clock=time.monotonic, start_threads: bool = True,
                 label: str | None = None) -> None:
        """Open the Inverse3 on `port`, or the one detected at `index`, or the first detected.
        `binding`: the HaplyHardwareAPI module (a fake in tests); None loads it. `start_threads`
        False leaves the watchdog's and the grip's checks to the caller (`_watch_once`,
        `_grip_once`: tests drive them)."""
        if port is not None and (not isinstance(port, str) or not port.strip()):
            raise ValueError(f"port must be a serial port name, got {port!r}")
        if index is not None and (isinstance(index, bool) or not isinstance(index, int) or index < 0):
            raise ValueError(f"index must be an integer >= 0, got {index!r}")
        if not isinstance(grip, str) or not grip.strip():
            raise ValueError(f"grip must be \"auto\", \"off\" or a serial port, got {grip!r}")
        if twist_axis not in _AXES:
            raise ValueError(f"twist_axis must be \"x\", \"y\" or \"z\" (the VerseGrip's axis), got {twist_axis!r}")
        scale, offset = config.check_workspace(workspace_scale, workspace_offset)
        if not (config.finite(stall_ms) and 0 <= stall_ms <= 1000):
            raise ValueError(f"stall_ms must be a number of milliseconds in [0, 1000] (0: no watchdog), got {stall_ms!r}")
        for name, v, high in (("timeout_ms", timeout_ms, 1000), ("grip_stale_ms", grip_stale_ms, 5000)):
            if not (config.finite(v) and 0 < v <= high):
                raise ValueError(f"{name} must be a number of milliseconds in (0, {high}], got {v!r}")
        if max_force is not None and not (config.finite(max_force) and 0.0 <= max_force <= FORCE_CEILING_N):
            raise ValueError(f"max_force must be a finite number in [0, {FORCE_CEILING_N:g}] (the Inverse3's limit), "
                             f"got {max_force!r}")
        self._api = load_binding() if binding is None else binding
        self.port_wanted, self.index = (port.strip() if port else None), index
        self.workspace_scale, self.workspace_offset = scale, offset
        self.max_force = float(DEFAULT_MAX_FORCE_N if max_force is None else max_force)
        self.max_stiffness, self.max_damping = MAX_STIFFNESS_N_PER_M, MAX_DAMPING_NS_PER_M
        self.stall_s = stall_ms / 1000.0
        self.timeout_s = timeout_ms / 1000.0
        self.grip_stale_s = grip_stale_ms / 1000.0
        self._twist_axis = _AXES[twist_axis]
        self._init_recovery(clock)
        self.closed = False
        # read/send/close and the watchdog from different threads: one at a time, so no command
        # can land between close()'s zero and the links being dropped
        self._lock = threading.RLock()
        self.sends = self.nan_sends = self.invalid_samples = self.errors = self.stall_zeroes = 0
        self.grip_stale_samples = self.grip_errors = self.grip_reopens = 0
        self.last_force: tuple | None = None   # the last force an answered exchange carried (device frame, N)
        self.velocity = (0.0, 0.0, 0.0)        # of the last valid sample (engine frame, scaled, m/s)
        self._command = _ZERO                  # the force read re-sends (device frame, N)
        self._command_at = time.monotonic()    # when send last set it (host clock, s)
        self._twist = 0.0                      # unwrapped twist (rad) and the raw angle it came from
        self._twist_raw: float | None = None

        self._link, self._identity, info = self._connect()  # (stream, Inverse3): dropped together
        self.port = self._port_opened
        self.device_id = self._identity[0]
        self.firmware_version = info.get("firmware_version")
        try:
            self.powered = bool(self._link[1].get_power_status())  # the device's own word (False: no supply)
        except Exception:
            self.powered = None
        self.label = label or f"{NAME} Inverse3 {self.device_id:04X} ({self.port})"

        # the VerseGrip: its port, its (stream, Handle) pair, its latest reading
        self.grip_port = self._grip_port(grip.strip())
        self._grip_link = None
        self._grip_latest: tuple | None = None  # (time, (w, x, y, z), buttons): replaced whole, never mutated
        self._grip_id = None                     # the first grip's device id: another's readings are dropped
        self._grip_failing_since: float | None = None
        if self.grip_port is not None:
            try:
                self._grip_link = self._open_grip()
            except Exception as exc:
                self._release()
                raise DeviceError(f"cannot open the VerseGrip on {self.grip_port}: {type(exc).__name__}: {exc}") from None
        _OPEN.add(self)
        if start_threads:
            if self.stall_s > 0.0:
                start_stall_watchdog(self, "softproxy-haply-watchdog")
            if self.grip_port is not None:
                threading.Thread(target=_grip_reader, args=(weakref.ref(self),), name="softproxy-haply-grip",
                                 daemon=True).start()

    # -- opening ------------------------------------------------------------------------------

    def _choose_port(self) -> str:
        """The Inverse3's port: the one given, else the detected one at `index` (or the first)."""
        detected = _ports(self._api.detect_inverse3s)
        if self.port_wanted is not None:
            port = self.port_wanted
            if port not in detected and not os.path.exists(port):
                raise DeviceError(f"cannot open a {NAME} Inverse3 on {port}: no such port ({PORT_HINT})")
        else:
            i = self.index or 0
            if i >= len(detected):
                which = f" at index {i}" if self.index is not None else ""
                raise DeviceError(f"cannot open a {NAME} Inverse3{which}: {len(detected)} detected ({PORT_HINT})")
            port = detected[i]
        if os.path.exists(port) and not os.access(port, os.R_OK | os.W_OK):
            raise DeviceError(f"cannot open a {NAME} Inverse3 on {port}: permission denied ({PORT_HINT})")
        return port

    def _connect(self):
        """((stream, Inverse3), identity, wake-up info) of an Inverse3 that answered a zero force,
        or DeviceError naming what to check."""
        port = self._choose_port()
        api = self._api
        try:
            stream = api.SerialStream(port)
            arm = api.Inverse3(stream, OPEN_TIMEOUT_S)
            info = arm.device_wakeup_dict()
            arm.set_read_timeout(self.timeout_s)
            answer = arm.end_effector_force([0.0, 0.0, 0.0])  # zero force first; it must be answered
        except Exception as exc:
            raise DeviceError(f"cannot open a {NAME} Inverse3 on {port}: {type(exc).__name__}: {exc}") from None
        if self._unanswered(answer):
            raise DeviceError(f"cannot open a {NAME} Inverse3 on {port}: it did not answer ({PORT_HINT})")
        try:
            identity = (int(info["device_id"]), str(info["device_id_ext"]))
        except (TypeError, KeyError, ValueError) as exc:
            raise DeviceError(f"cannot open a {NAME} Inverse3 on {port}: no device id in its wake-up ({exc!r})") from None
        self._port_opened = port
        return (stream, arm), identity, info

    @staticmethod
    def _unanswered(answer) -> bool:
        """True for the binding's answer to an exchange nobody answered: two zero vectors."""
        try:
            position, velocity = answer
            return all(c == 0.0 for c in (*position, *velocity))
        except (TypeError, ValueError):
            return False  # malformed: a garbage reading (an invalid sample), not silence

    def _grip_port(self, grip: str) -> str | None:
        if grip == "off":
            return None
        if grip != "auto":
            return grip
        grips = _ports(self._api.detect_handles)
        return grips[0] if grips else None

    def _open_grip(self):
        """A (stream, Handle) pair on the grip's port (the binding never raises here; a dead port
        shows as unanswered statuses)."""
        stream = self._api.SerialStream(self.grip_port)
        return stream, self._api.Handle(stream)

    def _release(self) -> None:
        """Drop the Inverse3's link: the Inverse3 before its stream (it points into it)."""
        link, self._link = self._link, None
        if link is not None:
            stream, arm = link
            del arm, link
            del stream

    # -- the exchange with the Inverse3 ---------------------------------------------------------

    def _exchange(self, force, what: str):
        """One exchange: `force` (device frame, N) out, (position, velocity) back; a failure (no
        answer, an exception, no link) is a DeviceError and the failed state. Once closed only
        zero goes out; a non-finite force never does."""
        if self.closed and any(force):
            raise DeviceError(f"{self.label}: device is closed")
        if not all(math.isfinite(c) for c in force):  # defence in depth: send() never hands one on
            self.nan_sends += 1
            force = _ZERO
        if self._link is None:
            raise self._fail(what, "not connected")
        try:
            answer = self._link[1].end_effector_force([float(force[0]), float(force[1]), float(force[2])])
        except Exception as exc:
            raise self._fail(what, f"{type(exc).__name__}: {exc}") from None
        if self._unanswered(answer):
            raise self._fail(what, f"no answer within {self.timeout_s * 1000:g} ms")
        self.last_force = tuple(force)
        return answer

    # -- failure and recovery ----------------------------------------------------------------

    def _fail(self, what: str, why: str) -> DeviceError:
        """Enter (or stay in) the failed state: one zero force tried, the link dropped; the DeviceError to raise."""
        self.errors += 1
        self._enter_failure()
        self._command = _ZERO
        if self._link is not None:
            try:
                self._link[1].end_effector_force([0.0, 0.0, 0.0])
            except Exception:
                pass
            self._release()
        self._fault_why = f"{self.label}: failed while {what} ({why})"
        self._fault = self._fault_text()
        return DeviceError(self._fault)

    def _fault_text(self) -> str:
        plan = self._with_last_reopen(f"rendering zero force; reopening every {REOPEN_INTERVAL_S:g} s")
        return f"{self._fault_why}; {plan}"

    def _try_reopen(self) -> None:
        """Open the Inverse3 again (wake-up, an answered zero force); it must be the same one."""
        self._release()
        try:
            link, identity, _ = self._connect()
        except DeviceError as exc:
            self.last_reopen_error = str(exc)
            return
        if identity != self._identity:
            del link
            self.last_reopen_error = (f"the device opened is not the same one (device id, UUID {identity}, "
                                      f"expected {self._identity})")
            return
        self._link = link
        self.port = self._port_opened
        self._reopened()

    def _recover(self) -> bool:
        """While failed: reopen when due; True once a reopen went through (its zero force answered)."""
        self._reopen_when_due()
        if self._link is None:
            self._fault = self._fault_text()  # with why the last reopen failed
            return False
        self._fault = None
        return True

    # -- the VerseGrip's thread -----------------------------------------------------------------

    def _grip_once(self) -> bool:
        """One VerseGrip status into the slot (the grip's thread; tests call it); True when it was
        a good one. A status with an error flag, no unit quaternion or another grip's id is
        dropped; after REOPEN_INTERVAL_S of those the grip's port is opened again."""
        link = self._grip_link  # held here for the call: the stream must outlive the Handle's use
        if link is None or self.closed:
            return False
        try:
            status = link[1].GetVersegripStatus()
            q = _unit_quaternion(status["quaternion"]) if not status.get("error_flag") else None
            grip_id, buttons = status.get("device_id"), status.get("buttons", 0)
        except Exception:
            q, grip_id, buttons = None, None, 0
        now = self._clock()
        if q is not None and self._grip_id is None:
            self._grip_id = grip_id
        if q is not None and grip_id == self._grip_id:
            ok = isinstance(buttons, int) and not isinstance(buttons, bool) and buttons >= 0
            self._grip_latest = (now, q, buttons if ok else 0)  # one assignment: the slot
            self._grip_failing_since = None
            return True
        self.grip_errors += 1
        if self._grip_failing_since is None:
            self._grip_failing_since = now
        elif now - self._grip_failing_since >= REOPEN_INTERVAL_S and not self.closed:
            self._grip_failing_since = now
            try:
                self._grip_link = self._open_grip()
                self.grip_reopens += 1
            except Exception:
                pass
            if self.closed:  # closed meanwhile: the new port is not kept open
                self._grip_link = None
        del link
        return False

    # -- the Device protocol -----------------------------------------------------------------

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        with self._lock:
            self._read(t, samples)

    def _read(self, t: float, samples: list[DeviceSample]) -> None:
        self._refuse_unless_ready()
        stale = time.monotonic() - self._command_at > self.stall_s > 0.0
        force = _ZERO if self._await_fresh or stale else self._command
        answer = self._exchange(force, "reading")
        valid = self._fill(t, samples[0], answer)
        if not valid:
            self.invalid_samples += 1
        else:  # back: a clean sample ends a failure
            self._fresh_sample()

    def _fill(self, t: float, s: DeviceSample, answer) -> bool:
        """The sample from an answer and the grip's slot; False when a reading is no finite number,
        out of the arm's reach, or the grip's reading stale or missing."""
        s.t = t
        s.valid = False
        try:
            position, velocity = answer
        except (TypeError, ValueError):
            return False
        p, v = _three(position), _three(velocity)
        if p is None or math.sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) > MAX_REACH_M:
            return False
        q, buttons, twist = (1.0, 0.0, 0.0, 0.0), 0, 0.0
        if self.grip_port is not None:
            latest = self._grip_latest
            if latest is None or self._clock() - latest[0] > self.grip_stale_s:
                self.grip_stale_samples += 1
                return False
            q, buttons = latest[1], latest[2]
            twist = self._unwrapped_twist(q)
        m, k, o = DEVICE_TO_ENGINE, self.workspace_scale, self.workspace_offset
        s.x, s.y, s.z = (k * (m[j][0] * p[0] + m[j][1] * p[1] + m[j][2] * p[2]) + o[j] for j in range(3))
        # a rotation R seen through M is M R Mᵀ: the quaternion (w, M v)
        qv = [m[j][0] * q[1] + m[j][1] * q[2] + m[j][2] * q[3] for j in range(3)]
        s.qw, s.qx, s.qy, s.qz = q[0], qv[0], qv[1], qv[2]
        s.twist = twist
        s.buttons = buttons
        if v is not None:
            self.velocity = tuple(k * (m[j][0] * v[0] + m[j][1] * v[1] + m[j][2] * v[2]) for j in range(3))
        s.valid = True
        return True

    def _unwrapped_twist(self, q) -> float:
        """The grip's rotation about its twist axis (swing-twist), unwrapped, from the first reading (rad)."""
        raw = 2.0 * math.atan2(q[1 + self._twist_axis], q[0])
        if self._twist_raw is not None:
            self._twist += _wrap(raw - self._twist_raw)
        self._twist_raw = raw
        return self._twist

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        with self._lock:
            self._send(finger, fx, fy, fz)

    def _send(self, finger: int, fx: float, fy: float, fz: float) -> None:
        if not self._count_send(finger, (fx, fy, fz)):
            fx = fy = fz = 0.0  # the motors get zero
        if self._await_fresh:  # failed, or back without a clean sample yet: no force
            if self._fault is not None:
                raise DeviceError(self._fault)
            self._command = _ZERO
            self._exchange(_ZERO, "writing zero force after a failure")
            return
        m = DEVICE_TO_ENGINE  # engine -> device: the transpose
        f = [m[0][j] * fx + m[1][j] * fy + m[2][j] * fz for j in range(3)]
        n = math.sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2])
        if n > self.max_force:
            f = [c * (self.max_force / n) for c in f]
        if not all(math.isfinite(c) for c in f):  # finite components whose norm overflows: inf * 0 is NaN
            self.nan_sends += 1
            f = [0.0, 0.0, 0.0]
        self._command = (f[0], f[1], f[2])
        self._command_at = time.monotonic()
        self._exchange(self._command, "sending a force")

    def _watch_once(self, now: float | None = None) -> None:
        """The stall watchdog's check: a non-zero command not renewed by send for `stall_s` (host
        clock, `now` in tests) becomes zero force. Waits for the lock at most `stall_s`: a call
        stuck in the binding holds it, and nothing written from here would get through either."""
        if self.closed or not self._lock.acquire(timeout=self.stall_s):
            return
        try:
            now = time.monotonic() if now is None else now
            if self.closed or not any(self._command) or now - self._command_at <= self.stall_s:
                return
            self._command = _ZERO
            try:
                self._exchange(_ZERO, "writing zero force after the loop stalled")
            except DeviceError:
                return  # failed: the next read reports it
            self.stall_zeroes += 1
        finally:
            self._lock.release()

    def close(self) -> None:
        """Zero force first, whatever happened before (up to CLOSE_ZERO_ATTEMPTS exchanges, the
        second on a reopened device), then the grip's thread stopped and the links dropped. Never raises."""
        with self._lock:
            if self.closed:
                return
            self.closed = True  # from here only zero goes out; the grip's thread ends
            self._command = _ZERO
            _OPEN.discard(self)

            def write_zero() -> bool:
                if self._link is None:
                    return False
                answer = self._link[1].end_effector_force([0.0, 0.0, 0.0])
                return not self._unanswered(answer)

            self._zero_on_close(write_zero)
            self._release()
            # the grip's thread may be inside a call on its link: it holds the pair until it returns
            self._grip_link = None

    def __repr__(self) -> str:
        return (f"HaplyDevice({self.label!r}, grip={self.grip_port!r}, max_force={self.max_force:g}, "
                f"powered={self.powered})")

    # -- configuration -----------------------------------------------------------------------

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>", binding=None, clock=None,
                    start_threads: bool = True) -> "HaplyDevice":
        """Build from a scene's [device] table; errors name the field.

            type = "haply"
            port = "/dev/ttyACM0"         # optional: the Inverse3's serial port, else the first detected
            index = 0                     # optional: the detected Inverse3 at this index
            grip = "auto"                 # "auto" (the first VerseGrip, if any), "off", or its port
            twist_axis = "z"              # the VerseGrip's axis the twist turns about
            workspace_scale = 1.0         # positions x this
            workspace_offset = [0, 0, 0]  # m, added to positions
            max_force_N = 2.0             # at most 3.3
            stall_ms = 50                 # a force not renewed for this long is replaced by zero (0: never)
            timeout_ms = 20               # an exchange not answered in this long is a failure
            grip_stale_ms = 100           # a VerseGrip reading older than this makes the sample invalid
        """
        config.check_table(cfg, source)
        table = config.check_type(cfg, source, "haply")  # each field as softproxy.schema declares it
        kwargs = config.given(table, cfg, {
            "port": "port", "index": "index", "grip": "grip", "twist_axis": "twist_axis",
            "workspace_scale": "workspace_scale", "workspace_offset": "workspace_offset", "max_force_N": "max_force",
            "stall_ms": "stall_ms", "timeout_ms": "timeout_ms", "grip_stale_ms": "grip_stale_ms"})
        if "index" in kwargs and "port" in kwargs:
            raise ValueError(f"{source}: device.index and device.port both choose a device: give one")
        if clock is not None:
            kwargs["clock"] = clock
        return config.construct(source, cls, binding, start_threads=start_threads, **kwargs)

    @classmethod
    def from_argument(cls, argument: str, scene=None, *, binding=None, clock=None,
                      start_threads: bool = True) -> "HaplyDevice":
        """`--device haply[:PORT|INDEX][,key=value...]`: the keys of `from_config`, vectors separated
        by ':' (`workspace_offset=0:0:0.05`). When the scene's own [device] is a Haply one, the
        argument overrides its fields."""
        source = f"--device haply:{argument}"
        cfg, parts = config.argument_table(argument, scene, "haply")
        if parts and "=" not in parts[0]:
            first = parts.pop(0)
            if first not in ("first", "auto"):
                if first.isdigit():
                    cfg["index"] = int(first)
                else:
                    cfg["port"] = first
        config.argument_items(cfg, parts, source, usage="PORT|INDEX[,key=value...]",
                              strings=("port", "grip", "twist_axis", "type"), integers=("index",))
        return cls.from_config(cfg, source=source, binding=binding, clock=clock, start_threads=start_threads)
