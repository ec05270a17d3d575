"""Several devices in one servo loop (issue 45): the bimanual hand-over, fault isolation between
devices, zero and close for every device on the way out, and device-aware stiffness."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from softproxy.device import DeviceError
from softproxy.device_group import DeviceGroup
from softproxy.run import build, open_device
from softproxy.scene import load_scene
from softproxy.servo import ServoLoop
from softproxy.stiffness_cap import cap_fingers


def _scene_devices(scene, **extra):
    """The scene's simulated devices, one per [[device]] table (with `extra` config merged in)."""
    return [open_device("sim", scene, {**table, **extra}, source="test") for table in scene.devices]


class FailingAfter:
    """Wraps a device: its read raises DeviceError from loop time `t_fail` on (an unplugged cable)."""

    def __init__(self, device, t_fail: float) -> None:
        self.inner, self.t_fail = device, t_fail
        self.fingers, self.max_force, self.max_torque = device.fingers, device.max_force, device.max_torque
        self.closed = False
        self.raised = 0

    def read(self, t, samples):
        if t >= self.t_fail:
            self.raised += 1
            raise DeviceError("cable pulled")
        self.inner.read(t, samples)

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.inner.send(finger, fx, fy, fz, tx, ty, tz)

    def close(self):
        self.closed = True
        self.inner.close()


def _ticks(loop, seconds: float) -> None:
    """Tick the loop for `seconds` of loop time (tick by tick: `run` ends with zero force)."""
    for _ in range(int(round(seconds * loop.rate_hz))):
        loop.tick()


def _box(loop):
    body = loop.world.body_id("box")
    return loop.world.data.xpos[body].copy()


def test_bimanual_hand_over():
    """Hand A lifts the cube, hand B takes it and carries it 8 cm along y: at the end the cube is
    aloft (it rests at z = 0.02 m if dropped), 8 cm along y (it stays at y = 0 unless B carried
    it), A's fingers touch nothing and B's hold it."""
    scene = load_scene("bimanual_grasp")
    with build(scene, _scene_devices(scene), realtime=False) as loop:
        _ticks(loop, 3.0)
        held = _box(loop)
        a, b = loop.fingers[:2], loop.fingers[2:]
        assert held[2] > 0.07  # lifted by A (and B)
        assert all(f.body >= 0 for f in loop.fingers)  # both hands on it before A lets go
        _ticks(loop, 2.0)
        end = _box(loop)
        assert end[2] > 0.07
        assert 0.07 < end[1] < 0.09
        assert not any(f.body >= 0 for f in a)
        assert all(f.body >= 0 and 1.0 < abs(f.normal_force) < 6.0 for f in b)
        assert loop.faults["device_error"] == 0 and loop.faults["invalid_sample"] == 0


def test_fault_on_one_device_zeroes_only_its_fingers():
    """Device 0 (hand A) fails while both hands hold the cube: its fingers render zero and its
    device is sent zero, while hand B keeps rendering and keeps the cube aloft."""
    scene = load_scene("bimanual_grasp")
    a_dev, b_dev = _scene_devices(scene)
    failing = FailingAfter(a_dev, 2.5)
    with build(scene, [failing, b_dev], realtime=False) as loop:
        _ticks(loop, 3.0)
        group = loop.device
        assert isinstance(group, DeviceGroup)
        assert failing.raised > 400 and group.read_failures == [failing.raised, 0]
        assert group.last_errors[0] == "cable pulled"
        assert loop.faults["device_error"] == 0  # not the whole read: one device's
        a, b = loop.fingers[:2], loop.fingers[2:]
        assert all((f.fx, f.fy, f.fz) == (0.0, 0.0, 0.0) for f in a)
        assert a_dev.last_force == [(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)]
        assert all(f.body >= 0 and abs(f.normal_force) > 1.0 for f in b)
        assert all(max(abs(c) for c in force) > 1.0 for force in b_dev.last_force)
        assert _box(loop)[2] > 0.07  # B alone holds it


def test_every_device_failing_is_a_device_error():
    """When every device's read fails the tick is a device_error, as with one device."""
    scene = load_scene("bimanual_grasp")
    devices = [FailingAfter(d, 0.0) for d in _scene_devices(scene)]
    with build(scene, devices, realtime=False) as loop:
        loop.run(10)
        assert loop.faults["device_error"] >= 10
        assert "device 0: cable pulled" in loop.last_device_error


class Recording:
    """Wraps a device: keeps every send, optionally raising on sends or close."""

    def __init__(self, device, send_raises=False, close_raises=False) -> None:
        self.inner, self.sent, self.closed = device, [], False
        self.fingers, self.max_force, self.max_torque = device.fingers, device.max_force, device.max_torque
        self.send_raises, self.close_raises = send_raises, close_raises

    def read(self, t, samples):
        self.inner.read(t, samples)

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.sent.append((finger, fx, fy, fz, tx, ty, tz))
        if self.send_raises:
            raise DeviceError("send refused")
        self.inner.send(finger, fx, fy, fz, tx, ty, tz)

    def close(self):
        self.closed = True
        self.inner.close()
        if self.close_raises:
            raise DeviceError("close refused")


def test_close_zeroes_and_closes_every_device_whatever_one_raises():
    """Leaving the loop sends zero to every finger of every device, last, and closes both devices
    though the first one's sends and close raise."""
    scene = load_scene("bimanual_grasp")
    a, b = (Recording(d) for d in _scene_devices(scene))
    a.send_raises = a.close_raises = True
    loop = build(scene, [a, b], realtime=False)
    _ticks(loop, 2.5)  # both hands holding: non-zero sends
    assert any(any(v != 0.0 for v in s[1:]) for s in b.sent[-2:])
    loop.close()
    assert a.closed and b.closed
    for dev in (a, b):
        last = {s[0]: s[1:] for s in dev.sent}
        assert sorted(last) == [0, 1]
        assert all(v == (0.0,) * 6 for v in last.values())
    assert "close refused" in loop.last_device_error
    assert loop.faults["send_error"] > 0


def test_per_device_force_limits():
    """Each finger is clamped to its own device's force limit, not the largest device's."""
    scene = load_scene("bimanual_grasp")
    a, b = _scene_devices(scene)
    weak = open_device("sim", scene, {**scene.devices[1], "max_force_N": 1.5}, source="test")
    with build(scene, [a, weak], realtime=False) as loop:
        assert [f.max_force for f in loop.fingers] == [40.0, 40.0, 1.5, 1.5]
        _ticks(loop, 3.0)
        assert max(f.max_force_seen for f in loop.fingers[2:]) <= 1.5 + 1e-12
        assert max(f.max_force_seen for f in loop.fingers[:2]) > 2.0
    b.close()


def test_finger_on_a_device_the_loop_lacks():
    """A finger naming a device the loop does not drive is refused in one line."""
    scene = load_scene("bimanual_grasp")
    a, b = _scene_devices(scene)
    with pytest.raises(Exception, match="device 1, but the loop drives one device"):
        build(scene, a, realtime=False)
    a.close()
    b.close()


def test_two_device_group_refuses_the_same_device_twice():
    scene = load_scene("bimanual_grasp")
    a, _ = _scene_devices(scene)
    with pytest.raises(ValueError, match="same device twice"):
        DeviceGroup([a, a])


# -- device-aware stiffness -----------------------------------------------------------------

def test_stiffness_capped_to_the_device_with_one_line():
    """A finger stiffer than its device renders stably runs at the device's figure, with one
    line per finger; --allow-stiffer keeps the scene's figure and says so."""
    scene = load_scene("two_finger_grasp")
    stiff = open_device("sim", scene, {**scene.device, "max_stiffness_N_per_m": 400.0,
                                       "max_damping_Ns_per_m": 4.0}, source="test")
    notes = []
    with build(scene, stiff, realtime=False, notes=notes) as loop:
        assert [f.k for f in loop.fingers] == [400.0, 400.0]
        assert [f.b for f in loop.fingers] == [4.0, 4.0]
    assert len(notes) == 2
    assert "stiffness 2000 N/m capped to 400" in notes[0] and "damping 5 N·s/m capped to 4" in notes[0]
    stiff = open_device("sim", scene, {**scene.device, "max_stiffness_N_per_m": 400.0}, source="test")
    notes = []
    with build(scene, stiff, realtime=False, allow_stiffer=True, notes=notes) as loop:
        assert [f.k for f in loop.fingers] == [2000.0, 2000.0]
    assert len(notes) == 2 and "kept (--allow-stiffer)" in notes[0]


def test_simulated_device_has_no_stiffness_limit_by_default():
    scene = load_scene("two_finger_grasp")
    notes = []
    with build(scene, open_device("sim", scene), realtime=False, notes=notes) as loop:
        assert [f.k for f in loop.fingers] == [2000.0, 2000.0]
    assert notes == []


def test_cap_per_device_in_a_group():
    """Each finger is capped by its own device's figure."""
    scene = load_scene("bimanual_grasp")
    a = open_device("sim", scene, {**scene.devices[0], "max_stiffness_N_per_m": 1000.0}, source="test")
    b = open_device("sim", scene, scene.devices[1], source="test")
    capped, notes = cap_fingers(scene.fingers, [a, b])
    assert [p.stiffness for p in capped] == [1000.0, 1000.0, 2000.0, 2000.0]
    assert len(notes) == 2 and all("device 0" in n for n in notes)
    a.close()
    b.close()


def test_vendor_figures():
    """The adapters' tables give CHAI3D's figures for the devices the issue names."""
    from softproxy.devices import forcedimension, openhaptics

    assert openhaptics.model_stiffness("Touch") == (400.0, 4.0)
    assert forcedimension.MODEL_STIFFNESS[33] == (5000.0, 30.0)  # omega.3
    assert forcedimension.MODEL_STIFFNESS[104] == (4000.0, 30.0)  # sigma.7
    assert forcedimension.MODEL_STIFFNESS[60] == (3000.0, 20.0)  # Falcon


# -- the command line -----------------------------------------------------------------------

def _cli(*args):
    return subprocess.run([sys.executable, "-m", "softproxy.cli", *args], capture_output=True, text=True, timeout=600)


def test_cli_device_count_must_match_the_scene():
    r = _cli("run", "bimanual_grasp", "--headless", "--device", "sim")
    assert r.returncode == 2
    assert "--device given 1 time(s)" in r.stderr and "2 [[device]] tables" in r.stderr
    assert "Traceback" not in r.stderr


def test_cli_runs_the_bimanual_scene_with_two_devices():
    r = _cli("run", "bimanual_grasp", "--headless", "--device", "sim", "--device", "sim", "--duration", "0.5")
    assert r.returncode == 0, r.stderr
    assert "scene bimanual_grasp: 500 ticks" in r.stdout


def test_cap_counts_the_workspace_scale():
    """The hand feels k·scale: with scale 2 a 400 N/m device caps k at 200 N/m."""
    from dataclasses import replace

    scene = load_scene("two_finger_grasp")
    dev = open_device("sim", scene, {**scene.device, "max_stiffness_N_per_m": 400.0}, source="test")
    capped, _ = cap_fingers([replace(p, scale=2.0) for p in scene.fingers], [dev])
    assert [p.stiffness for p in capped] == [200.0, 200.0]
    dev.close()


def test_bimanual_scene_on_two_omega7s(monkeypatch):
    """The same bimanual scene on two (fake) omega.7s, their grippers as two fingers each,
    through the adapter's entry point: each [[device]] table opens its own device (an argument
    overrides its own table's fields, not the first's), the run renders on both, and both are
    sent zero last and closed."""
    sys.path.insert(0, str(__import__("pathlib").Path(__file__).parent))
    from fake_dhd import OMEGA7_RIGHT, FakeDHD, Hardware

    from softproxy.devices import forcedimension as fdmod
    from softproxy.run import run_scene

    left, right = Hardware(OMEGA7_RIGHT, serial=1), Hardware(OMEGA7_RIGHT, serial=2)
    for hw in (left, right):
        hw.position, hw.gap = [0.0, 0.0, 0.08], 0.05
    dhd = FakeDHD(left, right)
    monkeypatch.setattr(fdmod, "load_binding", lambda: dhd)
    scene = load_scene("bimanual_grasp")
    scene.devices = [{"type": "forcedimension", "index": 0}, {"type": "forcedimension", "index": 1, "max_force_N": 5.0}]
    scene.device = scene.devices[0]
    a = open_device("forcedimension", scene)
    b = open_device("forcedimension:max_force_N=4", scene, index=1)
    assert (a.serial, b.serial) == (1, 2) and b.max_force == 4.0 and a.fingers == b.fingers == 2
    assert (a.max_stiffness, a.max_damping) == (5000.0, 30.0)
    try:
        result = run_scene(scene, [a, b], duration_s=0.3)
    finally:
        DeviceGroup([a, b]).close()
    assert result["ticks"] == 300 and result["faults"]["device_error"] == 0 and result["notes"] == []
    assert [d["read_failures"] for d in result["devices"]] == [0, 0]
    for hw in (left, right):
        assert len(hw.wire) > 300
        f, t, g, _ = hw.wire[-1]
        assert f == (0.0, 0.0, 0.0) and t == (0.0, 0.0, 0.0) and g == 0.0


def test_a_finger_on_a_device_the_scene_lacks_is_one_line(tmp_path):
    """A [[finger]] naming a device past the scene's [[device]] tables: one line naming it."""
    from pathlib import Path

    from softproxy.scene import SceneError

    source = Path(load_scene("bimanual_grasp").path)
    (tmp_path / "bimanual_grasp.xml").write_text((source.parent / "bimanual_grasp.xml").read_text())
    text = source.read_text().replace('name = "b_back"\ndevice = 1', 'name = "b_back"\ndevice = 2')
    bad = tmp_path / "bad.toml"
    bad.write_text(text)
    with pytest.raises(SceneError, match=r"finger\[3\]\.device is 2, but the scene has 2 \[\[device\]\] tables"):
        load_scene(str(bad))
    one = source.read_text().replace('device = 1\n', 'device = 7\n', 1)
    single = tmp_path / "single.toml"
    single.write_text(one.split("# keyframes:")[0] + '[device]\ntype = "sim"\n[[device.finger]]\nkeyframes = [[0.0, 0.0, 0.0, 0.0, 0.0]]\n')
    with pytest.raises(SceneError, match=r"device is 7, but the scene has 1 device"):
        load_scene(str(single))


def test_cli_record_takes_one_device(tmp_path):
    r = _cli("run", "bimanual_grasp", "--headless", "--device", "sim", "--device", "sim",
             "--record", str(tmp_path / "run.rec"))
    assert r.returncode == 2 and "--record records one device" in r.stderr and "Traceback" not in r.stderr


def test_close_from_another_thread_stops_the_servo_thread_then_zeroes_both():
    """A run in a servo thread, closed from the main thread: nothing but zero reaches either
    device after close() returns, and both are closed."""
    scene = load_scene("bimanual_grasp")
    a, b = (Recording(d) for d in _scene_devices(scene))
    loop = build(scene, [a, b], realtime=False)
    _ticks(loop, 2.5)  # both hands holding
    thread = loop.run_in_thread(100_000, realtime=False)
    give_up = time.monotonic() + 60.0  # (a guard against a dead thread, not a timing check)
    while loop.ticks < 2600 and thread.is_alive() and time.monotonic() < give_up:
        time.sleep(0.001)
    assert loop.ticks >= 2600
    loop.close()
    assert not thread.is_alive() and a.closed and b.closed  # the thread ended: nothing can follow the zero
    for dev in (a, b):
        last = {s[0]: s[1:] for s in dev.sent}
        assert sorted(last) == [0, 1] and all(v == (0.0,) * 6 for v in last.values())
    assert loop.error is None


def test_a_hid_profile_declares_its_stiffness(tmp_path):
    """A HID profile's max_stiffness reaches the device (and so the cap); the shipped ones declare none."""
    from pathlib import Path

    from softproxy.devices.hid_profile import load_profile

    shipped = Path(__file__).parent.parent / "devices" / "profiles" / "open_haptic.toml"
    assert load_profile(str(shipped)).max_stiffness is None
    mine = tmp_path / "mine.toml"
    mine.write_text(shipped.read_text().replace("max_force = 5.0", "max_force = 5.0\nmax_stiffness = 800.0\nmax_damping = 3.0", 1))
    profile = load_profile(str(mine))
    assert (profile.max_stiffness, profile.max_damping) == (800.0, 3.0)


def test_a_cap_below_the_lowest_stiffness_is_one_line():
    """At scale 100 a 400 N/m device allows 4 N/m in the world, below the lowest stiffness a
    finger takes: one line naming the finger and what to change, not a capped finger."""
    from dataclasses import replace

    from softproxy.scene import SceneError

    scene = load_scene("two_finger_grasp")
    dev = open_device("sim", scene, {**scene.device, "max_stiffness_N_per_m": 400.0}, source="test")
    with pytest.raises(ValueError, match="finger 'right'.* 4 N/m in the world at scale 100.*--allow-stiffer"):
        cap_fingers([replace(p, scale=100.0) for p in scene.fingers], [dev])
    far = replace(scene, fingers=[replace(p, scale=100.0) for p in scene.fingers])
    with pytest.raises(SceneError, match="below the lowest stiffness"):
        build(far, dev, realtime=False)
    assert cap_fingers(far.fingers, [dev], allow_stiffer=True)[0] == far.fingers
    dev.close()


def test_a_fingertip_sensor_reads_its_own_devices_sample():
    """A sensing channel on hand B's first finger reads row 2 of the loop's samples (device 1,
    finger 0), not row 0 (device 0's finger 0, which its `device_finger` alone would name)."""
    from softproxy.fingertip_sensors import SensingSpec

    scene = load_scene("bimanual_grasp")
    scene.sensing = [None, None, SensingSpec(), None]
    with build(scene, _scene_devices(scene), realtime=False) as loop:
        assert loop.sample_rows == [0, 1, 2, 3]
        (channel,) = loop.sensors
        assert channel.finger is loop.fingers[2] and channel.device_finger == 2
        _ticks(loop, 2.5)  # B holds the cube: its sensor senses contacts
        assert channel.errors == 0 and channel.summary()["sensed"] > 0


class PythonOnly:
    """Wraps a device so that the loop calls it from Python (it has no compiled_io)."""

    def __init__(self, device) -> None:
        self.inner, self.fingers = device, device.fingers

    max_force = property(lambda self: self.inner.max_force)
    max_torque = property(lambda self: self.inner.max_torque)

    def read(self, t, samples):
        self.inner.read(t, samples)

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.inner.send(finger, fx, fy, fz, tx, ty, tz)

    def close(self):
        self.inner.close()


def _bimanual_run(python: bool, faults: dict):
    scene = load_scene("bimanual_grasp")
    devices = [open_device("sim", scene, {**scene.devices[0], "faults": faults}, source="test"),
               open_device("sim", scene, {**scene.devices[1], "faults": {"drop": 0.01}}, source="test")]
    with build(scene, [PythonOnly(d) for d in devices] if python else devices, realtime=False) as loop:
        assert loop.compiled_block is not python
        loop.run(int(5.0 * loop.rate_hz), every=250, on_tick=lambda lp: None)
        return (loop.world.data.qpos.tolist(), [(f.max_force_seen, f.energy, f.slip_events) for f in loop.fingers],
                loop.faults, list(loop.device.read_failures), [d.sends for d in devices])


def test_a_group_of_compiled_devices_runs_compiled_and_agrees_bit_for_bit():
    """Two simulated devices run as compiled blocks (softproxy.compiled.group) and give exactly
    what the same devices called from Python give, faults on one device included: a stalled or
    dropped read, NaN and spikes (each device's own fingers hold; the other's render)."""
    faults = {"stall": 0.005, "nan": 0.01, "spike": 0.002, "drop": 0.01}
    compiled, python = _bimanual_run(False, faults), _bimanual_run(True, faults)
    assert compiled == python
    qpos, _, counted, failures, _ = compiled
    assert failures[0] > 0 and counted["invalid_sample"] > 0  # the faults happened
    assert 0.07 < qpos[1] < 0.09 and qpos[2] > 0.07  # and the hand-over still came off


def test_a_compiled_group_closed_from_another_thread_ends_at_zero():
    """A compiled group's block in a servo thread, closed from the main thread while both hands
    hold the cube: the thread has ended and both devices render zero on every finger."""
    scene = load_scene("bimanual_grasp")
    devices = _scene_devices(scene)
    loop = build(scene, devices, realtime=False)
    assert loop.compiled_block
    thread = loop.run_in_thread(100_000, realtime=True)  # paced: still running when closed
    give_up = time.monotonic() + 60.0  # (a guard against a dead thread, not a timing check)
    while loop.ticks < 2300 and thread.is_alive() and time.monotonic() < give_up:
        time.sleep(0.01)
    assert loop.ticks >= 2300 and thread.is_alive()  # 2.3 s: both hands on the cube
    loop.close()
    assert not thread.is_alive() and loop.error is None
    for d in devices:
        assert d.max_force_sent > 1.0  # it was rendering a grip ...
        assert d.closed and d.last_force == [(0.0, 0.0, 0.0)] * 2  # ... and ends at zero
