"""OpenHaptics adapter (devices/openhaptics.py) against a fake of pyOpenHaptics
(tests/fake_openhaptics.py): frames and units, limits from the SDK or the model, the exchange
with the scheduler's callback (never blocking it, commands that expire), and the safety
properties of test_hid_safety.py - zero force on every way out, every force finite and
clamped, garbage readings invalid, a device that fails mid-run renders zero and is reopened,
close() never raises."""

import math
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))
from fake_openhaptics import FakeOpenHaptics  # noqa: E402

from conftest import Clock, box_loop  # noqa: E402

from softproxy.device import DeviceError, DeviceSample, check_device  # noqa: E402
from softproxy.devices import openhaptics as ohmod  # noqa: E402
from softproxy.devices.openhaptics import FAIL_AFTER_S, REOPEN_INTERVAL_S, OpenHapticsDevice  # noqa: E402


def make(fake=None, **kwargs):
    fake = fake or FakeOpenHaptics()
    clock = Clock(10.0)
    dev = OpenHapticsDevice(fake, clock=clock, sleep=lambda s: fake.step(1), **kwargs)
    return dev, fake, clock


def tick(dev, fake, clock, s, t=0.0, frames=1):
    """One servo tick: the scheduler runs `frames` frames (1 ms each), then the loop reads."""
    for _ in range(frames):
        clock.now += 0.001
        fake.step(1)
    dev.read(t, s)


def rendering(**kwargs):
    """A device that has had one tick and renders 0.5 N up (engine z): (dev, fake, clock, samples)."""
    dev, fake, clock = make(**kwargs)
    s = [DeviceSample()]
    tick(dev, fake, clock, s)
    dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    fake.step(1)
    return dev, fake, clock, s


def assert_finite_and_clamped(forces, limit):
    for f in forces:
        assert all(math.isfinite(v) for v in f) and np.linalg.norm(f) <= limit * (1 + 1e-12)


def test_pose_in_metres_in_the_engine_frame_and_the_gimbal_twist():
    """OpenHaptics' millimetres, x right, y up, z towards the operator become metres with the
    engine's z up (x, -z, y), scaled then offset; the stylus frame becomes a quaternion about
    the matching engine axis; the twist is the third gimbal angle; buttons pass through. The
    binding's prints stay out of the output."""
    dev, fake, clock = make(workspace_scale=2.0, workspace_offset=(0.0, 0.0, 0.1))
    fake.pose_mm = [10.0, 20.0, 30.0]
    c, s_ = math.cos(0.4), math.sin(0.4)
    fake.rotation = [[c, 0.0, s_], [0.0, 1.0, 0.0], [-s_, 0.0, c]]  # 0.4 rad about OpenHaptics' y: the engine's z
    fake.gimbals = [0.1, 0.2, -0.6]
    fake.buttons = 2
    s = [DeviceSample()]
    tick(dev, fake, clock, s)
    assert s[0].valid and (s[0].x, s[0].y, s[0].z) == pytest.approx((0.02, -0.06, 0.14))
    assert (s[0].qw, s[0].qx, s[0].qy, s[0].qz) == pytest.approx((math.cos(0.2), 0.0, 0.0, math.sin(0.2)))
    assert s[0].twist == pytest.approx(-0.6) and s[0].buttons == 2
    dev.send(0, 0.1, 0.2, 0.3, 1.0, 1.0, 1.0)  # engine -> OpenHaptics: (fx, fz, -fy); torque dropped
    fake.step(1)
    assert fake.forces[-1] == pytest.approx((0.1, 0.3, -0.2))
    check_device(dev)


def test_limits_from_the_sdk_else_the_model_table():
    """Default max_force: the SDK's nominal continuous force; up to its peak on request, refused
    above; without SDK figures, the model table (Touch X 1.75 N / 7.9 N); no torque."""
    dev, fake, _ = make(FakeOpenHaptics(continuous=0.5, peak=2.0))
    assert (dev.max_force, dev.peak_force, dev.max_torque) == (0.5, 2.0, 0.0)
    dev, fake, _ = make(FakeOpenHaptics(model="Touch X", give_limits=False), max_force=5.0)
    assert (dev.max_force, dev.peak_force) == (5.0, 7.9)
    with pytest.raises(ValueError, match=r"max_force must be a finite number in \[0, 3.3\] \(Touch's peak force\)"):
        make(FakeOpenHaptics(give_limits=False), max_force=4.0)


def test_commands_are_rendered_only_while_fresh_and_armed():
    """The callback renders nothing before the first valid sample, the latest command while it
    is younger than command_timeout_ms, and zero once the loop stops sending (counted)."""
    dev, fake, clock = make(command_timeout_ms=50.0)
    s = [DeviceSample()]
    dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)  # before any sample: not armed
    fake.step(1)
    assert fake.forces[-1] == (0.0, 0.0, 0.0)
    tick(dev, fake, clock, s)
    dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    fake.step(1)
    assert fake.forces[-1] == pytest.approx((0.0, 0.5, 0.0))
    for _ in range(60):  # the loop stalls; the scheduler goes on
        clock.now += 0.001
        fake.step(1)
    assert fake.forces[-1] == (0.0, 0.0, 0.0) and dev.callback_zeroed > 0


def test_every_force_is_finite_and_clamped():
    """Random forces, 5 % NaN/Inf: every force the callback sets is finite and within max_force;
    non-finite sends are counted and render zero."""
    rng = np.random.default_rng(5)
    dev, fake, clock = make()
    s = [DeviceSample()]
    for k in range(300):
        tick(dev, fake, clock, s, k * 1e-3)
        w = rng.uniform(-20.0, 20.0, 6)
        if rng.random() < 0.05:
            w[rng.integers(3)] = [math.nan, math.inf, -math.inf][rng.integers(3)]
        dev.send(0, *w.tolist())
    fake.step(1)
    assert dev.nan_sends > 0
    assert_finite_and_clamped(fake.forces, dev.max_force)
    assert max(np.linalg.norm(f) for f in fake.forces) == pytest.approx(dev.max_force)


@pytest.mark.parametrize("garbage", ["nan", "none"])
def test_garbage_readings_are_invalid_samples_never_a_force(garbage):
    """NaN or None from the device, or a transform that is no rotation: invalid, counted, and no
    non-finite force; good readings are valid again."""
    dev, fake, clock = make()
    s = [DeviceSample()]
    tick(dev, fake, clock, s)
    fake.garbage = garbage
    tick(dev, fake, clock, s)
    assert not s[0].valid and dev.invalid_samples == 1
    fake.garbage = None
    fake.rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]]  # a reflection
    tick(dev, fake, clock, s)
    assert not s[0].valid
    fake.rotation = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
    tick(dev, fake, clock, s)
    assert s[0].valid and s[0].is_finite()
    dev.send(0, 0.0, 0.0, 0.3, 0.0, 0.0, 0.0)
    fake.step(1)
    assert_finite_and_clamped(fake.forces, dev.max_force)


def test_stale_samples_are_invalid():
    """A scheduler that falls behind by more than stale_ms: the sample is invalid (counted), not
    yet a failure."""
    dev, fake, clock = make(stale_ms=20.0)
    s = [DeviceSample()]
    tick(dev, fake, clock, s)
    clock.now += 0.03
    dev.read(0.03, s)
    assert not s[0].valid and dev.stale_samples == 1 and dev.failures == 0


@pytest.mark.parametrize("how", ["hd_error", "raise"])
def test_a_device_that_fails_mid_run_renders_zero_and_is_reopened(how):
    """An HD error after a frame (the binding then stops scheduling the callback) or a binding
    call raising inside the callback: zero force at once, DeviceError naming the device, a
    reopen every REOPEN_INTERVAL_S; back, it renders zero until a valid sample, then forces."""
    dev, fake, clock, s = rendering()
    assert fake.forces[-1] != (0.0, 0.0, 0.0)
    if how == "hd_error":
        fake.error_frames = 1
        fake.step(1)  # this frame ends with an error: the callback is no longer scheduled
        assert not fake.scheduled
        for k in range(int(FAIL_AFTER_S * 1000)):
            clock.now += 0.001
            fake.step(1)
            if k < 15:
                dev.read(0.0, s)
        with pytest.raises(DeviceError, match="no sample from the OpenHaptics scheduler"):
            clock.now += 0.002
            dev.read(0.1, s)
    else:
        fake.raise_in.add("get_transform")
        fake.step(1)
        assert fake.forces[-1] == (0.0, 0.0, 0.0)  # the callback zeroed the force itself
        with pytest.raises(DeviceError, match="failed in the scheduler callback.*device fault"):
            dev.read(0.0, s)
        fake.raise_in.clear()
    with pytest.raises(DeviceError):
        dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    inits = fake.inits
    clock.now += REOPEN_INTERVAL_S
    with pytest.raises(DeviceError):  # reopened: waits for the callback to run
        dev.read(0.2, s)
    assert fake.inits == inits + 1 and dev.reopens == 1
    n = len(fake.forces)
    fake.step(1)
    dev.read(0.201, s)
    assert s[0].valid and dev.recoveries == 1 and dev.failures == 1
    assert fake.forces[n] == (0.0, 0.0, 0.0)  # zero first
    dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
    fake.step(1)
    assert fake.forces[-1] == pytest.approx((0.0, 0.5, 0.0))
    dev.close()
    assert fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running and fake.disabled


def test_close_renders_zero_then_stops_and_never_raises():
    """close(): the callback's last force is zero, then the scheduler stops and the device is
    disabled; twice is harmless; a binding that raises on close does not escape; a closed
    device refuses reads and sends."""
    dev, fake, clock, s = rendering()
    dev.close()
    assert fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running and fake.disabled == [1]
    dev.close()
    with pytest.raises(DeviceError, match="closed"):
        dev.send(0, 0.0, 0.0, 0.1, 0.0, 0.0, 0.0)

    dev, fake, clock = make()
    tick(dev, fake, clock, s)
    fake.hd.stop_scheduler = lambda: (_ for _ in ()).throw(OSError("gone"))
    dev.close()
    assert dev.closed and fake.disabled == [1]  # disabled even so


def test_an_unopenable_device_and_a_missing_binding_are_one_line(monkeypatch):
    """hdInitDevice failing: pyOpenHaptics 1.0.1 misses it (it compares the handle with an error
    code) and either fails later, on hdGetString's NULL, or finishes with HD_INVALID_HANDLE as
    its id; both are DeviceError naming the device and what to check, the scheduler stopped. No
    pyOpenHaptics, no libHD, or a platform the binding loads no libHD on: one line naming what
    to install."""
    for strings in ("null", "ok"):
        fake = FakeOpenHaptics()
        fake.init_fails = True
        fake.strings_without_device = strings
        with pytest.raises(DeviceError, match="cannot open OpenHaptics device 'Left': hdInitDevice failed") as e:
            OpenHapticsDevice(fake, device_name="Left")
        assert "\n" not in str(e.value) and "Touch Setup" in str(e.value) and not fake.running, strings

    fake = FakeOpenHaptics()

    def no_lib_hd(*args, **kwargs):
        raise NameError("name '_lib_hd' is not defined")  # macOS: the binding defines no _lib_hd

    fake.HapticDevice = no_lib_hd
    with pytest.raises(DeviceError, match="OpenHaptics SDK library was not found.*Linux and Windows only") as e:
        OpenHapticsDevice(fake)
    assert "\n" not in str(e.value) and "install the OpenHaptics SDK" in str(e.value)

    def no_module(name):
        raise ModuleNotFoundError("No module named 'pyOpenHaptics'", name="pyOpenHaptics")

    monkeypatch.setattr(ohmod.importlib, "import_module", no_module)
    with pytest.raises(DeviceError, match=r"pip install 'softproxy\[openhaptics\]'$"):
        OpenHapticsDevice()
    assert ohmod.availability()["binding"] is False

    def no_sdk(name):
        raise OSError("libHD.so: cannot open shared object file: No such file or directory")

    monkeypatch.setattr(ohmod.importlib, "import_module", no_sdk)
    with pytest.raises(DeviceError, match="OpenHaptics SDK library was not found.*libHD") as e:
        OpenHapticsDevice()
    assert "\n" not in str(e.value)
    row = ohmod.availability()
    assert row["binding"] is True and row["sdk"] is False


def test_configuration_from_the_argument_and_a_scene_table():
    """`--device openhaptics:Left,max_force_N=0.5,workspace_offset=0:0:0.05`; mistakes name the flag."""
    fake = FakeOpenHaptics()
    dev = OpenHapticsDevice.from_argument("Left,max_force_N=0.5,workspace_offset=0:0:0.05", binding=fake)
    assert (dev.device_name, dev.max_force, dev.workspace_offset) == ("Left", 0.5, (0.0, 0.0, 0.05))
    dev.close()
    dev = OpenHapticsDevice.from_argument("default", binding=FakeOpenHaptics())
    assert dev.device_name == "Default Device"
    dev.close()
    with pytest.raises(ValueError, match=r"--device openhaptics:default,stale_ms=0: device.stale_ms must be"):
        OpenHapticsDevice.from_argument("default,stale_ms=0", binding=FakeOpenHaptics())
    with pytest.raises(ValueError, match=r"s.toml: device has unknown field\(s\) \['index'\]"):
        OpenHapticsDevice.from_config({"type": "openhaptics", "index": 0}, source="s.toml", binding=FakeOpenHaptics())


# ---------------------------------------------------------------------------------------------
# in the servo loop

def test_servo_loop_presses_survives_an_hd_error_and_ends_at_zero_force():
    """A ServoLoop with the Touch descending onto a box (the scheduler stepped once per tick): it
    renders the contact; an HD error stops the callback, the loop gets DeviceErrors (zero force),
    the device is reopened and renders again; the run ends with zero force."""
    dev, fake, clock = make()
    fake.pose_mm = [0.0, 80.0, 0.0]  # OpenHaptics' y is up
    loop = box_loop(dev)
    ticks = [0]

    def on_tick(_):
        ticks[0] += 1
        clock.now += 0.001
        fake.pose_mm = [0.0, max(66.0, 80.0 - 0.05 * ticks[0]), 0.0]  # 2 mm into the box's top
        fake.step(1)

    fake.step(1)
    loop.run(600, on_tick=on_tick)
    assert max(f[1] for f in fake.forces) > 0.5
    fake.error_frames = 1
    n = len(fake.forces)
    loop.run(500, on_tick=on_tick)
    assert loop.faults["device_error"] > 0 and dev.reopens >= 1 and dev.recoveries == 1
    assert max(f[1] for f in fake.forces[n:]) > 0.5
    loop.close()
    assert fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running
    assert_finite_and_clamped(fake.forces, dev.max_force)


def test_a_threaded_scheduler_keeps_its_rate_beside_a_paced_loop():
    """With the fake scheduler in its own thread at 1 kHz and the servo loop paced in real time
    at 1 kHz, the callback runs at least every other tick (read() hands it the interpreter lock;
    without that it gets about one tick in ten), samples are valid, and the device ends at zero
    force when the loop closes."""
    fake = FakeOpenHaptics()
    fake.pose_mm = [0.0, 100.0, 0.0]  # in the air
    fake.start_thread()
    try:
        time.sleep(0.02)
        dev = OpenHapticsDevice(fake)
        loop = box_loop(dev)
        before = dev.callback_ticks
        loop.run(400, realtime=True)
        ran = dev.callback_ticks - before
        print(f"\ncallback ran {ran} times in 400 paced ticks; tick {loop.stats.summary_us()} us")
        assert ran > 200 and loop.faults["device_error"] == 0
        assert loop.faults["invalid_sample"] < 40
        loop.close()
        assert fake.force == (0.0, 0.0, 0.0)
    finally:
        fake.stop_thread()


def test_a_scene_runs_on_a_touch_through_the_entry_point(monkeypatch):
    """`--device openhaptics:default` reaches the adapter through the `softproxy.devices` entry
    point; the knob scene runs 0.2 s with the scheduler in its own thread: forces finite and
    clamped, zero force and the scheduler stopped at the end."""
    from softproxy.run import open_device, run_scene
    from softproxy.scene import load_scene

    fake = FakeOpenHaptics()
    fake.pose_mm = [0.0, 70.0, 0.0]
    monkeypatch.setattr(ohmod, "load_binding", lambda: fake)
    fake.start_thread()
    try:
        scene = load_scene("knob")
        dev = open_device("openhaptics:default,max_force_N=0.5", scene)
        assert isinstance(dev, OpenHapticsDevice) and dev.max_force == 0.5
        try:
            result = run_scene(scene, dev, duration_s=0.2, realtime=True)
        finally:
            dev.close()
    finally:
        fake.stop_thread()
    assert result["ticks"] == 200 and result["faults"]["device_error"] == 0
    assert fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running
    assert_finite_and_clamped(fake.forces, 0.5)


def test_an_exception_in_a_with_block_leaves_zero_force_and_a_stopped_scheduler():
    """Leaving `with ServoLoop(...)` by an exception while pressing: the callback's last force is
    zero, the scheduler stopped and the device disabled."""
    dev, fake, clock = make()
    fake.pose_mm = [0.0, 66.0, 0.0]

    def step(_):
        clock.now += 0.001
        fake.step(1)

    fake.step(1)
    with pytest.raises(ZeroDivisionError):
        with box_loop(dev) as loop:
            loop.run(200, on_tick=step)
            assert max(np.linalg.norm(f) for f in fake.forces) > 0.5
            1 / 0
    assert fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running and fake.disabled and dev.closed


def test_close_waits_for_a_frame_begun_after_it():
    """A frame already under way when close() starts has read the old force; when it ends it must
    not pass for the zero: close() waits for a frame begun after it, so the last force written
    before the scheduler stops is zero. The scheduler runs in its own thread, as the real one;
    frames are gated so that each of close()'s waits lets exactly one more frame finish."""
    fake = FakeOpenHaptics()
    held, release, frame_waiting, gate = threading.Event(), threading.Event(), threading.Event(), threading.Semaphore(0)
    gating = [False]
    waits = [0]
    get_transform = fake.hd.get_transform

    def gated_get_transform():  # the start of a frame
        if gating[0]:
            frame_waiting.set()
            gate.acquire(timeout=1.0)
        return get_transform()

    def hold_a_frame(f):  # inside set_force: the frame has chosen its force
        if f != (0.0, 0.0, 0.0) and not held.is_set():
            held.set()
            gating[0] = True
            release.wait(1.0)

    def sleep(s):  # close() waiting: the frame under way ends; after the first wait, one more frame runs
        waits[0] += 1
        if waits[0] == 1:
            release.set()
        else:
            frame_waiting.clear()
            gate.release()
        frame_waiting.wait(1.0)

    fake.start_thread()
    try:
        dev = OpenHapticsDevice(fake, sleep=sleep, yield_gil=False)
        s = [DeviceSample()]
        deadline = time.monotonic() + 60.0  # a hang guard: load can delay the scheduler thread
        while not s[0].valid and time.monotonic() < deadline:
            time.sleep(0.002)
            dev.read(0.0, s)
        fake.hd.get_transform = gated_get_transform
        fake.set_force_hook = hold_a_frame
        dev.send(0, 0.0, 0.0, 0.5, 0.0, 0.0, 0.0)
        assert held.wait(60.0)
        dev.close()  # the frame under way writes 0.5 N after close() started
        assert fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running
    finally:
        gating[0] = False
        release.set()
        for _ in range(3):
            gate.release()
        fake.stop_thread()


def test_a_device_left_open_is_zeroed_and_stopped_at_exit():
    """The exit hook closes every device still open (its scheduler thread must not call into an
    interpreter being torn down): zero force last, scheduler stopped; closed devices are left out."""
    dev, fake, clock, s = rendering()
    assert fake.forces[-1] != (0.0, 0.0, 0.0)
    other, other_fake, _ = make()
    other.close()
    closes = len(other_fake.disabled)
    ohmod._OPEN.close_all()
    assert dev.closed and fake.forces[-1] == (0.0, 0.0, 0.0) and not fake.running and fake.disabled
    assert len(other_fake.disabled) == closes


def test_a_failed_open_leaves_a_running_device_alone():
    """The HD scheduler is the process's: a second device that fails to open must not stop the
    scheduler a device already open runs on."""
    dev, fake, clock = make()
    s = [DeviceSample()]
    tick(dev, fake, clock, s)
    fake.init_fails = True
    with pytest.raises(DeviceError, match="hdInitDevice failed"):
        OpenHapticsDevice(fake, device_name="Right")
    assert fake.running
    dev.close()
    assert not fake.running
