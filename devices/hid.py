"""HID haptic and 6-DOF input devices, driven by declarative profiles (`softproxy.devices.hid_profile`).

`HidDevice` implements `softproxy.device.Device` for one finger over a transport with the
subset of cython-hidapi's `hid.device` API it uses: `set_nonblocking`, `read(n)`,
`write(bytes)`, `close` (and `open_path` in `HidDevice.open`). Tests drive it with a fake
transport; `HidDevice.open(profile, path=None)` opens a real device through `hid` and can
reopen it by its path after a failure.

Reading (`read(t, samples)`, once per servo tick, never blocks):
* every pending report is drained (non-blocking reads, at most `max_reports_per_read`);
  each is parsed by the profile; the newest value of every field is kept, so a device that
  splits its axes over several reports (SpaceNavigator: translation id 1, rotation id 2)
  still yields one complete sample;
* rate mode integrates the axis velocities over the loop's dt into a position clamped to
  the workspace box (and the twist to ±twist_limit);
* the sample is `valid = False` (and counted in `invalid_samples`) when:
  - no complete sample was ever received (a periodic device before its first report);
  - stale: a periodic device sent no report carrying an axis for more than `stale_ms`
    (wall clock; the profile's, overridable) - the last values are kept, marked invalid,
    and rate mode stops integrating. `on_change` devices (the SpaceMouse reports only while
    the cap moves) are never stale: silence means at rest;
  - a sequence anomaly was seen this tick (dropped, duplicated or out-of-order reports,
    counted in `dropped` / `duplicates` / `out_of_order`; the counter then resynchronises
    on the report received);
  - the status field fails the profile's [status] test (e.g. FAULT set, CALIBRATED clear):
    counted in `status_faults`, the report's data is not used, and samples stay invalid
    until a report with a good status arrives;
  - a malformed report (ReportError) arrived this tick (`bad_reports`, `last_report_error`).
  Report ids the profile does not use are counted in `ignored_reports` and skipped.

Sending (`send(finger, fx, fy, fz, tx, ty, tz)`): the wrench is clamped to the device's
max_force / max_torque, packed into the profile's output report (sequence +1 per report,
enable = 1) and written. A non-finite component gives the zero-force report with enable = 0
(counted in `nan_sends`). An input-only profile (no [output], max_force = max_torque = 0)
renders nothing: send only counts.

Failure and recovery. An exception from a transport call (cython-hidapi raises OSError
or ValueError) or a negative write count is a failure: that read or send raises `DeviceError` naming the device (the servo
loop renders zero force that tick). The device is not given up:
* from the failure on, `send` writes no force: while failed it raises DeviceError at once,
  and once the transport works again it writes the zero-force, enable = 0 report instead
  of the force asked for, until `read` has produced a valid sample;
* every `read` while failed first tries to get the zero-force report through (output
  devices; an input-only one retries its read), and raises DeviceError while that fails.
  When it goes through the device is back: the read goes on with a fresh start - the
  values, sequence counter, status and stale clock from before the failure are forgotten,
  so a periodic device's samples are invalid until a complete report arrives (an
  on_change one starts at rest, as when opened). The first valid sample ends the failure
  (`recoveries`); forces are rendered again from the next send;
* a device from `HidDevice.open` also reopens its path (through the same `hid` module)
  every REOPEN_INTERVAL_S of its clock while failed, the first time REOPEN_INTERVAL_S after
  the failure (a transient error recovers on the same transport before that). The old
  transport is closed first: on Linux a hidraw node held open keeps its number, and a
  replugged device would come back under another one. When `hid.enumerate()` told at open
  which device the path was (USB ids, serial, usage, interface), a reopen first checks that
  the path still names that device: hidraw numbers are reused, and force reports must not
  go to another device;
* a device built on a given transport (no `reopen`) retries on that transport for as long
  as it fails; after NO_REOPEN_NOTICE_ERRORS failures in a row its error message says, from
  then on, that it will not be reopened.
Counted in `failures` (working -> failed), `transport_errors` (every failed call),
`reopens` and `recoveries`. `close()` always tries the zero-force, enable = 0 report
(CLOSE_ZERO_ATTEMPTS writes, the second on a reopened transport when it can reopen),
whatever happened before, never raises, then closes the transport. What a host cannot
guarantee (a killed process, a pulled cable, power loss) the firmware must: the device
drops to zero force when no output report arrives for 50 ms (devices/profiles/README.md).

Configuration: `HidDevice.from_config(cfg, source=...)` takes a scene's [device] table
(`type = "hid"`, `profile = "spacemouse"`, ...); `HidDevice.from_argument("spacemouse,mode=rate",
scene)` serves `softproxy run SCENE --device hid:spacemouse,mode=rate`.

`list_devices()` lists the connected HID devices with the profile that matches each;
`devices_main(as_json)` prints that as a table or JSON (the `softproxy devices` command).
"""

from __future__ import annotations

import functools
import importlib
import json
import math
import sys
import time
from pathlib import Path

from softproxy.device import DeviceError, DeviceSample

from . import device_config as config
from .lifecycle import DeviceLifecycle
from .recovery import CLOSE_ZERO_ATTEMPTS, REOPEN_INTERVAL_S, FaultRecovery  # noqa: F401 (this adapter's constants too)
from .hid_profile import (
    Profile,
    ProfileError,
    ReportError,
    build_output,
    load_profile,
    load_profiles,
    parse_input,
    zero_output,
)

MAX_DT = 0.1
"""Longest step (s) integrated at once in rate mode: a stalled loop does not make the finger jump."""
NO_REOPEN_NOTICE_ERRORS = 100
"""Failures in a row after which a device that cannot reopen (built on a given transport) says so."""
_TRANSPORT_ERRORS = (Exception,)
"""What a transport call may raise and is a failure of the device: cython-hidapi raises OSError or
ValueError, but whatever a driver raises, the device goes to zero force first when it comes back."""


def _import_hid():
    """The cython-hidapi module (`pip install hidapi`), or DeviceError saying how to get it."""
    try:
        mod = importlib.import_module("hid")
    except ImportError as exc:
        raise DeviceError(f"the `hid` module (pip package hidapi) is not available: {exc}") from None
    if not (hasattr(mod, "enumerate") and hasattr(mod, "device")):
        raise DeviceError(f"the `hid` module found at {getattr(mod, '__file__', '?')} is not cython-hidapi")
    return mod


def _path_text(path) -> str:
    if isinstance(path, (bytes, bytearray)):
        return bytes(path).decode("utf-8", "replace")
    return "" if path is None else str(path)


def _raw_path(path) -> bytes | None:
    if isinstance(path, str):
        return path.encode()
    return bytes(path) if isinstance(path, (bytes, bytearray)) else None


_IDENTITY_KEYS = ("vendor_id", "product_id", "serial_number", "usage_page", "usage", "interface_number")


def _identity(info: dict) -> tuple:
    """What tells one HID interface from another in an `hid.enumerate()` entry."""
    return tuple(info.get(k) for k in _IDENTITY_KEYS)


def _open_transport(hid, raw_path: bytes, path_text: str, profile_name: str):
    """An `hid.device` opened at `raw_path`, or DeviceError saying why (and how to fix access)."""
    transport = hid.device()
    try:
        transport.open_path(raw_path)
    except (OSError, ValueError, TypeError) as exc:
        raise DeviceError(f"cannot open HID device {path_text!r} for profile {profile_name!r}: {exc} "
                          "(on Linux, /dev/hidraw* needs a udev rule giving your user access)") from None
    return transport


class _Reopener:
    """Opens the device at one path again (`HidDevice.open` gives one to the device it opens).

    With the device's identity known, the path must still name that device: after a replug
    the path may be another device's, and output reports are forces.
    """

    def __init__(self, hid, raw_path: bytes, profile_name: str, identity: tuple | None) -> None:
        self.hid = hid
        self.raw_path = raw_path
        self.path_text = _path_text(raw_path)
        self.profile_name = profile_name
        self.identity = identity

    def __call__(self):
        if self.identity is not None:
            here = [i for i in self.hid.enumerate() if _raw_path(i.get("path")) == self.raw_path]
            if not here:
                raise OSError(f"{self.path_text} is not connected")
            now = _identity(here[0])
            if now != self.identity:
                raise OSError(f"{self.path_text} is now another device ({dict(zip(_IDENTITY_KEYS, now))})")
        return _open_transport(self.hid, self.raw_path, self.path_text, self.profile_name)


class _NoTransport:
    """In place of a transport closed for a reopen that failed: every call fails as a vanished device's."""

    def __init__(self, why: str) -> None:
        self.why = why

    def read(self, max_length, timeout_ms=0):
        raise OSError(self.why)

    def write(self, data):
        raise OSError(self.why)

    def set_nonblocking(self, value):
        raise OSError(self.why)

    def close(self) -> None:
        pass


class HidDevice(DeviceLifecycle, FaultRecovery):
    """One finger read from (and, with an [output], rendered on) a HID device described by a profile."""

    fingers = 1
    STATS = ("reports", "bad_reports", "ignored_reports", "status_faults", "sequence_errors", "dropped", "duplicates",
             "out_of_order", "backlogs", "invalid_samples", "stale_samples", "sends", "nan_sends", "failures",
             "transport_errors", "reopens", "recoveries")

    def __init__(self, profile, transport, *, mode: str | None = None, workspace_scale: float = 1.0,
                 workspace_offset=(0.0, 0.0, 0.0), workspace_half_m=(0.1, 0.1, 0.1),
                 twist_limit_rad: float = math.pi, stale_ms: float | None = None,
                 max_force: float | None = None, max_torque: float | None = None,
                 clock=time.monotonic, max_reports_per_read: int = 256, label: str | None = None,
                 reopen=None) -> None:
        """`transport`: an open `hid.device` (or a fake one). `reopen`: None, or a callable
        returning a new open transport to the same device, tried while the device is failed
        (`HidDevice.open` passes one); without it the device retries on `transport`."""
        profile = load_profile(profile)
        self.profile = profile
        mode = profile.mode if mode is None else mode
        if mode not in profile.modes:
            raise ValueError(f"mode must be one of {list(profile.modes)} for profile {profile.name!r}, got {mode!r}")
        scale, offset = config.check_workspace(workspace_scale, workspace_offset)
        half = tuple(workspace_half_m)
        if len(half) != 3 or not all(config.finite(v) and v > 0 for v in half):
            raise ValueError(f"workspace_half_m must be 3 finite numbers > 0 (m), got {workspace_half_m!r}")
        if not (config.finite(twist_limit_rad) and twist_limit_rad > 0):
            raise ValueError(f"twist_limit_rad must be a finite number > 0, got {twist_limit_rad!r}")
        stale_ms = profile.stale_ms if stale_ms is None else stale_ms
        if not (config.finite(stale_ms) and stale_ms >= 0):
            raise ValueError(f"stale_ms must be a finite number >= 0, got {stale_ms!r}")
        for name, value, cap in (("max_force", max_force, profile.max_force),
                                 ("max_torque", max_torque, profile.max_torque)):
            if value is not None and not (config.finite(value) and 0 <= value <= cap):
                raise ValueError(f"{name} must be a finite number in [0, {cap:g}] (the profile's limit), "
                                 f"got {value!r}")
        if not (isinstance(max_reports_per_read, int) and max_reports_per_read >= 1):
            raise ValueError(f"max_reports_per_read must be an integer >= 1, got {max_reports_per_read!r}")
        self.mode = mode
        self.workspace_scale, self.workspace_offset = scale, offset
        self.workspace_half_m = tuple(float(v) for v in half)
        self.twist_limit_rad = float(twist_limit_rad)
        self.stale_ms = float(stale_ms)
        self.max_force = float(profile.max_force if max_force is None else max_force)
        # what the profile declares (softproxy.stiffness_cap); the shipped profiles declare none:
        # an input-only SpaceMouse (renders no force) and open DIY devices no vendor rates
        self.max_stiffness, self.max_damping = profile.max_stiffness, profile.max_damping
        self.max_torque = float(profile.max_torque if max_torque is None else max_torque)
        self.max_reports_per_read = max_reports_per_read
        self.label = label or profile.name
        self._init_recovery(clock)  # a device given a transport (no `reopen`) does not reopen
        self._transport = transport
        self._read_size = profile.max_bytes + 1  # one more than allowed: an oversized report shows as such

        self._axis = []  # (sample attribute, field, sign) for x, y, z, twist
        for attr in ("x", "y", "z", "twist"):
            if attr in profile.axes:
                fname, sign = profile.axes[attr]
                self._axis.append((attr, fname, sign))
        self._axis_fields = {fname for _, fname, _ in self._axis}
        self._periodic = profile.reporting == "periodic"
        # on_change devices start at rest (every axis 0); periodic ones wait for their first report
        self._values: dict[str, float] = {} if self._periodic else dict.fromkeys(self._axis_fields, 0.0)
        self._buttons = 0
        self._seq: int | None = None
        self._seq_mod = 1 << profile.sequence_bits if profile.sequence_bits else 0
        self._faulted = False
        self._last_report_time: float | None = None
        self._last_t: float | None = None
        self._pos = list(self.workspace_offset)  # rate mode: integrated position
        self._twist = 0.0                        # rate mode: integrated twist
        self._out_seq = 0
        self._reopen = reopen
        self._errors_in_a_row = 0       # transport errors since the last read that went through
        self.closed = False

        self.reports = 0
        self.bad_reports = 0
        self.ignored_reports = 0
        self.status_faults = 0
        self.sequence_errors = 0
        self.dropped = 0
        self.duplicates = 0
        self.out_of_order = 0
        self.backlogs = 0
        self.invalid_samples = 0
        self.stale_samples = 0
        self.sends = 0
        self.nan_sends = 0
        self.transport_errors = 0
        self.status: int | None = None
        self.last_report_error = ""
        self.last_output: bytes | None = None

        try:
            transport.set_nonblocking(1)
        except (OSError, ValueError) as exc:
            raise DeviceError(f"{self.label}: cannot make the HID device non-blocking: {exc}") from None

    # -- opening -----------------------------------------------------------------------------

    @classmethod
    def open(cls, profile, path=None, *, hid_module=None, **kwargs) -> "HidDevice":
        """Open the device at `path` (bytes or str, as `hid.enumerate()` gives it), or else the
        first connected device the profile matches, through cython-hidapi (`hid_module`, for tests)."""
        profile = load_profile(profile)
        hid = hid_module if hid_module is not None else _import_hid()
        if path is None:
            try:
                infos = list(hid.enumerate())
            except (OSError, ValueError) as exc:
                raise DeviceError(f"cannot enumerate HID devices: {exc}") from None
            found = [i for i in infos if any(m.matches(i) for m in profile.matches)]
            if not found:
                raise DeviceError(f"no connected HID device matches profile {profile.name!r} "
                                  f"(ids {', '.join(profile.ids()) or 'none'}); `softproxy devices` lists the "
                                  "connected ones; give the device's path or add a [[match]] to the profile")
            path = found[0].get("path")
            identity = _identity(found[0])
        else:
            identity = None
            try:  # who the path is, so that a reopen can check it is still that device
                here = [i for i in hid.enumerate() if _raw_path(i.get("path")) == _raw_path(path)]
                identity = _identity(here[0]) if here else None
            except (OSError, ValueError, TypeError):
                pass
        raw_path = path.encode() if isinstance(path, str) else path
        transport = _open_transport(hid, raw_path, _path_text(path), profile.name)
        kwargs.setdefault("label", f"{profile.name} at {_path_text(path)}")
        if isinstance(raw_path, (bytes, bytearray)):
            kwargs.setdefault("reopen", _Reopener(hid, bytes(raw_path), profile.name, identity))
        try:
            return cls(profile, transport, **kwargs)
        except BaseException:
            try:
                transport.close()
            except Exception:
                pass
            raise

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>", transport=None, hid_module=None,
                    clock=None) -> "HidDevice":
        """Build from a scene's [device] table; errors name the field.

            type = "hid"
            profile = "spacemouse"          # a shipped profile's name, or a path (relative to the scene)
            path = "/dev/hidraw3"           # optional: this device, else the first the profile matches
            mode = "position"               # or "rate"; default: the profile's
            workspace_scale = 1.0           # position mode: positions x this; rate mode: velocities x this
            workspace_offset = [0, 0, 0.05] # m: added to positions; rate mode: start and box centre
            workspace_half_m = [0.1, 0.1, 0.1]  # rate mode: half extents of the box (m)
            twist_limit_rad = 3.14159       # rate mode: |twist| limit
            stale_ms = 20                   # periodic devices: invalid after this long without a report
            max_force_N = 2.0               # lower the profile's limits (never raise them)
            max_torque_Nm = 0.02

        `transport` (a fake `hid.device`, already open), `hid_module` and `clock` are for tests.
        """
        fail = functools.partial(config.field_error, source)
        config.check_table(cfg, source)
        table = config.check_type(cfg, source, "hid", " for a HID device")  # each field as softproxy.schema declares it
        base = Path(source).resolve().parent if Path(source).is_file() else None
        try:
            profile = load_profile(table.profile.strip(), base)
        except ProfileError as exc:
            raise ValueError(f"{source}: device.profile: {exc}") from None
        kwargs = config.given(table, cfg, {
            "mode": "mode", "workspace_scale": "workspace_scale", "workspace_offset": "workspace_offset",
            "workspace_half_m": "workspace_half_m", "twist_limit_rad": "twist_limit_rad", "stale_ms": "stale_ms"})
        if "mode" in kwargs and kwargs["mode"] not in profile.modes:
            raise fail("device.mode", f"one of {list(profile.modes)} (what profile {profile.name!r} supports)",
                       kwargs["mode"])
        for key, arg, cap in (("max_force_N", "max_force", profile.max_force),
                              ("max_torque_Nm", "max_torque", profile.max_torque)):
            if key in cfg:  # within the profile's limit (the schema checked it is a finite number >= 0)
                if getattr(table, key) > cap:
                    raise fail(f"device.{key}", f"a finite number in [0, {cap:g}] (profile {profile.name!r}'s limit)",
                               cfg[key])
                kwargs[arg] = getattr(table, key)
        if clock is not None:
            kwargs["clock"] = clock
        if transport is not None:
            return cls(profile, transport, **kwargs)
        return cls.open(profile, cfg.get("path"), hid_module=hid_module, **kwargs)

    @classmethod
    def from_argument(cls, argument: str, scene=None, *, transport=None, hid_module=None) -> "HidDevice":
        """`softproxy run SCENE --device hid:PROFILE[,key=value...]`: a HID device for any scene.

        PROFILE is a profile name or path (relative to the current folder); the keys are
        those of `from_config` (e.g. `hid:spacemouse,mode=rate,workspace_offset=0:0:0.05`,
        vectors separated by ':'). When the scene's own [device] is a HID one, the argument
        overrides its fields; otherwise the scene's [device] (e.g. a scripted one) is ignored.
        """
        source = f"--device hid:{argument}"
        cfg, parts = config.argument_table(argument, scene, "hid")
        if parts and "=" not in parts[0]:
            cfg["profile"] = parts.pop(0)
        config.argument_items(cfg, parts, source, usage="PROFILE[,key=value...]",
                              vectors=("workspace_offset", "workspace_half_m"), strings=("profile", "path", "mode", "type"))
        return cls.from_config(cfg, source=source, transport=transport, hid_module=hid_module)

    # -- the Device protocol -------------------------------------------------------------------

    # -- failure and recovery (see the module docstring) ---------------------------------------

    def _fail(self, what: str, exc: BaseException) -> DeviceError:
        """Enter (or stay in) the failed state after a transport error; the DeviceError to raise."""
        self.transport_errors += 1
        self._errors_in_a_row += 1
        if self._enter_failure():  # working until now: forget the device's state
            self._forget_samples()
        if self.profile.output is not None:
            plan = "retrying, the zero-force report first"
        else:
            plan = "retrying"
        if self._reopen is not None:
            plan = self._with_last_reopen(f"{plan}, reopening the device every {REOPEN_INTERVAL_S:g} s")
        elif self._errors_in_a_row >= NO_REOPEN_NOTICE_ERRORS:
            plan = (f"{self._errors_in_a_row} failures in a row; it will not be reopened (it was given a "
                    f"transport, not opened by path): still {plan} on the same transport")
        self._fault = (f"{self.label}: HID device disappeared or failed while {what} "
                       f"({type(exc).__name__}: {exc}); rendering zero force; {plan}")
        return DeviceError(self._fault)

    def _forget_samples(self) -> None:
        """Back to the state of a just-opened device: nothing from before a failure is trusted."""
        self._values.clear()
        if not self._periodic:
            self._values.update(dict.fromkeys(self._axis_fields, 0.0))  # on_change: at rest
        self._buttons = 0
        self._seq = None
        self._faulted = False
        self.status = None
        self._last_report_time = None
        self._last_t = None

    def _try_reopen(self) -> bool:
        """Close the transport and open the device again by its path; True when it opened."""
        try:
            self._transport.close()
        except Exception:  # a vanished device's handle may refuse to close
            pass
        transport = None
        try:
            transport = self._reopen()
            transport.set_nonblocking(1)
        except Exception as exc:  # whatever the module raises, the device stays failed
            self.last_reopen_error = str(exc) or type(exc).__name__
            if transport is not None:
                try:
                    transport.close()
                except Exception:
                    pass
            self._transport = _NoTransport(f"not open: the last reopen failed: {self.last_reopen_error}")
            return False
        self._transport = transport
        self._reopened()
        return True

    def _write_zero(self, what: str) -> bool:
        """Write the zero-force, enable = 0 report; False (and failed) when it did not go through."""
        self._out_seq = (self._out_seq + 1) & 0xFFFFFFFF
        try:
            self._write(zero_output(self.profile, self._out_seq), what)
        except DeviceError:
            return False
        return True

    def _recover(self) -> bool:
        """While failed: reopen when due, then get the zero-force report through; True when it did."""
        if self._reopen is not None:
            self._reopen_when_due()
        if self.profile.output is not None and not self._write_zero("writing the zero-force report"):
            return False
        self._fault = None  # the read goes on from a fresh start; samples count from here
        return True

    def _check_sequence(self, seq: int) -> bool:
        """True on a sequence anomaly (counted); the counter resynchronises on `seq`."""
        last, self._seq = self._seq, seq
        if last is None:
            return False
        d = (seq - last) % self._seq_mod
        if d == 1:
            return False
        self.sequence_errors += 1
        if d == 0:
            self.duplicates += 1
        elif d < self._seq_mod // 2:
            self.dropped += d - 1
        else:
            self.out_of_order += 1
        return True

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        self._refuse_unless_ready()
        profile = self.profile
        transport = self._transport
        mode = self.mode
        values = self._values
        axis_fields = self._axis_fields
        bad = False
        now = self._clock()
        for _ in range(self.max_reports_per_read):
            try:
                data = transport.read(self._read_size)
            except _TRANSPORT_ERRORS as exc:
                raise self._fail("reading", exc) from None
            if not data:
                break
            try:
                report = parse_input(profile, data, mode)
            except ReportError as exc:
                self.bad_reports += 1
                self.last_report_error = str(exc)
                bad = True
                continue
            if report is None:
                self.ignored_reports += 1
                continue
            self.reports += 1
            vals = report.values
            if self._seq_mod and "sequence" in vals and self._check_sequence(vals["sequence"]):
                bad = True
            if "status" in vals:
                st = vals["status"]
                self.status = st
                if (st & profile.status_set) != profile.status_set or st & profile.status_clear:
                    self.status_faults += 1
                    self._faulted = True
                    continue  # a faulted device's numbers are not used
                self._faulted = False
            if "buttons" in vals:
                self._buttons = vals["buttons"]
            carried = False
            for name, v in vals.items():
                if name in axis_fields:
                    values[name] = v
                    carried = True
            if carried:
                self._last_report_time = now
        else:
            self.backlogs += 1  # more pending than one tick drains: the rest waits for the next

        complete = len(values) == len(axis_fields)
        stale = False
        if self._periodic and self.stale_ms > 0.0:
            last = self._last_report_time
            stale = last is None or (now - last) * 1000.0 > self.stale_ms
        dt = 0.0 if self._last_t is None else t - self._last_t
        dt = 0.0 if not (dt > 0.0) else MAX_DT if dt > MAX_DT else dt
        self._last_t = t
        ok = complete and not stale and not self._faulted

        s = samples[0]
        ox, oy, oz = self.workspace_offset
        k = self.workspace_scale
        if mode == "position":
            pos = [ox, oy, oz]
            twist = 0.0
            if complete:
                for attr, fname, sign in self._axis:
                    v = sign * values[fname]
                    if attr == "twist":
                        twist = v
                    else:
                        i = "xyz".index(attr)
                        pos[i] += k * v
            s.x, s.y, s.z = pos
            s.twist = twist
        else:
            if ok and not bad and dt > 0.0:
                p = self._pos
                for attr, fname, sign in self._axis:
                    v = sign * values[fname] * dt
                    if attr == "twist":
                        tw = self._twist + v
                        lim = self.twist_limit_rad
                        self._twist = lim if tw > lim else -lim if tw < -lim else tw
                    else:
                        i = "xyz".index(attr)
                        c, h = self.workspace_offset[i], self.workspace_half_m[i]
                        q = p[i] + k * v
                        p[i] = c + h if q > c + h else c - h if q < c - h else q
            s.x, s.y, s.z = self._pos
            s.twist = self._twist
        s.t = t
        s.qw, s.qx, s.qy, s.qz = 1.0, 0.0, 0.0, 0.0
        s.buttons = self._buttons
        valid = ok and not bad and s.is_finite()
        s.valid = valid
        if stale:
            self.stale_samples += 1
        if not valid:
            self.invalid_samples += 1
        if self._await_fresh:  # after a failure: the transport answered
            self._errors_in_a_row = 0
        if valid:  # a valid sample ends a failure
            self._fresh_sample()

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        self._count_send(finger, (fx, fy, fz, tx, ty, tz))  # a NaN is never written: see build_output
        if self.profile.output is None:
            return  # input-only device: renders nothing
        if self._await_fresh:  # failed, or back but without a fresh sample yet: no force
            if self._fault is not None:
                raise DeviceError(self._fault)  # the next read retries
            self._out_seq = (self._out_seq + 1) & 0xFFFFFFFF
            self._write(zero_output(self.profile, self._out_seq), "sending zero force after a failure")
            return
        self._out_seq = (self._out_seq + 1) & 0xFFFFFFFF
        report = build_output(self.profile, self._out_seq, fx, fy, fz, tx, ty, tz, enable=True,
                              max_force=self.max_force, max_torque=self.max_torque)
        self._write(report, "sending a force")

    def _write(self, report: bytes, what: str) -> None:
        try:
            n = self._transport.write(report)
        except _TRANSPORT_ERRORS as exc:
            raise self._fail(what, exc) from None
        if isinstance(n, int) and n < 0:
            raise self._fail(what, OSError(f"write returned {n}"))
        self.last_output = report

    def close(self) -> None:
        """Zero force (enable = 0) first when the device renders force, whatever happened before
        (up to CLOSE_ZERO_ATTEMPTS writes), then release it. Never raises."""
        if self.closed:
            return
        self.closed = True
        if self.profile.output is not None:  # the device may be back on a new handle for the second try
            self._zero_on_close(lambda: self._write_zero("sending zero force on close"), self._reopen is not None)
        try:
            self._transport.close()
        except Exception:  # closing a vanished device must not mask what the caller is doing
            pass

    def __repr__(self) -> str:
        return f"HidDevice({self.label!r}, mode={self.mode!r}, max_force={self.max_force:g})"


# ---------------------------------------------------------------------------------------------
# listing


def list_devices(enumerate_fn=None, profiles: list[Profile] | None = None) -> list[dict]:
    """The connected HID devices (`hid.enumerate()`, or `enumerate_fn` for tests), each with
    the name of the profile that matches it (or None) and the model that profile gives it."""
    if enumerate_fn is None:
        enumerate_fn = _import_hid().enumerate
    if profiles is None:
        profiles = load_profiles().profiles
    rows = []
    for info in enumerate_fn():
        profile_name, model = None, None
        for p in profiles:
            m = next((m for m in p.matches if m.matches(info)), None)
            if m is not None:
                profile_name, model = p.name, m.model or None
                break
        vid, pid = info.get("vendor_id"), info.get("product_id")
        rows.append({
            "id": f"{vid:04x}:{pid:04x}" if isinstance(vid, int) and isinstance(pid, int) else "?",
            "vendor_id": vid,
            "product_id": pid,
            "manufacturer": info.get("manufacturer_string") or "",
            "product": info.get("product_string") or "",
            "serial": info.get("serial_number") or "",
            "usage_page": info.get("usage_page"),
            "usage": info.get("usage"),
            "interface": info.get("interface_number"),
            "path": _path_text(info.get("path")),
            "profile": profile_name,
            "model": model,
        })
    return rows


def devices_main(as_json: bool = False, *, enumerate_fn=None, out=None, err=None, backends=None) -> int:
    """`softproxy devices [--json]`: print the connected HID devices and their profiles; 0, or 1
    when HID devices cannot be enumerated. Broken profiles and profiles that shadow another
    of the same name get one line each on `err` (and, shadowing, a "shadowing" list in the JSON).
    `backends`: rows of the other device backends' availability (a vendor SDK's devices: backend,
    binding, sdk, devices, message), printed after the HID devices and as "backends" in the JSON."""
    out = sys.stdout if out is None else out
    backends = list(backends or [])
    err = sys.stderr if err is None else err
    profiles, errors, shadowing = load_profiles()
    for e in errors:
        print(f"softproxy devices: skipping a broken profile: {e}", file=err)
    for sh in shadowing:
        print(f"softproxy devices: warning: {sh.warning()}", file=err)
    try:
        rows = list_devices(enumerate_fn, profiles)
    except (DeviceError, OSError, ValueError) as exc:
        print(f"softproxy devices: cannot list HID devices: {exc}", file=err)
        return 1
    if as_json:
        doc = {"devices": rows, "profiles": [{"name": p.name, "description": p.description, "ids": p.ids(),
                                             "renders_force": p.renders_force, "modes": list(p.modes),
                                             "source": p.source} for p in profiles],
               "shadowing": [{"name": sh.name, "source": sh.source, "shadowed": sh.shadowed,
                              "warning": sh.warning()} for sh in shadowing],
               "backends": backends}
        print(json.dumps(doc, indent=2), file=out)
        return 0
    if not rows:
        print("no HID devices connected", file=out)
    else:
        header = ("id", "profile", "model / product", "usage", "if", "path")
        cells = [header]
        for r in rows:
            usage = (f"{r['usage_page']:04x}:{r['usage']:04x}" if isinstance(r["usage_page"], int)
                     and isinstance(r["usage"], int) else "-")
            cells.append((r["id"], r["profile"] or "-", r["model"] or r["product"] or "-", usage,
                          "-" if r["interface"] is None else str(r["interface"]), r["path"]))
        widths = [max(len(c[i]) for c in cells) for i in range(len(header))]
        for c in cells:
            print("  ".join(v.ljust(w) for v, w in zip(c, widths)).rstrip(), file=out)
    print(f"profiles: {', '.join(p.name for p in profiles) or 'none'} "
          f"(a device without one needs a profile: see devices/profiles/README.md)", file=out)
    for b in backends:  # vendor SDKs: whether `--device NAME:...` can work here, and why not
        state = ("ready" if b.get("sdk") else "SDK missing" if b.get("binding") else "binding missing")
        print(f"{b.get('backend')}: {state}; {b.get('message', '')}", file=out)
    return 0
