"""Haply adapter (devices/haply.py) against a fake of the HaplyHardwareAPI binding
(tests/fake_haply.py, checked against the installed wheel below): frames and units, the
VerseGrip's frame, twist and buttons, the limits, and the safety properties of the other
adapters - zero force on every way out, every command finite and clamped, garbage readings
invalid, a device that fails mid-run renders zero and is reopened (the same one only), a
stalled loop leaves zero force, close() from any thread never raises and is the last word."""

import ast
import gc
import inspect
import math
import re
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
import fake_haply  # noqa: E402
from fake_haply import FakeHaply, GripHardware, Inverse3Hardware  # noqa: E402

from conftest import Clock, box_loop  # noqa: E402

from softproxy.device import DeviceError, DeviceSample, check_device  # noqa: E402
from softproxy.devices import haply as hmod  # noqa: E402
from softproxy.devices.haply import CLOSE_ZERO_ATTEMPTS, REOPEN_INTERVAL_S, HaplyDevice  # noqa: E402


def make(with_grip=True, **kwargs):
    """A device over a fake Inverse3 (and a VerseGrip unless with_grip=False), threads left to the test."""
    kwargs.setdefault("stall_ms", 0)
    hw = Inverse3Hardware()
    g = GripHardware()
    api = FakeHaply(hw, grips=(g,) if with_grip else ())
    clock = Clock(10.0)
    dev = HaplyDevice(api, clock=clock, start_threads=False, **kwargs)
    return dev, api, hw, g, clock


def tick(dev, s, clock, t=0.0):
    """One servo tick's read, the grip's thread having read the grip once just before."""
    clock.now += 0.001
    dev._grip_once()
    dev.read(t, s)


def assert_finite_and_clamped(dev, wire):
    for f in wire:
        assert len(f) == 3 and all(isinstance(c, float) and math.isfinite(c) for c in f), f
        assert np.linalg.norm(f) <= dev.max_force * (1 + 1e-12)


def zero(f):
    return list(f) == [0.0, 0.0, 0.0]


# ---------------------------------------------------------------------------------------------
# the fake against the wheel

def _wheel_signatures(doc: str, name: str) -> list[list[tuple[str, object]]]:
    """Every overload of `name` in a pybind11 docstring, as [(parameter, default or None)]
    without `self`; a default is the literal the docstring shows."""
    found = []
    for m in re.finditer(rf"{re.escape(name)}\((.*?)\) ->", doc):
        params, depth, cur = [], 0, ""
        for ch in m.group(1) + ",":
            if ch == "," and depth == 0:
                params.append(cur.strip())
                cur = ""
                continue
            depth += ch in "[(" or -(ch in "])")
            cur += ch
        out = []
        for p in params:
            if not p or p.startswith("self:") or p == "self":
                continue
            head, _, default = p.partition(" = ")
            out.append((head.split(":")[0].strip(), ast.literal_eval(default) if default else None))
        found.append(out)
    return found


def _fake_signature(fn) -> list[tuple[str, object]]:
    params = [p for p in inspect.signature(fn).parameters.values() if p.name != "self"]
    return [(p.name, None if p.default is inspect.Parameter.empty else p.default) for p in params]


def test_the_fake_mirrors_the_installed_wheel(tmp_path):
    """Every function and method the fake gives (the ones the adapter calls) exists in the
    wheel with the same parameters (name where the wheel names it, count, defaults); and on a
    port with nothing behind it the wheel answers as the fake does: no exception, the wake-up
    and grip status with the fake's keys, two zero vectors from end_effector_force."""
    real = pytest.importorskip("HaplyHardwareAPI", reason="the haplyhardwareapi wheel is not installed "
                               "(pip install 'softproxy[haply]'; CPython 3.11 on Linux x86-64 only)")
    for name in ("detect_inverse3s", "detect_handles", "detect_wired_handles", "detect_wireless_handles",
                 "get_cpp_version"):
        assert _fake_signature(getattr(FakeHaply, name)) in _wheel_signatures(getattr(real, name).__doc__, name)
    for cls in ("SerialStream", "Inverse3", "Handle"):
        fake_cls, real_cls = getattr(fake_haply, cls), getattr(real, cls)
        for name, fn in vars(fake_cls).items():
            if not callable(fn) or (name.startswith("_") and name != "__init__"):
                continue
            assert hasattr(real_cls, name), f"{cls}.{name} is not in the wheel"
            ours = _fake_signature(fn)
            theirs = _wheel_signatures(getattr(real_cls, name).__doc__, name)
            assert any(len(o) == len(ours) and all(d1 == d2 and (n1 == n2 or not n1.isidentifier())
                                                   for (n1, d1), (n2, d2) in zip(o, ours)) for o in theirs), \
                f"{cls}.{name}: ours {ours}, the wheel's {theirs}"

    port = str(tmp_path / "ttyNothing")
    stream = real.SerialStream(port)  # no exception: the binding prints and carries on
    arm = real.Inverse3(stream, 0.02)
    assert set(arm.device_wakeup_dict()) == set(fake_haply.WAKEUP_KEYS)
    assert arm.end_effector_force([0.0, 0.0, 0.0]) == ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    assert arm.get_power_status() is False
    status = real.Handle(stream).GetVersegripStatus()
    assert set(status) == set(fake_haply.GRIP_KEYS)
    assert status["error_flag"] == fake_haply.NO_ANSWER_FLAG and status["quaternion"] == [0.0, 0.0, 0.0, 0.0]
    fake = FakeHaply()
    fake_stream = fake.SerialStream(port)
    assert fake.Inverse3(fake_stream, 0.02).end_effector_force() == ([0.0, 0.0, 0.0], [0.0, 0.0, 0.0])
    assert set(fake.Handle(fake_stream).GetVersegripStatus()) == set(status)


# ---------------------------------------------------------------------------------------------
# frames, units, limits

def test_position_grip_frame_twist_and_buttons_in_the_engine_frame():
    """The Inverse3's frame (x right, y away from the operator, z up, m) is the engine's:
    positions are scaled then offset; the VerseGrip's quaternion is the finger's frame, its
    rotation about the twist axis the twist (unwrapped past ±pi), its buttons pass through;
    the velocity is kept, scaled; forces go out unchanged (N)."""
    dev, api, hw, g, clock = make(workspace_scale=2.0, workspace_offset=(0.0, 0.0, 0.1))
    hw.position, hw.velocity = [0.01, -0.12, 0.15], [0.1, 0.0, -0.2]
    g.quaternion = [math.cos(0.15), 0.0, 0.0, math.sin(0.15)]  # 0.3 rad about z
    g.buttons = 5
    s = [DeviceSample()]
    tick(dev, s, clock)
    assert s[0].valid and (s[0].x, s[0].y, s[0].z) == pytest.approx((0.02, -0.24, 0.4))
    assert (s[0].qw, s[0].qx, s[0].qy, s[0].qz) == pytest.approx((math.cos(0.15), 0.0, 0.0, math.sin(0.15)))
    assert s[0].twist == pytest.approx(0.0) and s[0].buttons == 5  # counted from the first reading
    assert dev.velocity == pytest.approx((0.2, 0.0, -0.4))
    for k in range(1, 13):  # turned on about z, 0.5 rad a tick: past pi, no jump
        a = 0.3 + 0.5 * k
        g.quaternion = [math.cos(a / 2), 0.0, 0.0, math.sin(a / 2)]
        tick(dev, s, clock)
        assert s[0].twist == pytest.approx(0.5 * k)
    dev.send(0, 1.0, -0.5, 0.25, 0.3, 0.0, 0.0)  # the torque is dropped: 3-DOF
    assert hw.wire[-1] == pytest.approx([1.0, -0.5, 0.25])
    check_device(dev)
    assert dev.max_torque == 0.0 and dev.fingers == 1


def test_without_a_grip_the_frame_is_the_identity():
    """grip=off (or none detected with auto): the position alone, the identity frame, no twist."""
    for dev, api, hw, g, clock in (make(with_grip=False), make(grip="off")):
        assert dev.grip_port is None
        s = [DeviceSample()]
        tick(dev, s, clock)
        assert s[0].valid and (s[0].qw, s[0].qx, s[0].qy, s[0].qz) == (1.0, 0.0, 0.0, 0.0) and s[0].twist == 0.0


def test_limits_default_lowered_and_refused_above_the_ceiling():
    """The default limit, a lower one, and one above the ceiling refused in one line; every
    command within the limit."""
    dev, api, hw, g, clock = make()
    assert dev.max_force == hmod.DEFAULT_MAX_FORCE_N
    dev, api, hw, g, clock = make(max_force=1.0)
    tick(dev, [DeviceSample()], clock)
    dev.send(0, 0.0, 30.0, 40.0, 0.0, 0.0, 0.0)
    assert hw.wire[-1] == pytest.approx([0.0, 0.6, 0.8])
    with pytest.raises(ValueError, match=r"max_force must be a finite number in \[0, 3.3\]"):
        make(max_force=10.0)


def test_every_command_is_finite_and_clamped():
    """Random forces, 5 % with NaN/Inf and some finite but so large their norm overflows: every
    force that reaches the motors is 3 finite floats within the limit; the bad ones are counted
    and go out as zero."""
    rng = np.random.default_rng(3)
    dev, api, hw, g, clock = make(max_force=1.5)
    s = [DeviceSample()]
    for k in range(400):
        tick(dev, s, clock, k * 1e-3)
        f = rng.uniform(-40.0, 40.0, 3)
        if rng.random() < 0.05:
            f[rng.integers(3)] = [math.nan, math.inf, -math.inf][rng.integers(3)]
        if rng.random() < 0.02:
            f[:] = 1e308
        dev.send(0, *f.tolist(), 0.0, 0.0, 0.0)
    assert dev.nan_sends > 0
    assert_finite_and_clamped(dev, hw.wire)
    assert max(np.linalg.norm(f) for f in hw.wire) == pytest.approx(1.5)


# ---------------------------------------------------------------------------------------------
# bad readings

@pytest.mark.parametrize("garbage", ["nan", "none"])
def test_garbage_readings_are_invalid_samples_never_a_force(garbage):
    """NaN or None from the Inverse3 or the grip, a position out of the arm's reach, a grip
    quaternion that is none: the sample is invalid and counted; readings coming back are valid."""
    dev, api, hw, g, clock = make()
    s = [DeviceSample()]
    tick(dev, s, clock)
    assert s[0].valid
    api.garbage = garbage
    tick(dev, s, clock)
    assert not s[0].valid and dev.invalid_samples >= 1
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert_finite_and_clamped(dev, hw.wire)
    api.garbage = None
    hw.position = [0.0, -2.0, 0.1]  # 2 m out: no reading of this arm
    tick(dev, s, clock)
    assert not s[0].valid
    hw.position = [0.0, -0.12, 0.15]
    g.quaternion = [0.2, 0.0, 0.0, 0.0]  # no unit quaternion: dropped, the grip goes stale
    for _ in range(150):
        tick(dev, s, clock)
    assert not s[0].valid and dev.grip_errors > 0 and dev.grip_stale_samples > 0
    g.quaternion = [1.0, 0.0, 0.0, 0.0]
    tick(dev, s, clock)
    assert s[0].valid and s[0].is_finite()


def test_a_stale_or_foreign_grip_makes_the_sample_invalid_and_is_reopened():
    """The grip stops answering: after grip_stale_ms the samples are invalid (zero force), the
    grip's port is opened again after REOPEN_INTERVAL_S of errors; a different VerseGrip's
    readings are dropped; the grip coming back makes samples valid again."""
    dev, api, hw, g, clock = make()
    s = [DeviceSample()]
    tick(dev, s, clock)
    g.silent = True
    clock.now += 0.05
    dev.read(0.0, s)
    assert s[0].valid  # 50 ms old: still fresh
    for _ in range(300):  # 0.3 s of silence
        tick(dev, s, clock)
    assert not s[0].valid and dev.grip_reopens >= 1
    g.silent = False
    g.device_id = 0x77  # another grip on that transceiver
    for _ in range(10):
        tick(dev, s, clock)
    assert not s[0].valid
    g.device_id = 0x2A
    tick(dev, s, clock)
    assert s[0].valid


def test_the_grip_thread_fills_the_slot():
    """With its threads started, the grip is read by its own thread (no tick needed)."""
    api = FakeHaply(Inverse3Hardware(), grips=(GripHardware(),))
    dev = HaplyDevice(api, stall_ms=0)
    try:
        deadline = time.monotonic() + 60.0  # a hang guard only
        while dev._grip_latest is None and time.monotonic() < deadline:
            time.sleep(0.005)
        s = [DeviceSample()]
        dev.read(0.0, s)
        assert s[0].valid
    finally:
        dev.close()


# ---------------------------------------------------------------------------------------------
# failures and recovery

@pytest.mark.parametrize("how", ["silent", "raise"])
def test_a_failure_renders_zero_then_reopens_then_waits_for_a_clean_sample(how):
    """The Inverse3 stops answering (or a call raises): DeviceError naming why, one zero force
    tried, nothing else written while failed; after REOPEN_INTERVAL_S it is opened again (its
    zero force answered), and forces render again only after a clean sample."""
    dev, api, hw, g, clock = make()
    s = [DeviceSample()]
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    n = len(hw.wire)
    if how == "silent":
        hw.silent = True
    else:
        api.raise_in.add("end_effector_force")
    with pytest.raises(DeviceError, match="failed while reading.*(no answer within 20 ms|serial I/O error)") as e:
        tick(dev, s, clock)
    assert "\n" not in str(e.value)
    with pytest.raises(DeviceError):
        dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    for _ in range(50):  # 50 ms: no reopen yet
        with pytest.raises(DeviceError):
            tick(dev, s, clock)
    assert all(zero(f) for f in hw.wire[n:])
    hw.silent = False
    api.raise_in.clear()
    api.garbage = "nan"  # back, but the first reading is garbage: still no force
    clock.now += REOPEN_INTERVAL_S
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert dev.reopens == 1 and not s[0].valid and all(zero(f) for f in hw.wire[n:])
    api.garbage = None
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert s[0].valid and dev.recoveries == 1 and dev.failures == 1
    assert hw.wire[-1] == pytest.approx([0.0, 0.0, 1.0])


def test_unplugged_device_is_reopened_and_must_be_the_same_one():
    """Unplugged: reads raise, reopening is tried every REOPEN_INTERVAL_S; plugged back it is
    opened again, zero force first; another Inverse3 where it was (another UUID) is refused."""
    dev, api, hw, g, clock = make()
    s = [DeviceSample()]
    tick(dev, s, clock)
    api.unplug(hw)
    with pytest.raises(DeviceError, match="failed while reading"):
        tick(dev, s, clock)
    clock.now += REOPEN_INTERVAL_S
    with pytest.raises(DeviceError, match="last reopen: cannot open a Haply Inverse3: 0 detected"):
        tick(dev, s, clock)
    api.plug(hw)
    n = len(hw.wire)
    clock.now += REOPEN_INTERVAL_S
    tick(dev, s, clock)
    assert s[0].valid and dev.reopens == 1 and dev.recoveries == 1 and zero(hw.wire[n])

    api.unplug(hw)
    with pytest.raises(DeviceError):
        tick(dev, s, clock)
    other = Inverse3Hardware(port=hw.port, serial_uuid="00000000-0000-4000-8000-000000000001")
    api.devices = [other]  # another Inverse3 on the same port
    clock.now += 2 * REOPEN_INTERVAL_S
    with pytest.raises(DeviceError, match="not the same one"):
        tick(dev, s, clock)
    assert all(zero(f) for f in other.wire)
    dev.close()


def test_a_failed_send_tries_zero_force_before_it_drops_the_link():
    """A send whose exchange raises: the adapter's last word on that link is a zero force (the
    link may still carry the old one), then nothing until the device is reopened."""
    dev, api, hw, g, clock = make()
    s = [DeviceSample()]
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)

    def refuse_force(force):
        if any(force):
            raise RuntimeError("serial write failed")

    hw.exchange_hook = refuse_force
    with pytest.raises(DeviceError, match="failed while sending a force.*serial write failed"):
        dev.send(0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    assert zero(hw.wire[-1]) and dev._link is None
    n = len(hw.wire)
    with pytest.raises(DeviceError):
        tick(dev, s, clock)
    assert len(hw.wire) == n


def test_power_status_is_read_at_open():
    """The device's power status, read at open, is `powered` (False: its motors render nothing)."""
    dev, api, hw, g, clock = make()
    assert dev.powered is True
    hw2 = Inverse3Hardware()
    hw2.powered = False
    assert HaplyDevice(FakeHaply(hw2), start_threads=False).powered is False


def test_opening_names_what_to_check():
    """No Inverse3 detected, an index past them, a port that does not exist, one that does not
    answer: DeviceError, one line each, nothing left driven."""
    with pytest.raises(DeviceError, match="cannot open a Haply Inverse3: 0 detected") as e:
        HaplyDevice(_none(), start_threads=False)
    assert "\n" not in str(e.value)
    api = FakeHaply(Inverse3Hardware())
    with pytest.raises(DeviceError, match="at index 3: 1 detected"):
        HaplyDevice(api, index=3, start_threads=False)
    with pytest.raises(DeviceError, match="on /dev/nonexistent-haply: no such port"):
        HaplyDevice(api, port="/dev/nonexistent-haply", start_threads=False)
    api.devices[0].silent = True
    with pytest.raises(DeviceError, match="on /dev/ttyACM0: it did not answer"):
        HaplyDevice(api, start_threads=False)


def _none():
    api = FakeHaply(Inverse3Hardware())
    api.unplug(api.devices[0])
    return api


def test_the_streams_outlive_their_devices():
    """The binding keeps raw pointers to its streams: the adapter holds each pair, so after a
    collection every call still reaches a live stream (the fake raises where the wheel crashes)."""
    dev, api, hw, g, clock = make()
    gc.collect()
    s = [DeviceSample()]
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    assert s[0].valid and dev.errors == 0 and dev.grip_errors == 0


# ---------------------------------------------------------------------------------------------
# ways out

def test_close_always_tries_zero_force_and_never_raises():
    """close(): zero force is the last command; a failed device gets zero force too (reopened
    for it); a dead one gets CLOSE_ZERO_ATTEMPTS tries and no exception; close() twice is
    harmless; a closed device refuses reads and sends."""
    dev, api, hw, g, clock = make()
    s = [DeviceSample()]
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    dev.close()
    assert zero(hw.wire[-1]) and dev._link is None and dev._grip_link is None
    dev.close()
    with pytest.raises(DeviceError, match="closed"):
        dev.read(0.0, s)
    with pytest.raises(DeviceError, match="closed"):
        dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)

    dev, api, hw, g, clock = make()
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    api.raise_in.add("end_effector_force")
    dev.close()
    assert api.calls.count("end_effector_force") >= CLOSE_ZERO_ATTEMPTS
    assert hw.wire[-1] == pytest.approx([0.0, 0.0, 1.5])  # what only the device's own safety can stop

    dev, api, hw, g, clock = make()
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.5, 0.0, 0.0, 0.0)
    api.raise_in.add("end_effector_force")
    with pytest.raises(DeviceError):
        dev.read(0.0, s)
    api.raise_in.clear()
    dev.close()  # failed, link dropped: close reopens to write zero
    assert zero(hw.wire[-1])


def test_a_close_from_another_thread_never_lets_a_command_land_after_its_zero():
    """close() from another thread while a send is in the binding: the send's force lands
    first, then close()'s zero; the last force on the device is zero."""
    dev, api, hw, g, clock = make()
    tick(dev, [DeviceSample()], clock)
    closer = threading.Thread(target=dev.close)

    def close_meanwhile(force):
        if any(force) and not closer.is_alive() and not dev.closed:
            closer.start()
            closer.join(0.2)  # without the lock, close() runs to its end here

    hw.exchange_hook = close_meanwhile
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    closer.join(5.0)
    assert dev.closed and not closer.is_alive()
    assert hw.wire[-2] == pytest.approx([0.0, 0.0, 1.0]) and zero(hw.wire[-1])


def test_a_device_left_open_is_zeroed_at_exit():
    dev, api, hw, g, clock = make()
    tick(dev, [DeviceSample()], clock)
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    hmod._OPEN.close_all()
    assert dev.closed and zero(hw.wire[-1])


def test_a_stalled_loop_leaves_zero_force_not_its_last():
    """A non-zero force not renewed for stall_ms is replaced by zero (once, counted), and a read
    re-sends zero, not the old force; a fresh send renders again; a closed device is left
    alone. Then the watchdog's own thread, on a real 20 ms stall."""
    dev, api, hw, g, clock = make(stall_ms=1000)  # its thread is not started: the checks are driven here
    s = [DeviceSample()]
    tick(dev, s, clock)
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    sent_at, n = dev._command_at, len(hw.wire)
    dev._watch_once(now=sent_at + 0.9)
    assert len(hw.wire) == n
    dev._watch_once(now=sent_at + 1.1)
    assert zero(hw.wire[-1]) and dev.stall_zeroes == 1 and len(hw.wire) == n + 1
    dev._watch_once(now=sent_at + 5.0)
    assert len(hw.wire) == n + 1  # zero already
    tick(dev, s, clock)
    assert zero(hw.wire[-1])
    dev.send(0, 0.0, 0.0, 0.7, 0.0, 0.0, 0.0)
    assert hw.wire[-1] == pytest.approx([0.0, 0.0, 0.7])
    dev.close()
    n = len(hw.wire)
    dev._watch_once(now=sent_at + 100.0)
    assert len(hw.wire) == n

    api = FakeHaply(Inverse3Hardware())
    dev = HaplyDevice(api, stall_ms=20, grip="off")
    dev.read(0.0, [DeviceSample()])
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    deadline = time.monotonic() + 60.0  # a hang guard: the watcher acts after 20 ms, load can delay it
    while dev.stall_zeroes == 0 and time.monotonic() < deadline:
        time.sleep(0.005)
    assert dev.stall_zeroes == 1 and zero(api.devices[0].wire[-1])
    dev.close()


# ---------------------------------------------------------------------------------------------
# configuration, discovery

def test_missing_binding_is_one_line_naming_the_extra(monkeypatch):
    def no_module(name):
        raise ModuleNotFoundError(f"No module named {name!r}", name=name)

    monkeypatch.setattr(hmod.importlib, "import_module", no_module)
    with pytest.raises(DeviceError) as e:
        HaplyDevice()
    assert "pip install 'softproxy[haply]'" in str(e.value) and "\n" not in str(e.value)
    row = hmod.availability()
    assert row["binding"] is False and "pip install" in row["message"]

    def wrong_platform(name):
        raise ImportError("HaplyHardwareAPI.cpython-311-x86_64-linux-gnu.so: wrong ELF class")

    monkeypatch.setattr(hmod.importlib, "import_module", wrong_platform)
    with pytest.raises(DeviceError, match="cannot load.*CPython 3.11 on Linux x86-64"):
        HaplyDevice()


def test_availability_lists_the_ports_and_softproxy_devices_shows_them(monkeypatch, capsys):
    import json

    from softproxy.cli import main

    api = FakeHaply(Inverse3Hardware("/dev/ttyACM0"), Inverse3Hardware("/dev/ttyACM2", device_id=5),
                    grips=(GripHardware("/dev/ttyACM1"),))
    row = hmod.availability(api)
    assert (row["binding"], row["sdk"], row["devices"]) == (True, True, 2)
    assert row["ports"] == {"inverse3": ["/dev/ttyACM0", "/dev/ttyACM2"], "versegrip": ["/dev/ttyACM1"]}
    assert "2 Inverse3 (/dev/ttyACM0, /dev/ttyACM2), 1 VerseGrip (/dev/ttyACM1)" == row["message"]
    assert "udev" in hmod.availability(_none())["message"]
    monkeypatch.setattr(hmod, "load_binding", lambda: api)
    main(["devices", "--json"])
    doc = json.loads(capsys.readouterr().out)
    haply = next(b for b in doc["backends"] if b["backend"] == "haply")
    assert haply["devices"] == 2


def test_configuration_from_a_scene_table_and_the_argument():
    """`--device haply:1,grip=off,...` and `haply:/dev/ttyACM2`; mistakes name the flag or field."""
    api = FakeHaply(Inverse3Hardware("/dev/ttyACM0"), Inverse3Hardware("/dev/ttyACM2", device_id=5),
                    grips=(GripHardware("/dev/ttyACM1"),))
    dev = HaplyDevice.from_argument("1,grip=off,workspace_offset=0:0:0.05,max_force_N=1.5", binding=api,
                                    start_threads=False)
    assert (dev.port, dev.grip_port, dev.workspace_offset, dev.max_force) == ("/dev/ttyACM2", None,
                                                                              (0.0, 0.0, 0.05), 1.5)
    dev.close()
    dev = HaplyDevice.from_argument("/dev/ttyACM2,twist_axis=x", binding=api, start_threads=False)
    assert (dev.device_id, dev.grip_port) == (5, "/dev/ttyACM1")
    dev.close()
    dev = HaplyDevice.from_config({"type": "haply"}, binding=api, start_threads=False)
    assert dev.port == "/dev/ttyACM0" and dev.label == "Haply Inverse3 049D (/dev/ttyACM0)"
    dev.close()
    with pytest.raises(ValueError, match=r"--device haply:twist_axis=w: device.twist_axis must be"):
        HaplyDevice.from_argument("twist_axis=w", binding=api)
    with pytest.raises(ValueError, match=r"scene.toml: device has unknown field\(s\) \['profile'\]"):
        HaplyDevice.from_config({"type": "haply", "profile": "x"}, source="scene.toml", binding=api)
    with pytest.raises(ValueError, match=r"scene.toml: max_force must be a finite number in \[0, 3.3\]"):
        HaplyDevice.from_config({"type": "haply", "max_force_N": 50.0}, source="scene.toml", binding=api)
    with pytest.raises(ValueError, match="device.index and device.port both choose a device"):
        HaplyDevice.from_config({"type": "haply", "index": 0, "port": "/dev/ttyACM0"}, source="s", binding=api)
    with pytest.raises(ValueError, match="timeout_ms"):
        HaplyDevice(api, timeout_ms=0)


# ---------------------------------------------------------------------------------------------
# in the servo loop

def test_servo_loop_presses_survives_a_failure_and_ends_at_zero_force():
    """A ServoLoop drives the fake Inverse3 down onto a box: it renders the contact, a device
    silent for 50 ticks costs zero force (counted), it renders again after, and the run and
    the close end with zero force."""

    dev, api, hw, g, clock = make(with_grip=False)
    hw.position = [0.0, 0.0, 0.08]  # above the box (top at 0.06 m, finger radius 8 mm)
    loop = box_loop(dev)
    ticks = [0]

    def on_tick(_):
        ticks[0] += 1
        clock.now += 0.001
        hw.position = [0.0, 0.0, max(0.066, 0.08 - 5e-5 * ticks[0])]  # 2 mm in

    loop.run(600, on_tick=on_tick)
    assert max(f[2] for f in hw.wire) > 0.5
    hw.silent = True
    n = len(hw.wire)
    loop.run(50, on_tick=on_tick)
    assert loop.faults["device_error"] == 50 and all(zero(f) for f in hw.wire[n:])
    hw.silent = False
    loop.run(300, on_tick=on_tick)
    assert max(f[2] for f in hw.wire[n:]) > 0.5 and dev.recoveries == 1
    assert zero(hw.wire[-1])
    loop.close()
    assert zero(hw.wire[-1]) and dev.closed
    assert_finite_and_clamped(dev, hw.wire)


def test_a_scene_runs_through_the_entry_point(monkeypatch):
    """`--device haply:...` reaches the adapter through the `softproxy.devices` entry point and
    a scene runs 0.2 s on it: every command finite and clamped, zero force at the end."""
    from softproxy.run import check_device_fingers, open_device, run_scene
    from softproxy.scene import load_scene

    hw = Inverse3Hardware()
    hw.position = [0.0, 0.0, 0.08]
    api = FakeHaply(hw, grips=(GripHardware(),))
    monkeypatch.setattr(hmod, "load_binding", lambda: api)
    scene = load_scene("knob")
    dev = open_device("haply:max_force_N=1.0,stall_ms=0", scene)
    assert isinstance(dev, HaplyDevice) and dev.max_force == 1.0
    check_device_fingers(scene, dev, "test")
    deadline = time.monotonic() + 60.0  # the grip's own thread fills its slot first (a hang guard)
    while dev._grip_latest is None and time.monotonic() < deadline:
        time.sleep(0.005)
    try:
        result = run_scene(scene, dev, duration_s=0.2)
    finally:
        dev.close()
    assert result["faults"]["device_error"] == 0
    assert zero(hw.wire[-1])
    assert_finite_and_clamped(dev, hw.wire)


@pytest.mark.parametrize("seed", [1, 2])
def test_random_failure_schedules_end_at_zero_force(seed):
    """Property, under random failures (silence, raising calls, unplugs of 1..100 ticks, garbage
    readings, a silent grip) and random forces, 2 % non-finite: while failed nothing but zero
    goes out; every force is finite and clamped; every failure is recovered from; after
    close() the last force is zero."""
    rng = np.random.default_rng(seed)
    dev, api, hw, g, clock = make(max_force=2.0)
    s = [DeviceSample()]
    outage = 0
    awaiting = False
    for k in range(1500):
        api.raise_in.clear()
        api.garbage = None
        hw.silent = g.silent = False
        if outage:
            outage -= 1
            if outage == 0:
                api.plug(hw)
        elif k < 1200:
            u = rng.random(5)
            if u[0] < 0.02:
                hw.silent = True
            if u[1] < 0.02:
                api.raise_in.add("end_effector_force")
            if u[2] < 0.01:
                outage = int(rng.integers(1, 101))
                api.unplug(hw)
            if u[3] < 0.02:
                api.garbage = "nan"
            if u[4] < 0.02:
                g.silent = True
        n = len(hw.wire)
        try:
            tick(dev, s, clock, k * 1e-3)
        except DeviceError:
            awaiting = True
        if s[0].valid:
            awaiting = False
        f = rng.uniform(-5.0, 5.0, 3)
        if rng.random() < 0.02:
            f[rng.integers(3)] = math.nan
        try:
            dev.send(0, *f.tolist(), 0.0, 0.0, 0.0)
        except DeviceError:
            awaiting = True
        if awaiting:
            assert all(zero(c) for c in hw.wire[n:])
    assert dev.failures >= 2 and dev.recoveries == dev.failures  # each failure lasts a reopen interval at least
    assert any(not zero(c) for c in hw.wire[-100:])
    dev.close()
    assert zero(hw.wire[-1])
    assert_finite_and_clamped(dev, hw.wire)
