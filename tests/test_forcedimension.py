"""Force Dimension adapter (devices/forcedimension.py) against a fake of the DHD binding
(tests/fake_dhd.py): frames and units, the gripper as two fingers, the SDK's and the model's
limits, and the safety properties of test_hid_safety.py - zero force on every way out, every
command finite and clamped, garbage readings invalid, a device that fails mid-run renders zero
and comes back, close() never raises."""

import math
import sys
import time
from pathlib import Path

import mujoco
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from fake_dhd import FALCON, OMEGA3, OMEGA7_RIGHT, SIGMA7_RIGHT, FakeDHD, Hardware  # noqa: E402

from conftest import BOX_ON_PLANE_XML, Clock, box_loop  # noqa: E402

from softproxy.device import DeviceError, DeviceSample, check_device  # noqa: E402
from softproxy.devices import forcedimension as fdmod  # noqa: E402
from softproxy.devices.forcedimension import (  # noqa: E402
    CLOSE_ZERO_ATTEMPTS,
    REOPEN_INTERVAL_S,
    ForceDimensionDevice,
)


def make(kind=SIGMA7_RIGHT, **kwargs):
    kwargs.setdefault("stall_ms", 0)  # no watchdog thread writing zero between a send and its check
    hw = Hardware(kind)
    dhd = FakeDHD(hw)
    clock = Clock(10.0)
    dev = ForceDimensionDevice(dhd, clock=clock, **kwargs)
    return dev, dhd, hw, clock


def samples(dev):
    return [DeviceSample() for _ in range(dev.fingers)]


def assert_zero(cmd):
    f, t, g, _ = cmd
    assert f == (0.0, 0.0, 0.0) and t == (0.0, 0.0, 0.0) and g == 0.0


def assert_finite_and_clamped(dev, wire):
    for f, t, g, _ in wire:
        assert all(math.isfinite(v) for v in (*f, *t, g))
        assert np.linalg.norm(f) <= dev.max_force * (1 + 1e-12)
        assert np.linalg.norm(t) <= dev.max_torque * (1 + 1e-12)
        assert abs(g) <= dev.max_gripper_force * (1 + 1e-12)


def test_position_orientation_twist_and_buttons_in_the_engine_frame():
    """DHD's x (towards the operator) is the engine's -y, its y the engine's x; positions are
    scaled then offset; the wrist frame becomes a quaternion about the same engine axis; the
    twist is the handle's roll (the third wrist angle); buttons pass through."""
    dev, dhd, hw, clock = make(OMEGA7_RIGHT, gripper="off", workspace_scale=2.0, workspace_offset=(0.0, 0.0, 0.1))
    hw.position = [0.01, 0.02, 0.03]
    c, s_ = math.cos(0.3), math.sin(0.3)
    hw.frame = [[c, -s_, 0.0], [s_, c, 0.0], [0.0, 0.0, 1.0]]  # 0.3 rad about DHD's z (= the engine's z)
    hw.angles = [0.1, -0.2, 0.7]
    hw.buttons = 5
    s = samples(dev)
    dev.read(0.0, s)
    assert s[0].valid and (s[0].x, s[0].y, s[0].z) == pytest.approx((0.04, -0.02, 0.16))
    assert (s[0].qw, s[0].qx, s[0].qy, s[0].qz) == pytest.approx((math.cos(0.15), 0.0, 0.0, math.sin(0.15)))
    assert s[0].twist == pytest.approx(0.7) and s[0].buttons == 5
    dev.send(0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0)  # engine frame -> DHD frame: (-fy, fx, fz)
    assert hw.wire[-1][0] == pytest.approx((-2.0, 1.0, 3.0))


def test_gripper_is_two_fingers_and_their_squeeze_the_gripper_force():
    """omega.7 / sigma.7: thumb and index gap/2 either side of the end-effector along the gripper
    axis (DHD's y = the engine's x at rest); forces pushing them apart open the gripper (fg > 0),
    a common push is the end-effector's force, and the torque of an off-axis pair reaches an
    active wrist (sigma.7) only."""
    dev, dhd, hw, clock = make(SIGMA7_RIGHT)
    assert dev.fingers == 2 and (dev.max_force, dev.max_torque, dev.max_gripper_force) == (12.0, 0.2, 8.0)
    hw.position, hw.gap = [0.0, 0.0, 0.05], 0.04
    s = samples(dev)
    dev.read(0.0, s)
    assert (s[0].x, s[0].y, s[0].z) == pytest.approx((-0.02, 0.0, 0.05))
    assert (s[1].x, s[1].y, s[1].z) == pytest.approx((0.02, 0.0, 0.05))
    dev.send(0, -2.0, 0.0, 0.0, 0.0, 0.0, 0.0)  # an object between them pushes both outwards
    dev.send(1, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    f, t, g, enabled = hw.wire[-1]
    assert g == pytest.approx(2.0) and f == pytest.approx((0.0, 0.0, 0.0)) and enabled
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)  # both pressed up: the handle is pushed up, no squeeze
    dev.send(1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    f, t, g, _ = hw.wire[-1]
    assert f == pytest.approx((0.0, 0.0, 2.0)) and g == pytest.approx(0.0) and t == pytest.approx((0.0, 0.0, 0.0))
    dev.send(0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0)  # thumb down, index up: a moment about the engine's y
    dev.send(1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    f, t, g, _ = hw.wire[-1]
    assert t == pytest.approx(tuple(fdmod._to_device([0.0, -0.04, 0.0])))
    omega, _, ohw, _ = make(OMEGA7_RIGHT)
    omega.read(0.0, samples(omega))
    omega.send(0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0)
    omega.send(1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert omega.max_torque == 0.0 and ohw.wire[-1][1] == (0.0, 0.0, 0.0)  # passive wrist


def test_limits_from_the_model_the_sdk_and_the_user():
    """The model's rated force unless the SDK enforces a lower one; a user limit lowers them and is
    refused above them; the limits are handed to the SDK; devices without an active wrist or
    gripper render no torque or gripper force."""
    hw = Hardware(FALCON)
    hw.limits["force"] = 4.0  # set by the SDK's configuration
    dev = ForceDimensionDevice(FakeDHD(hw))
    assert (dev.fingers, dev.max_force, dev.max_torque, dev.max_gripper_force) == (1, 4.0, 0.0, 0.0)
    dev, dhd, hw, _ = make(SIGMA7_RIGHT, max_force=3.0, max_torque=0.1)
    assert hw.limits == {"force": 3.0, "torque": 0.1, "gripper": 8.0} and hw.force_enabled
    with pytest.raises(ValueError, match=r"max_force must be a finite number in \[0, 12\] \(omega.3's limit\)"):
        make(OMEGA3, max_force=30.0)
    with pytest.raises(ValueError, match="gripper=on: this omega.3 has no gripper"):
        make(OMEGA3, gripper="on")
    dev, *_ = make(OMEGA3)
    check_device(dev)


def test_every_command_is_finite_and_clamped():
    """Random wrenches, 5 % with NaN/Inf, on both fingers: every command that reaches the device is
    finite and within the force, torque and gripper limits (the sum of two clamped fingers is
    clamped again); a non-finite wrench is counted and renders as zero for that finger."""
    rng = np.random.default_rng(3)
    dev, dhd, hw, _ = make(SIGMA7_RIGHT, max_force=5.0, max_torque=0.05, max_gripper_force=2.0)
    s = samples(dev)
    for k in range(400):
        hw.gap = float(rng.uniform(0.0, 0.08))
        dev.read(k * 1e-3, s)
        for finger in range(2):
            w = rng.uniform(-40.0, 40.0, 6)
            if rng.random() < 0.05:
                w[rng.integers(6)] = [math.nan, math.inf, -math.inf][rng.integers(3)]
            dev.send(finger, *w.tolist())
    assert dev.nan_sends > 0
    assert_finite_and_clamped(dev, hw.wire)
    assert max(np.linalg.norm(c[0]) for c in hw.wire) == pytest.approx(5.0)


@pytest.mark.parametrize("garbage", ["nan", "none"])
def test_garbage_readings_are_invalid_samples_never_a_force(garbage):
    """NaN or None from the SDK's readings (position, frame, gap): the sample is invalid and
    counted, nothing non-finite reaches the device; readings coming back are valid again."""
    dev, dhd, hw, _ = make(SIGMA7_RIGHT)
    s = samples(dev)
    dev.read(0.0, s)
    assert s[0].valid
    dhd.garbage = garbage
    dev.read(0.001, s)
    assert not s[0].valid and not s[1].valid and s[0].usable() is False and dev.invalid_samples == 1
    dev.send(0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert_finite_and_clamped(dev, hw.wire)
    hw.frame = [[2.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]  # no rotation
    dhd.garbage = None
    dev.read(0.002, s)
    assert not s[0].valid
    hw.frame = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    dev.read(0.003, s)
    assert s[0].valid and s[0].is_finite()


@pytest.mark.parametrize("how", ["error", "raise"])
def test_a_read_failure_renders_zero_first_then_a_fresh_sample(how):
    """getPosition failing (returning -1, or raising): DeviceError naming the SDK's reason, no
    command while failed, the next read writes zero force before anything else, and forces
    render again only after a clean sample."""
    dev, dhd, hw, clock = make(SIGMA7_RIGHT)
    s = samples(dev)
    dev.read(0.0, s)
    dev.send(0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
    n = len(hw.wire)
    (dhd.fail if how == "error" else dhd.raise_in).add("getPosition")
    with pytest.raises(DeviceError, match="failed while reading.*(communication error|libusb I/O error)"):
        dev.read(0.001, s)
    with pytest.raises(DeviceError):
        dev.send(0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
    assert len(hw.wire) == n
    with pytest.raises(DeviceError):  # still failing: the zero write went, the read did not
        dev.read(0.002, s)
    assert_zero(hw.wire[n])
    (dhd.fail if how == "error" else dhd.raise_in).clear()
    dhd.garbage = "nan"  # back, but the first reading is garbage: still no force
    dev.read(0.003, s)
    dev.send(0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
    assert all(c[0] == (0.0, 0.0, 0.0) for c in hw.wire[n:])
    dhd.garbage = None
    dev.read(0.004, s)
    dev.send(0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
    assert s[0].valid and dev.recoveries == 1 and dev.failures == 1
    assert hw.wire[-1][0][2] == pytest.approx(3.0)


def test_unplugged_device_is_reopened_and_must_be_the_same_one():
    """Unplugged: reads raise, reopening is tried every REOPEN_INTERVAL_S; plugged back, it is
    opened again (limits and force mode set again, zero force first); a different device at
    the same place (another serial number) is refused."""
    dev, dhd, hw, clock = make(OMEGA7_RIGHT)
    s = samples(dev)
    dev.read(0.0, s)
    dhd.unplug()
    with pytest.raises(DeviceError, match="failed while reading"):
        dev.read(0.001, s)
    opens = dhd.calls.count("open")
    for k in range(10):  # 0.1 s of failed reads: no reopen before its interval
        clock.now += 0.01
        with pytest.raises(DeviceError):
            dev.read(0.002, s)
    assert dhd.calls.count("open") == opens
    clock.now += REOPEN_INTERVAL_S
    with pytest.raises(DeviceError, match="last reopen: cannot open"):
        dev.read(0.003, s)
    assert dhd.calls.count("open") == opens + 1
    dhd.plug()
    n = len(hw.wire)
    clock.now += REOPEN_INTERVAL_S
    dev.read(0.004, s)
    assert s[0].valid and dev.reopens == 1 and dev.recoveries == 1
    assert_zero(hw.wire[n])
    assert hw.force_enabled

    dhd.unplug()
    with pytest.raises(DeviceError):
        dev.read(0.005, s)
    hw.serial = 999  # another omega.7 where this one was
    dhd.plug()
    clock.now += 2 * REOPEN_INTERVAL_S
    with pytest.raises(DeviceError, match="not the same one"):
        dev.read(0.006, s)
    dev.close()


def test_close_always_tries_zero_force_and_never_raises():
    """close(): zero force is the last command, forces are disabled and the handle closed; a
    failed device gets zero force too; a dead one gets CLOSE_ZERO_ATTEMPTS tries and no
    exception; close() twice is harmless; a closed device refuses reads and sends."""
    dev, dhd, hw, _ = make(SIGMA7_RIGHT)
    s = samples(dev)
    dev.read(0.0, s)
    dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    dhd.fail.add("getPosition")
    with pytest.raises(DeviceError):
        dev.read(0.001, s)
    dhd.fail.clear()
    dev.close()
    assert_zero(hw.wire[-1])
    assert not hw.force_enabled and not dhd.handles
    dev.close()
    with pytest.raises(DeviceError, match="closed"):
        dev.read(0.002, s)

    dev, dhd, hw, _ = make(SIGMA7_RIGHT)
    dev.read(0.0, samples(dev))
    dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    dhd.raise_in.add("setForceAndTorqueAndGripperForce")
    dhd.raise_in.add("enableForce")
    dev.close()
    assert dhd.calls.count("setForceAndTorqueAndGripperForce") >= CLOSE_ZERO_ATTEMPTS + 2
    assert hw.wire[-1][0][2] == pytest.approx(4.0)  # what only the device's own safety can stop
    assert not dhd.handles


def test_missing_binding_or_sdk_is_one_line_naming_what_to_install(monkeypatch):
    """No forcedimension_core: the message names the extra; the binding present but libdrd
    missing, unloadable or too old (its import writes why to stderr and raises ImportError): the
    message gives the reason and names the SDK; one line each."""
    def no_module(name):
        raise ModuleNotFoundError(f"No module named {name.split('.')[0]!r}", name=name.split(".")[0])

    monkeypatch.setattr(fdmod.importlib, "import_module", no_module)
    with pytest.raises(DeviceError) as e:
        ForceDimensionDevice()
    assert "pip install 'softproxy[forcedimension]'" in str(e.value) and "\n" not in str(e.value)
    row = fdmod.availability()
    assert row["binding"] is False and "pip install" in row["message"]

    def no_sdk(name):  # as forcedimension_core.runtime does: the reason on stderr, then ImportError
        sys.stderr.write("Invalid version. v3.14.0.0 found but v3.16.0.0 is required.\n")
        raise ImportError("There were problems loading libdrd. Check if you have it installed properly.")

    monkeypatch.setattr(fdmod.importlib, "import_module", no_sdk)
    with pytest.raises(DeviceError, match="SDK library was not found.*v3.14.0.0 found but v3.16.0.0.*FDSDK") as e:
        ForceDimensionDevice()
    assert "\n" not in str(e.value)
    assert fdmod.availability()["binding"] is True and fdmod.availability()["sdk"] is False

    def no_sdk_silent(name):
        raise ImportError("There were problems loading libdrd.")

    monkeypatch.setattr(fdmod.importlib, "import_module", no_sdk_silent)
    with pytest.raises(DeviceError, match="SDK library was not found.*problems loading libdrd.*FDSDK"):
        ForceDimensionDevice()


def test_availability_counts_devices():
    row = fdmod.availability(FakeDHD(Hardware(), Hardware(FALCON, serial=7)))
    assert (row["binding"], row["sdk"], row["devices"], row["sdk_version"]) == (True, True, 2, "3.17.1.0")


def test_configuration_from_a_scene_table_and_the_argument():
    """`--device forcedimension:1,gripper=off,workspace_offset=0:0:0.05`: the device at index 1,
    one finger, offset; mistakes name the flag or field."""
    dhd = FakeDHD(Hardware(OMEGA3, serial=1), Hardware(OMEGA7_RIGHT, serial=2))
    dev = ForceDimensionDevice.from_argument("1,gripper=off,workspace_offset=0:0:0.05,max_force_N=3", dhd=dhd)
    assert (dev.model, dev.fingers, dev.workspace_offset, dev.max_force) == ("omega.7", 1, (0.0, 0.0, 0.05), 3.0)
    dev.close()
    dev = ForceDimensionDevice.from_argument("first", dhd=dhd)
    assert dev.model == "omega.3"
    dev.close()
    with pytest.raises(ValueError, match=r"--device forcedimension:gripper=maybe: device.gripper must be"):
        ForceDimensionDevice.from_argument("gripper=maybe", dhd=dhd)
    with pytest.raises(ValueError, match=r"scene.toml: device has unknown field\(s\) \['profile'\]"):
        ForceDimensionDevice.from_config({"type": "forcedimension", "profile": "x"}, source="scene.toml", dhd=dhd)
    with pytest.raises(ValueError, match=r"scene.toml: max_force must be a finite number in \[0, 12\]"):
        ForceDimensionDevice.from_config({"type": "forcedimension", "max_force_N": 50.0}, source="scene.toml", dhd=dhd)
    with pytest.raises(DeviceError, match="cannot open a Force Dimension device at index 5: invalid index"):
        ForceDimensionDevice.from_argument("5", dhd=dhd)


# ---------------------------------------------------------------------------------------------
# in the servo loop

def test_servo_loop_presses_survives_a_failure_and_ends_at_zero_force():
    """A ServoLoop drives the fake omega.3 (one finger) down onto a box: it renders the contact,
    a device failing for 50 ticks costs zero force those ticks (counted), it renders again after,
    and the run ends with zero force on the device."""

    dev, dhd, hw, clock = make(OMEGA3)
    hw.position = [0.0, 0.0, 0.08]  # above the box (top at 0.06 m, finger radius 8 mm)
    loop = box_loop(dev)
    ticks = [0]

    def on_tick(_):
        ticks[0] += 1
        clock.now += 0.001
        hw.position = [0.0, 0.0, max(0.066, 0.08 - 5e-5 * ticks[0])]  # DHD z is the engine's z: 2 mm in

    loop.run(600, on_tick=on_tick)
    assert max(c[0][2] for c in hw.wire) > 0.5
    dhd.fail.add("getPosition")
    n = len(hw.wire)
    loop.run(50, on_tick=on_tick)
    assert loop.faults["device_error"] == 50
    assert all(c[0] == (0.0, 0.0, 0.0) for c in hw.wire[n:])
    dhd.fail.clear()
    loop.run(100, on_tick=on_tick)
    assert max(c[0][2] for c in hw.wire[n:]) > 0.5 and dev.recoveries == 1
    assert_zero(hw.wire[-1])  # a run ends with zero force
    loop.close()
    assert_zero(hw.wire[-1])
    assert dev.closed
    assert_finite_and_clamped(dev, hw.wire)


@pytest.mark.parametrize("seed", [1, 2])
def test_random_failure_schedules_end_at_zero_force(seed):
    """Property, under random failures (read and write errors returning -1 or raising, unplugs
    of 1..100 ticks, garbage readings) with random wrenches, 2 % non-finite: while failed
    nothing but zero force is written; every command is finite and clamped; every failure is
    recovered from; after close() the last command is zero force."""
    rng = np.random.default_rng(seed)
    dev, dhd, hw, clock = make(SIGMA7_RIGHT, max_force=6.0, max_torque=0.1, max_gripper_force=3.0)
    s = samples(dev)
    outage = 0
    awaiting = False
    for k in range(1500):
        dhd.fail.clear()
        dhd.raise_in.clear()
        dhd.garbage = None
        if outage:
            outage -= 1
            if outage == 0:
                dhd.plug()
        elif k < 1200:
            u = rng.random(4)
            if u[0] < 0.03:
                (dhd.fail if rng.random() < 0.5 else dhd.raise_in).add("getPosition")
            if u[1] < 0.03:
                (dhd.fail if rng.random() < 0.5 else dhd.raise_in).add("setForceAndTorqueAndGripperForce")
            if u[2] < 0.01:
                outage = int(rng.integers(1, 101))
                dhd.unplug()
            if u[3] < 0.02:
                dhd.garbage = "nan"
        clock.now += 0.001
        hw.gap = float(rng.uniform(0.0, 0.06))
        n = len(hw.wire)
        try:
            dev.read(k * 1e-3, s)
        except DeviceError:
            awaiting = True
        if s[0].valid and not dhd.garbage:
            awaiting = False
        for finger in range(2):
            w = rng.uniform(-10.0, 10.0, 6)
            w[3:] *= 0.02
            if rng.random() < 0.02:
                w[rng.integers(6)] = math.nan
            try:
                dev.send(finger, *w.tolist())
            except DeviceError:
                awaiting = True
        if awaiting:
            assert all(c[0] == (0.0, 0.0, 0.0) and c[2] == 0.0 for c in hw.wire[n:])
    assert dev.failures > 3 and dev.recoveries == dev.failures
    assert any(c[0] != (0.0, 0.0, 0.0) for c in hw.wire[-100:])  # rendering again at the end
    dev.close()
    assert_zero(hw.wire[-1])
    assert_finite_and_clamped(dev, hw.wire)
    print(f"\nseed {seed}: {len(hw.wire)} commands, {dev.failures} failures, {dev.reopens} reopens, "
          f"{dev.recoveries} recoveries, {dev.nan_sends} non-finite sends zeroed")


def test_softproxy_devices_lists_the_backends(capsys):
    """`softproxy devices`: one line per vendor backend saying whether it can run here and why
    not; `--json` gives them under "backends" (with the device count the SDK sees)."""
    import io
    import json

    from softproxy.cli import main
    from softproxy.devices.hid import devices_main

    out = io.StringIO()
    rows = [fdmod.availability(FakeDHD(Hardware()))]
    assert devices_main(True, enumerate_fn=lambda: [], out=out, backends=rows) == 0
    doc = json.loads(out.getvalue())
    assert doc["backends"][0]["backend"] == "forcedimension" and doc["backends"][0]["devices"] == 1
    out = io.StringIO()
    devices_main(False, enumerate_fn=lambda: [], out=out, backends=rows)
    assert "forcedimension: ready; 1 device(s) connected" in out.getvalue()

    main(["devices", "--json"])
    doc = json.loads(capsys.readouterr().out)
    names = {b["backend"]: b for b in doc["backends"]}
    assert set(names) >= {"forcedimension", "openhaptics"}
    assert all(b["message"] for b in names.values())


def test_a_scene_runs_on_a_sigma7_through_the_entry_point(monkeypatch):
    """`[device] type = "forcedimension"` and `--device forcedimension:...` reach the adapter
    through the `softproxy.devices` entry point; the two-finger grasp scene runs 0.3 s on a
    (fake) sigma.7's gripper: every command finite and clamped, zero force at the end."""
    from softproxy.run import check_device_fingers, open_device, run_scene
    from softproxy.scene import load_scene

    hw = Hardware(SIGMA7_RIGHT)
    hw.position, hw.gap = [0.0, 0.0, 0.08], 0.05
    monkeypatch.setattr(fdmod, "load_binding", lambda: FakeDHD(hw))
    scene = load_scene("two_finger_grasp")
    scene.device = {"type": "forcedimension", "max_force_N": 4.0}
    dev = open_device("forcedimension", scene)
    assert isinstance(dev, ForceDimensionDevice) and dev.fingers == 2 and dev.max_force == 4.0
    check_device_fingers(scene, dev, "test")
    try:
        result = run_scene(scene, dev, duration_s=0.3)
    finally:
        dev.close()
    assert result["ticks"] == 300 and result["faults"]["device_error"] == 0
    assert_zero(hw.wire[-1])
    assert_finite_and_clamped(dev, hw.wire)
    dev = open_device("forcedimension:gripper=off,max_force_N=2", scene)
    assert dev.fingers == 1 and dev.max_force == 2.0
    dev.close()


def test_an_exception_in_a_with_block_leaves_zero_force_and_a_closed_device():
    """Leaving `with ServoLoop(...)` by an exception while the gripper fingers press: the last
    command is zero force and zero gripper force, forces disabled, the device closed."""
    from softproxy.finger import FingerParams, SoftFingerProxy
    from softproxy.fingertip import model
    from softproxy.servo import ServoLoop
    from softproxy.world import World

    dev, dhd, hw, clock = make(SIGMA7_RIGHT)
    hw.position, hw.gap = [0.0, 0.0, 0.065], 0.02  # both fingers 3 mm into the box's top
    world = World(mujoco.MjModel.from_xml_string(BOX_ON_PLANE_XML))
    fingers = [SoftFingerProxy(FingerParams(name=f"f{i}", radius=0.008, stiffness=1000.0, device_finger=i,
                                            soft_start=0.0), world.shapes, model("CH")) for i in range(2)]
    with pytest.raises(ZeroDivisionError):
        with ServoLoop(world, fingers, dev, 1000.0, overrun_watchdog=False) as loop:
            loop.run(50)
            assert max(np.linalg.norm(c[0]) for c in hw.wire) > 1.0
            1 / 0
    assert_zero(hw.wire[-1])
    assert not hw.force_enabled and dev.closed and not dhd.handles


def test_a_close_from_another_thread_never_lets_a_command_land_after_its_zero():
    """close() from another thread while a send is writing: the send's command lands first, then
    close()'s zero, forces disabled; the last command on the device is zero force."""
    import threading

    dev, dhd, hw, _ = make(SIGMA7_RIGHT)
    dev.read(0.0, samples(dev))
    closer = threading.Thread(target=dev.close)

    def close_meanwhile(f, t, fg):
        if any(f) and not closer.is_alive() and not dev.closed:
            closer.start()
            closer.join(0.2)  # without the lock, close() runs to its end here

    hw.command_hook = close_meanwhile
    dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    closer.join(2.0)
    assert dev.closed and not closer.is_alive()
    assert hw.wire[-2][0][2] == pytest.approx(4.0)
    assert_zero(hw.wire[-1])
    assert not hw.force_enabled and not dhd.handles


def test_a_device_left_open_is_zeroed_at_exit():
    """The exit hook closes every device still open: zero force last, forces disabled, handle
    closed; a device closed already is left alone."""
    dev, dhd, hw, _ = make(SIGMA7_RIGHT)
    dev.read(0.0, samples(dev))
    dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    other, other_dhd, _, _ = make(OMEGA3)
    other.close()
    calls = len(other_dhd.calls)
    fdmod._OPEN.close_all()
    assert dev.closed
    assert_zero(hw.wire[-1])
    assert not hw.force_enabled and not dhd.handles and len(other_dhd.calls) == calls


def test_a_model_the_binding_does_not_know_is_refused_in_one_line():
    """The binding turns the type id into its DeviceType enum, which raises for an id it lacks
    (a model newer than the binding): no device is driven with guessed limits; one line."""
    dhd = FakeDHD(Hardware(kind=77))
    with pytest.raises(DeviceError, match="cannot read what it is.*77") as e:
        ForceDimensionDevice(dhd)
    assert "\n" not in str(e.value) and not dhd.handles


def test_finite_fingers_whose_sum_overflows_send_zero_not_nan():
    """Two fingers' wrenches each finite but so large their sum, squeeze or moment overflows
    (inf, and inf * 0 = NaN in the clamp): the command is zero and counted, never NaN or inf."""
    dev, dhd, hw, _ = make(SIGMA7_RIGHT)
    dev.read(0.0, samples(dev))
    for w0, w1 in (((1e308, 0.0, 0.0), (1e308, 0.0, 0.0)), ((-1e308, 0.0, 1e308), (1e308, 0.0, -1e308))):
        before = dev.nan_sends
        dev.send(0, *w0, 0.0, 0.0, 0.0)
        dev.send(1, *w1, 0.0, 0.0, 0.0)
        assert_zero(hw.wire[-1])
        assert dev.nan_sends > before
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    dev.send(1, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert hw.wire[-1][0] == pytest.approx((0.0, 0.0, 2.0))


def test_a_stalled_loop_leaves_zero_force_not_its_last():
    """DHD renders the last command until the next: a non-zero command not renewed for stall_ms
    is replaced by zero force (once, counted); a fresh send renders again; a zero command or a
    closed device is left alone. Then the watchdog's own thread, on a real 20 ms stall."""
    dev, dhd, hw, _ = make(SIGMA7_RIGHT, stall_ms=1000)  # its thread would wait 1 s: the checks are driven here
    dev.read(0.0, samples(dev))
    dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    sent_at, n = dev._last_write, len(hw.wire)
    dev._watch_once(now=sent_at + 0.9)
    assert len(hw.wire) == n  # not stale yet
    dev._watch_once(now=sent_at + 1.1)
    assert_zero(hw.wire[-1])
    assert dev.stall_zeroes == 1 and len(hw.wire) == n + 1
    dev._watch_once(now=sent_at + 5.0)
    assert len(hw.wire) == n + 1 and dev.stall_zeroes == 1  # zero already
    dev.send(0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.0)
    assert hw.wire[-1][0][2] == pytest.approx(3.0)
    dev.close()
    n = len(hw.wire)
    dev._watch_once(now=sent_at + 100.0)
    assert len(hw.wire) == n

    dev, dhd, hw, _ = make(OMEGA3, stall_ms=20)
    dev.read(0.0, samples(dev))
    dev.send(0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0)
    deadline = time.monotonic() + 60.0  # a hang guard: the watcher acts after 20 ms, load can delay its thread
    while dev.stall_zeroes == 0 and time.monotonic() < deadline:
        time.sleep(0.005)
    assert dev.stall_zeroes == 1
    assert_zero(hw.wire[-1])
    dev.close()
    with pytest.raises(ValueError, match="stall_ms"):
        ForceDimensionDevice(FakeDHD(Hardware()), stall_ms=-1)
