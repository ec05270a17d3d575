"""HID device safety: a device that errors renders zero and comes back; close() always tries the
zero-force report; profile limits are bounded; a profile shadowing another is reported.

The device under test talks to a fake USB port (`Port`): the firmware end, which streams state
reports and records every output report that reached it (`wire`), and can fail transiently,
vanish, and come back. Handles to it are opened directly (a given transport) or through a
fake `hid` module (`PortModule`), so that `HidDevice.open` can reopen it by its path.
"""

import io
import json
import math
from collections import deque

import numpy as np
import pytest

from conftest import Clock, box_loop, oh_state

from softproxy.devices.hid import CLOSE_ZERO_ATTEMPTS, NO_REOPEN_NOTICE_ERRORS, REOPEN_INTERVAL_S, HidDevice, devices_main
from softproxy.devices.hid_profile import (
    MAX_FORCE_N,
    MAX_TORQUE_NM,
    PROFILE_DIR,
    PROFILE_PATH_ENV,
    ProfileError,
    Shadowing,
    load_profile,
    load_profiles,
    parse_output,
)
from softproxy.device import DeviceError, DeviceSample

PATH = b"/dev/hidraw4"
OPEN_HAPTIC_INFO = {"path": PATH, "vendor_id": 0x1209, "product_id": 0x0001, "serial_number": "A1",
                    "usage_page": 0xFF00, "usage": 1, "interface_number": 0,
                    "manufacturer_string": "maker", "product_string": "open haptic"}


class Port:
    """The firmware end of one USB device: what it received, what it sends, how it fails.

    `fail_reads` / `fail_writes`: that many next calls fail (transient errors), on any handle.
    `dead`: every call fails while set (a glitch on the same handle, which comes back).
    `unplug()`: the device vanishes; handles opened before never work again (as a hidraw
    file descriptor after a disconnect); `plug()` brings it back for new handles.
    """

    def __init__(self, info=OPEN_HAPTIC_INFO):
        self.info = dict(info)
        self.present = True
        self.generation = 0
        self.dead = False
        self.fail_reads = 0
        self.fail_writes = 0
        self.silent = False
        self.seq = 0
        self.x_um = 0
        self.wire = []            # every output report the device received, in order
        self.handles = []         # every handle opened on it
        self.write_failures = 0   # failed writes (injected or on a dead handle)

    def unplug(self):
        self.present = False
        self.generation += 1

    def plug(self):
        self.present = True

    def emit(self):
        """One state report to every open handle (each has its own queue, as hidraw's)."""
        if self.silent or not self.present:
            return
        self.seq += 1
        report = oh_state(self.seq, x_um=self.x_um, z_um=50_000)
        for h in self.handles:
            if h.alive():
                h.queue.append(report)


class PortHandle:
    """One open handle to a `Port`: the `hid.device` subset HidDevice uses."""

    def __init__(self, port, opened=True):
        self.port = port
        self.generation = port.generation
        self.opened = opened
        self.closed = False
        self.nonblocking = None
        self.queue = deque()
        port.handles.append(self)

    def alive(self):
        p = self.port
        return self.opened and not self.closed and p.present and self.generation == p.generation

    def _check(self, what):
        if self.closed or not self.opened:
            raise ValueError("not open")
        if not self.alive() or self.port.dead:
            raise OSError(f"{what} error")

    def set_nonblocking(self, v):
        self._check("ioctl")
        self.nonblocking = v
        return 0

    def read(self, max_length, timeout_ms=0):
        self._check("read")
        if self.port.fail_reads > 0:
            self.port.fail_reads -= 1
            raise OSError("transient read error")
        return list(self.queue.popleft()[:max_length]) if self.queue else []

    def write(self, data):
        try:
            self._check("write")
        except (OSError, ValueError):
            self.port.write_failures += 1
            raise
        if self.port.fail_writes > 0:
            self.port.fail_writes -= 1
            self.port.write_failures += 1
            raise OSError("transient write error")
        self.port.wire.append(bytes(data))
        return len(data)

    def close(self):
        self.closed = True


class PortModule:
    """A fake cython-hidapi module: `enumerate()` and `device().open_path()` over ports by path."""

    def __init__(self, port, path=PATH):
        self.ports = {path: port}
        self.enumerations = 0
        self.open_attempts = 0
        self.opened = 0

    def enumerate(self, vendor_id=0, product_id=0):
        self.enumerations += 1
        return [dict(p.info, path=path) for path, p in self.ports.items() if p.present]

    def device(self):
        module = self

        class Handle(PortHandle):
            def __init__(self):
                self.port = None
                self.opened = False
                self.closed = False
                self.queue = deque()

            def open_path(self, path):
                module.open_attempts += 1
                port = module.ports.get(path)
                if port is None or not port.present:
                    raise OSError("open failed")
                PortHandle.__init__(self, port)
                module.opened += 1

            def alive(self):
                return self.port is not None and PortHandle.alive(self)

        return Handle()


def decoded(profile, wire):
    return [parse_output(profile, w) for w in wire]


def assert_zero(report):
    assert report["enable"] == 0 and (report["fx"], report["fy"], report["fz"], report["torque"]) == (0, 0, 0, 0)


def finite_and_clamped(profile, wire, max_force=5.0, max_torque=0.05):
    """Every report on the wire decodes to finite numbers within the device's limits."""
    for r in decoded(profile, wire):
        assert all(math.isfinite(v) for v in r.values()), r
        assert math.hypot(r["fx"], r["fy"], r["fz"]) <= max_force * (1 + 1e-3) + 2e-3, r
        assert abs(r["torque"]) <= max_torque + 1e-5, r


def direct(port=None, **kw):
    """A device built on a given transport (no way to reopen it)."""
    port = port or Port()
    clock = Clock()
    return HidDevice("open_haptic", PortHandle(port), clock=clock, **kw), port, clock


def step(dev, port, clock, t, s, force=(0.0, 0.0, 5.0)):
    """One servo tick as the loop does it: the device streams, read, send; DeviceError counted."""
    clock.now += 0.001
    port.emit()
    errors = 0
    try:
        dev.read(t, s)
    except DeviceError:
        errors += 1
        force = (0.0, 0.0, 0.0)  # the loop renders zero on a tick whose read failed
    try:
        dev.send(0, *force, 0.0, 0.0, 0.0)
    except DeviceError:
        errors += 1
    return errors


# ---------------------------------------------------------------------------------------------
# scripted failures


def test_transient_read_error_recovers_zero_force_first_then_fresh_sample():
    """One read error: DeviceError that tick, no force while failed, the zero-force report is the
    first thing written once the transport answers, the sample from before is not trusted (invalid
    until a new report), and forces render again after a valid sample."""
    dev, port, clock = direct()
    s = [DeviceSample()]
    for k in range(5):
        assert step(dev, port, clock, k * 1e-3, s) == 0
    assert s[0].valid and decoded(dev.profile, port.wire)[-1]["fz"] == pytest.approx(5.0)
    n = len(port.wire)

    port.fail_reads = 1
    clock.now += 0.001
    with pytest.raises(DeviceError, match="disappeared or failed while reading.*transient read error"):
        dev.read(0.005, s)
    with pytest.raises(DeviceError):  # failed: no force goes out, not even tried
        dev.send(0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0)
    assert len(port.wire) == n

    port.silent = True  # back, but nothing new yet: 1 ms after the last good report (stale_ms = 20)
    clock.now += 0.001
    dev.read(0.006, s)
    assert not s[0].valid  # what was read before the failure is not trusted
    assert_zero(decoded(dev.profile, port.wire)[n])  # the first report after the failure
    dev.send(0, 0.0, 0.0, 5.0, 0.0, 0.0, 0.0)  # still no valid sample: zero, motors off
    assert all(r["enable"] == 0 for r in decoded(dev.profile, port.wire[n:]))

    port.silent = False
    assert step(dev, port, clock, 0.007, s) == 0
    assert s[0].valid and dev.recoveries == 1 and dev.failures == 1
    assert decoded(dev.profile, port.wire)[-1]["fz"] == pytest.approx(5.0)  # renders again
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])
    finite_and_clamped(dev.profile, port.wire)


def test_write_error_recovers_and_the_next_write_is_zero_force():
    """A failed force write leaves the last force on the wire; the next read gets the zero-force
    report through before anything else, then the device renders again."""
    dev, port, clock = direct()
    s = [DeviceSample()]
    for k in range(3):
        step(dev, port, clock, k * 1e-3, s)
    port.fail_writes = 1
    with pytest.raises(DeviceError, match="while sending a force.*transient write error"):
        dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    assert decoded(dev.profile, port.wire)[-1]["enable"] == 1  # what the device holds now
    n = len(port.wire)
    assert step(dev, port, clock, 0.004, s) == 0  # read: zero-force report, then a fresh sample
    wire = decoded(dev.profile, port.wire)
    assert_zero(wire[n])
    assert s[0].valid and wire[-1]["fz"] == pytest.approx(5.0)
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])


def test_on_change_device_forgets_its_state_after_a_failure():
    """An input-only, on_change device (SpaceMouse): the cap's deflection read before a failure is
    forgotten (at rest after recovery, as when opened), and nothing is ever written."""
    h = PortHandle(Port())
    dev = HidDevice("spacemouse", h, clock=Clock())
    s = [DeviceSample()]
    h.queue.append(bytes.fromhex("01 6400 0000 0000"))
    dev.read(0.0, s)
    assert s[0].x == pytest.approx(0.01)
    h.port.fail_reads = 1
    with pytest.raises(DeviceError, match="retrying"):
        dev.read(0.001, s)
    dev.read(0.002, s)
    assert s[0].valid and s[0].x == 0.0 and dev.recoveries == 1
    dev.send(0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dev.close()
    assert h.port.wire == [] and h.closed


def test_close_always_tries_zero_force_and_never_raises():
    """close() writes the zero-force report whatever happened before: after a failure that was never
    retried, through a transient error on the close write itself, and gives up quietly (closing
    the handle) when the transport stays dead."""
    # failed on read, never read again: close still sends zero force
    dev, port, clock = direct()
    s = [DeviceSample()]
    step(dev, port, clock, 0.0, s)
    port.fail_reads = 1
    with pytest.raises(DeviceError):
        dev.read(0.001, s)
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])

    # the zero-force write in close fails once: the retry gets it through
    dev, port, clock = direct()
    step(dev, port, clock, 0.0, s)
    port.fail_writes = 1
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])
    assert port.handles[0].closed and port.write_failures == 1

    # a dead transport: CLOSE_ZERO_ATTEMPTS tries, no exception, the handle is released
    dev, port, clock = direct()
    step(dev, port, clock, 0.0, s)
    port.dead = True
    dev.close()
    assert port.write_failures == CLOSE_ZERO_ATTEMPTS and port.handles[0].closed
    assert decoded(dev.profile, port.wire)[-1]["enable"] == 1  # what only the firmware watchdog can stop
    dev.close()  # idempotent

    # a transport raising something unexpected: a failure like any other (DeviceError, zero force
    # first when it works again), and it does not escape close
    class Weird(PortHandle):
        bug = True

        def write(self, data):
            if self.bug:
                raise RuntimeError("driver bug")
            return PortHandle.write(self, data)

    h = Weird(Port())
    dev = HidDevice("open_haptic", h, clock=Clock())
    with pytest.raises(DeviceError, match="RuntimeError: driver bug"):
        dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    h.bug = False
    h.queue.append(oh_state(1))
    dev.read(0.0, s)
    assert_zero(decoded(dev.profile, h.port.wire)[0])
    assert s[0].valid
    h.bug = True
    dev.close()
    assert dev.closed and h.closed


def test_device_vanishes_and_comes_back_through_reopen():
    """Unplugged: every read raises, nothing is written, reopening is tried every REOPEN_INTERVAL_S
    (the old handle released first); plugged back: reopened by path, zero force first, then a
    fresh sample, then forces again; close leaves zero force."""
    port = Port()
    mod = PortModule(port)
    clock = Clock()
    dev = HidDevice.open("open_haptic", hid_module=mod, clock=clock)
    assert mod.opened == 1 and "/dev/hidraw4" in dev.label
    s = [DeviceSample()]
    t = 0.0
    for _ in range(10):
        t += 1e-3
        assert step(dev, port, clock, t, s) == 0
    first = port.handles[0]
    port.unplug()
    attempts0 = mod.enumerations  # a reopen first checks what the path is
    errors = 0
    n = len(port.wire)
    for _ in range(1000):  # 1 s without the device
        t += 1e-3
        errors += step(dev, port, clock, t, s)
    assert errors == 2000 and len(port.wire) == n  # every read and send failed; nothing got out
    attempts = mod.enumerations - attempts0
    assert 1000 * 1e-3 / REOPEN_INTERVAL_S - 1 <= attempts <= 1000 * 1e-3 / REOPEN_INTERVAL_S + 1
    assert first.closed  # released for the reopen (a hidraw node held open keeps its number)
    with pytest.raises(DeviceError, match="reopening the device every 0.2 s.*not connected"):
        dev.read(t, s)

    port.plug()
    back = None
    for k in range(400):
        t += 1e-3
        step(dev, port, clock, t, s)
        if back is None and len(port.wire) > n:
            back = k
    assert back is not None and back * 1e-3 <= REOPEN_INTERVAL_S + 0.002
    wire = decoded(dev.profile, port.wire[n:])
    assert_zero(wire[0])  # back: zero force first
    assert wire[-1]["fz"] == pytest.approx(5.0) and s[0].valid  # and rendering again
    assert dev.reopens == 1 and dev.recoveries == 1 and mod.opened == 2
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])
    assert all(h.closed for h in port.handles)
    finite_and_clamped(dev.profile, port.wire)


def test_reopen_refuses_another_device_at_the_same_path():
    """After an unplug the path may name another device (hidraw numbers are reused): it is not
    opened, nothing is written to it, and the original is reopened when it is back."""
    port = Port()
    mod = PortModule(port)
    clock = Clock()
    dev = HidDevice.open("open_haptic", hid_module=mod, clock=clock)
    s = [DeviceSample()]
    step(dev, port, clock, 0.0, s)
    port.unplug()
    stranger = Port(dict(OPEN_HAPTIC_INFO, vendor_id=0x046D, product_id=0xC52B, serial_number=""))
    mod.ports[PATH] = stranger
    t = 0.0
    for _ in range(500):
        t += 1e-3
        step(dev, port, clock, t, s)
    assert stranger.wire == [] and stranger.handles == []
    with pytest.raises(DeviceError, match="is now another device"):
        dev.read(t, s)
    mod.ports[PATH] = port
    port.plug()
    for _ in range(300):
        t += 1e-3
        step(dev, port, clock, t, s)
    assert s[0].valid and dev.recoveries == 1
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])


def test_given_transport_retries_and_says_once_it_will_not_reopen():
    """A device built on a given transport retries on it every read; after NO_REOPEN_NOTICE_ERRORS
    failures in a row its message says it will not be reopened (said once in the message, from
    then on); the same transport recovers when it works again."""
    dev, port, clock = direct()
    s = [DeviceSample()]
    step(dev, port, clock, 0.0, s)
    port.dead = True
    messages = []
    for k in range(2 * NO_REOPEN_NOTICE_ERRORS):
        clock.now += 1.0  # time alone does not make it reopen: it cannot
        try:
            dev.read(k, s)
        except DeviceError as exc:
            messages.append(str(exc))
    notice = "it will not be reopened"
    assert len(messages) == 2 * NO_REOPEN_NOTICE_ERRORS
    assert not any(notice in m for m in messages[:NO_REOPEN_NOTICE_ERRORS - 1])
    assert all(m.count(notice) == 1 for m in messages[NO_REOPEN_NOTICE_ERRORS:])
    assert port.write_failures >= 2 * NO_REOPEN_NOTICE_ERRORS - 1  # the zero-force report, every read
    port.dead = False
    step(dev, port, clock, 1e3, s)
    assert s[0].valid and dev.recoveries == 1 and dev.reopens == 0
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])


class PressingPort(Port):
    """A finger descending onto the box's top face (z = 0.06 m + 8 mm radius) and pressing 1 mm in."""

    def emit(self):
        if not self.silent and self.present:
            self.seq += 1
            report = oh_state(self.seq, z_um=max(57_000, 80_000 - 50 * self.seq))
            for h in self.handles:
                if h.alive():
                    h.queue.append(report)


def test_servo_loop_renders_again_after_the_transport_comes_back():
    """In the servo loop: a transport dead for 50 ticks costs zero force those ticks, then the
    finger renders the contact again; the run ends with zero force on the wire."""

    port = PressingPort()
    clock = Clock()
    dev = HidDevice("open_haptic", PortHandle(port), clock=clock)
    loop = box_loop(dev)

    def on_tick(_):
        clock.now += 0.001
        port.emit()

    port.emit()
    loop.run(600, on_tick=on_tick)
    assert max(r["fz"] for r in decoded(dev.profile, port.wire)) > 0.5
    port.dead = True
    n = len(port.wire)
    loop.run(50, on_tick=on_tick)
    assert loop.faults["device_error"] == 50 and len(port.wire) == n
    port.dead = False
    loop.run(100, on_tick=on_tick)
    after = decoded(dev.profile, port.wire[n:])
    assert_zero(after[0])
    assert max(r["fz"] for r in after) > 0.5 and dev.recoveries == 1
    assert (after[-1]["fx"], after[-1]["fy"], after[-1]["fz"]) == (0, 0, 0)  # a run ends with zero force
    dev.close()
    assert_zero(decoded(dev.profile, port.wire)[-1])
    finite_and_clamped(dev.profile, port.wire)


# ---------------------------------------------------------------------------------------------
# random failure schedules

WILD = [math.nan, math.inf, -math.inf, 1e308]


def run_schedule(seed, reopenable, steps=500, tail=300):
    """`steps` servo ticks (1 ms) under random failures, then `tail` clean ticks, then close().

    Failures: a transient read or write error (3 % of ticks each), outages of 1..120 ticks
    (1 % of ticks: the same handle dead for a given transport, the device unplugged - its
    handles dead for good - for a device opened by path), and firmware silences of 1..30
    ticks (2 %). The wrench is random, 2 % of it non-finite, and asked for on every tick,
    failed or not. close() itself meets random last failures: a read that just failed (the
    device is failed when closed), a pending transient write error, and for a device opened
    by path a replug just before (its handle dead).
    Checks while it runs: the first report that reaches the wire after a DeviceError is the
    zero-force one, and so is everything up to the next valid sample.
    Returns the device, the port, the number of failures injected and the device's
    (failures, recoveries) before close.
    """
    rng = np.random.default_rng(seed)
    port = Port()
    clock = Clock()
    if reopenable:
        mod = PortModule(port)
        dev = HidDevice.open("open_haptic", hid_module=mod, clock=clock)
    else:
        dev = HidDevice("open_haptic", PortHandle(port), clock=clock)
    s = [DeviceSample()]
    injected = outage = silence = 0
    awaiting = False  # a DeviceError was seen and no valid sample since
    zero_first = False  # a DeviceError was seen and nothing reached the wire since

    def check_wire(n):
        """Reports written by the last call: zero force first after a failure, and only zero
        force while awaiting a valid sample."""
        nonlocal zero_first
        new = decoded(dev.profile, port.wire[n:])
        if zero_first and new:
            assert_zero(new[0])
            zero_first = False
        if awaiting:
            for r in new:
                assert_zero(r)

    for k in range(steps + tail):
        if outage:
            outage -= 1
            if outage == 0:
                port.dead = False
                port.plug()
        elif k < steps:
            u = rng.random(4)
            if u[0] < 0.03:
                port.fail_reads = 1
                injected += 1
            if u[1] < 0.03:
                port.fail_writes = 1
                injected += 1
            if u[2] < 0.01 and k < steps - 120:
                outage = int(rng.integers(1, 121))
                injected += 1
                if reopenable:
                    port.unplug()
                else:
                    port.dead = True
            if u[3] < 0.02 and not silence:
                silence = int(rng.integers(1, 31))
        port.silent = silence > 0
        silence = max(0, silence - 1)
        clock.now += 0.001
        port.emit()
        n = len(port.wire)
        try:
            dev.read(k * 1e-3, s)
        except DeviceError:
            awaiting = zero_first = True
        check_wire(n)
        if s[0].valid:
            awaiting = False
        wrench = rng.uniform(-8.0, 8.0, 6)
        wrench[3:] *= 0.02
        if rng.random() < 0.02:
            wrench[int(rng.integers(6))] = WILD[int(rng.integers(len(WILD)))]
        n = len(port.wire)
        try:
            dev.send(0, *wrench.tolist())
        except DeviceError:
            awaiting = zero_first = True
        check_wire(n)
    before_close = (dev.failures, dev.recoveries)
    if rng.random() < 0.5:  # the last read failed: close() meets a failed device
        port.fail_reads = 1
        with pytest.raises(DeviceError):
            dev.read((steps + tail) * 1e-3, s)
        injected += 1
    if reopenable and rng.random() < 0.5:
        port.unplug()  # out and back in just before close: the device's handle is dead
        port.plug()
    port.fail_writes = int(rng.integers(0, 2))
    injected += port.fail_writes
    dev.close()
    return dev, port, injected, before_close


@pytest.mark.parametrize("reopenable", [False, True], ids=["given-transport", "opened-by-path"])
@pytest.mark.parametrize("seed", [1, 2, 3, 4])
def test_random_failure_schedules_end_at_zero_force(seed, reopenable):
    """Property, under random failures: after close() the last report that reached the device is
    the zero-force (enable = 0) one; no report ever carried a non-finite or unclamped field; every
    failure was recovered from (the schedule ends with 0.3 s of a working transport)."""
    dev, port, injected, (failures, recoveries) = run_schedule(seed, reopenable)
    wire = decoded(dev.profile, port.wire)
    print(f"\nseed {seed} {'opened by path' if reopenable else 'given transport'}: {len(wire)} reports "
          f"written, {injected} failures injected ({port.write_failures} failed writes), {failures} "
          f"failures seen before close(), {recoveries} recoveries, {dev.reopens} reopens")
    assert injected > 0 and failures > 0
    assert_zero(wire[-1])
    finite_and_clamped(dev.profile, port.wire)
    assert recoveries == failures
    assert any(r["enable"] == 1 and r["fz"] != 0.0 for r in wire[-200:])  # rendering again at the end
    assert all(h.closed for h in port.handles)


# ---------------------------------------------------------------------------------------------
# profiles: bounded limits, shadowing never silent


def _profile_text(**replace):
    text = (PROFILE_DIR / "open_haptic.toml").read_text()
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new, 1)
    return text


@pytest.mark.parametrize("old,new,field", [
    ("max_force = 5.0", "max_force = 1e6", "max_force"),
    ("max_force = 5.0", "max_force = 100.5", "max_force"),
    ("max_force = 5.0", "max_force = inf", "max_force"),
    ("max_force = 5.0", "max_force = nan", "max_force"),
    ("max_torque = 0.05", "max_torque = 11.0", "max_torque"),
    ("max_torque = 0.05", "max_torque = -inf", "max_torque"),
    ('x = { offset = 4, type = "int32", scale = 1e-6 }', 'x = { offset = 4, type = "int32", scale = 1e4 }',
     "input.report[0].fields.x.scale"),
    ('scale = 1000.0 }', 'scale = 1e10 }', "output.fields.fx.scale"),
    ('scale = 1000.0 }', 'scale = inf }', "output.fields.fx.scale"),
])
def test_profile_limits_are_bounded(tmp_path, old, new, field):
    """Non-finite or absurd limits are refused at load, in one line naming the file and the field."""
    path = tmp_path / "arm.toml"
    path.write_text(_profile_text(**{old: new}))
    with pytest.raises(ProfileError) as exc:
        load_profile(str(path))
    msg = str(exc.value)
    assert msg.startswith(f"{path}: {field} must be ") and "\n" not in msg, msg


def test_profile_limits_at_the_bounds_load(tmp_path):
    """The bounds themselves are allowed, and every shipped profile loads within them."""
    path = tmp_path / "strong.toml"
    path.write_text(_profile_text(**{"max_force = 5.0": f"max_force = {MAX_FORCE_N}",
                                     "max_torque = 0.05": f"max_torque = {MAX_TORQUE_NM}"}))
    p = load_profile(str(path))
    assert (p.max_force, p.max_torque) == (MAX_FORCE_N, MAX_TORQUE_NM)
    for f in PROFILE_DIR.glob("*.toml"):
        p = load_profile(str(f))
        assert p.max_force <= MAX_FORCE_N and p.max_torque <= MAX_TORQUE_NM


def test_shadowing_profile_wins_and_is_reported(tmp_path, monkeypatch):
    """A user profile named like a shipped one is the one used, and load_profiles and
    `softproxy devices` (text and JSON) say which file shadows which; a folder listed twice
    shadows nothing; a broken shadowing profile is an error, not a silent fallback."""
    monkeypatch.delenv(PROFILE_PATH_ENV, raising=False)
    assert load_profiles().shadowing == [] and load_profiles().errors == []

    user = tmp_path / "user"
    user.mkdir()
    (user / "open_haptic.toml").write_text(_profile_text(**{"max_force = 5.0": "max_force = 2.0"}))
    (user / "my_arm.toml").write_text(_profile_text(**{'name = "open_haptic"': 'name = "my_arm"'}))
    monkeypatch.setenv(PROFILE_PATH_ENV, f"{user}{__import__('os').pathsep}{user}")
    found = load_profiles()
    shadow = Shadowing("open_haptic", str(user / "open_haptic.toml"), str(PROFILE_DIR / "open_haptic.toml"))
    assert found.shadowing == [shadow] and found.errors == []
    by_name = {p.name: p for p in found.profiles}
    assert by_name["open_haptic"].max_force == 2.0 and "my_arm" in by_name
    assert load_profile("open_haptic").source == str(user / "open_haptic.toml")

    out, err = io.StringIO(), io.StringIO()
    assert devices_main(False, enumerate_fn=lambda: [], out=out, err=err) == 0
    lines = err.getvalue().splitlines()
    assert len(lines) == 1 and "warning" in lines[0] and "'open_haptic'" in lines[0]
    assert str(user / "open_haptic.toml") in lines[0] and str(PROFILE_DIR / "open_haptic.toml") in lines[0]
    out, err = io.StringIO(), io.StringIO()
    assert devices_main(True, enumerate_fn=lambda: [], out=out, err=err) == 0
    doc = json.loads(out.getvalue())
    assert [(d["name"], d["source"], d["shadowed"]) for d in doc["shadowing"]] == [tuple(shadow)]
    assert "warning" in err.getvalue()

    (user / "open_haptic.toml").write_text(_profile_text(**{"max_force = 5.0": "max_force = 1e6"}))
    found = load_profiles()
    assert found.shadowing == [shadow]
    assert len(found.errors) == 1 and "open_haptic.toml: max_force must be" in found.errors[0]
    assert "open_haptic" not in {p.name for p in found.profiles}  # not replaced by the shipped one silently
    with pytest.raises(ProfileError, match="max_force must be"):
        load_profile("open_haptic")
