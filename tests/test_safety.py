"""Fault injection: the motor is never left driven and never sent NaN or more than its clamps.

The property (README, Safety): every way out of a run — normal end, exception, SIGINT,
SIGTERM, SIGHUP, the application's own exit — sends zero force to every finger and closes
the device; whatever the parameters, the model or the device say, what reaches `send()` is
finite and within the finger's and the device's limits, and anything else is zero force and
a counted fault. Each attack prints its counts (`pytest -s` shows them). The HID transport
that fails and recovers is attacked in test_hid_safety.py; recordings in test_recording.py.
"""

import gc
import math
import os
import signal
import subprocess
import sys
import textwrap
import time
import warnings

import mujoco
import numpy as np
import pytest

from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.input_error import UnitWarning
from softproxy import servo
from softproxy.servo import ServoLoop
from softproxy.world import World

PLANE = """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 0.1"/>
<body name="puck" pos="0.1 0 0.01"><freejoint/><geom type="box" size="0.02 0.02 0.01" mass="0.1"/></body>
</worldbody></mujoco>"""


class PressingDevice:
    """One or two fingers pressing 2 mm into the floor; keeps every send and whether it was closed."""

    def __init__(self, fingers=1, max_force=5.0, max_torque=0.05):
        self.fingers, self.max_force, self.max_torque = fingers, max_force, max_torque
        self.sends = []
        self.closed = 0
        self.garbage = None  # (field, value) written into finger 0's sample instead of a number
        self.twist_rate = 0.3  # rad/s

    def read(self, t, samples):
        for i, s in enumerate(samples):
            s.x, s.y, s.z, s.twist = 0.03 * i, 0.0, 0.008 - min(t, 0.05) * 0.1, self.twist_rate * t
            s.qw, s.qx, s.qy, s.qz = 1.0, 0.0, 0.0, 0.0
            s.valid = True
        if self.garbage is not None:
            setattr(samples[0], *self.garbage)

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.sends.append((finger, fx, fy, fz, tx, ty, tz))

    def close(self):
        self.closed += 1


def loop_on_plane(device, **params):
    world = World(mujoco.MjModel.from_xml_string(PLANE))
    params = {"soft_start": 0.0, **params}
    fingers = [SoftFingerProxy(FingerParams(name=f"f{i}", radius=0.005, device_finger=i, **params),
                               world.shapes, model("CH")) for i in range(device.fingers)]
    return ServoLoop(world, fingers, device, 1000.0, overrun_watchdog=False)


def assert_sends_safe(device, fmax, tmax):
    """Every send finite and within |F| ≤ fmax, |M| ≤ tmax (a rounding's worth over)."""
    w = np.array([s[1:] for s in device.sends], dtype=float)
    assert np.isfinite(w).all()
    assert (np.linalg.norm(w[:, :3], axis=1) <= fmax * (1 + 1e-12)).all()
    assert (np.linalg.norm(w[:, 3:], axis=1) <= tmax * (1 + 1e-12)).all()
    return w


def _deadly_signals_by_default() -> None:
    """In the child before exec: every signal whose default ends the process at that default and
    none blocked, as a terminal finds them. A shell that runs the tests in the background ignores
    SIGINT, `nohup` ignores SIGHUP, children inherit both, and the signal then never arrives."""
    for sig in (signal.SIGHUP, signal.SIGINT, signal.SIGQUIT, signal.SIGTERM, signal.SIGUSR1,
                signal.SIGUSR2, signal.SIGALRM, signal.SIGPIPE):
        signal.signal(sig, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_SETMASK, [])


@pytest.mark.parametrize("field", ["damping", "torsion_damping"])
def test_broken_gains_render_zero_and_count_a_fault(field):
    """Gains past what validation admits (set on a live finger: 1e308) make the wrench Inf/NaN:
    the device and the body get zero, and each such tick is an `unsafe_output` fault."""
    device = PressingDevice()
    device.twist_rate = 0.0  # b_τ·d(stretch)/dt is then Inf·0 = NaN
    loop = loop_on_plane(device)
    loop.run(40)  # in contact, pressing
    assert np.linalg.norm(device.sends[-2][1:4]) > 1.0
    assert not loop.faults["unsafe_output"]
    before = len(device.sends)
    f = loop.fingers[0]
    attr = {"damping": "b", "torsion_damping": "b_tau"}[field]
    setattr(f, attr, 1e308)
    loop.run(60)
    w = assert_sends_safe(device, 5.0, 0.05)
    late = w[before:-1]  # the run's ticks after the change (the last send is stop()'s zero)
    print(f"{field}=1e308: {len(late)} sends, "
          f"{loop.faults['unsafe_output']} unsafe outputs, largest |F| {np.linalg.norm(late[:, :3], axis=1).max():.3g} N")
    assert loop.faults["unsafe_output"] > 0
    assert np.isfinite(loop.world.data.qpos).all() and np.isfinite(loop.world.data.xfrc_applied).all()


def test_a_device_limit_that_turns_nan_mid_run_zeroes_the_force():
    """A device whose max_force becomes NaN, None, negative or a string after the loop was built:
    zero force and a fault each tick, until the limit is a number again."""
    device = PressingDevice(max_force=2.0)
    loop = loop_on_plane(device, stiffness=5000.0)
    loop.run(50)
    w = assert_sends_safe(device, 2.0, 0.05)
    assert np.linalg.norm(w[-2, :3]) > 1.9  # pressing at the device's clamp, not the finger's 40 N
    for bad in (math.nan, None, -1.0, "2"):
        device.max_force = bad
        n = len(device.sends)
        faults = loop.faults["unsafe_output"]
        loop.run(10)
        assert not np.any([s[1:] for s in device.sends[n:]]), f"max_force={bad!r} let a force through"
        assert loop.faults["unsafe_output"] == faults + 10
        device.max_force = 2.0


@pytest.mark.parametrize("value", [math.nan, math.inf, -1.0, None, "2", 1e9])
def test_a_device_with_broken_limits_is_refused_when_the_loop_is_built(value):
    """A NaN limit would switch the clamp off (15 N sent against 2 N): refused, naming the device."""
    device = PressingDevice()
    device.max_torque = value
    with pytest.raises(ValueError, match="PressingDevice: max_torque"):
        loop_on_plane(device)


def test_a_device_missing_the_protocol_is_refused():
    class NoSend:
        fingers, max_force, max_torque = 1, 1.0, 0.0

        def read(self, t, samples):
            pass

    with pytest.raises(TypeError, match=r"NoSend is not a softproxy.Device: it has no send\(\) or close\(\)"):
        loop_on_plane(NoSend())


def test_a_device_method_of_the_wrong_signature_is_refused():
    """A send that takes only the force (it would raise on every tick: counted, but silent) and
    a read without the time: refused when the loop is built, naming the method and both
    signatures; a method taking *args, or with defaults, is fine."""
    class ForceOnly(PressingDevice):
        def send(self, finger, fx, fy, fz):
            pass

    with pytest.raises(TypeError, match=r"ForceOnly: send must take \(finger, fx, fy, fz, tx, ty, tz\), its "
                                        r"signature is send\(finger, fx, fy, fz\)"):
        loop_on_plane(ForceOnly())

    class NoTime(PressingDevice):
        def read(self, samples):
            pass

    with pytest.raises(TypeError, match=r"NoTime: read must take \(t, samples\), its signature is read\(samples\)"):
        loop_on_plane(NoTime())

    class Loose(PressingDevice):
        def send(self, finger, *wrench, gain=1.0):
            super().send(finger, *wrench)

    loop_on_plane(Loose()).close()


def test_a_device_reporting_in_mm_is_warned_of_at_start():
    """A device whose first sample lies 8 m up (8 mm typed as m: the finger would hover far
    above everything, rendering nothing, no fault): one UnitWarning at start naming the device,
    the finger and the position; a device in m: none; one beyond the workspace (±1 km):
    none either, its samples are refused as garbage (counted)."""
    class InMillimetres(PressingDevice):
        def read(self, t, samples):
            super().read(t, samples)
            samples[0].z *= 1e3

    loop = loop_on_plane(InMillimetres())
    with pytest.warns(UnitWarning, match=r"device InMillimetres finger 0: position is \(0\.0, 0\.0, 8\.0\) m: in mm\?"):
        loop.start()
    loop.close()
    class Garbage(PressingDevice):
        def read(self, t, samples):
            super().read(t, samples)
            samples[0].z = 3e16

    for device in (PressingDevice(), Garbage()):
        quiet = loop_on_plane(device)
        with warnings.catch_warnings():
            warnings.simplefilter("error", UnitWarning)
            quiet.start()
        quiet.close()


GARBAGE = [None, "0.01", b"x", np.array([0.0, 1.0]), [0.0], 10 ** 400, math.nan, -math.inf, 1e400j, object()]
NUMBERS = [0, np.float32(0.004), np.float64(0.004), np.array(0.004), np.int64(0)]


def test_sample_fields_of_the_wrong_type_are_invalid_samples():
    """None, str, arrays, 10**400 in any field or in `valid`: never an exception out of tick(),
    a send every tick for every finger, zero force that tick, one invalid_sample each; numbers
    of other types (int, numpy scalars) are used as the floats they are."""
    device = PressingDevice(fingers=2)
    loop = loop_on_plane(device)
    loop.run(30)
    fields = ("x", "y", "z", "twist", "qw", "qx", "valid")
    rng = np.random.default_rng(7)
    garbage_ticks = 0
    for k in range(300):
        kind = rng.integers(3)
        if kind == 0:
            device.garbage = (fields[rng.integers(len(fields))], GARBAGE[rng.integers(len(GARBAGE))])
        elif kind == 1:
            device.garbage = (fields[rng.integers(4)], NUMBERS[rng.integers(len(NUMBERS))])
        else:
            device.garbage = ("valid", [True, 1, np.bool_(True)][rng.integers(3)])
        before_faults, before_sends = loop.faults["invalid_sample"], len(device.sends)
        loop.tick()
        assert len(device.sends) == before_sends + 2
        if kind == 0:
            garbage_ticks += 1
            assert loop.faults["invalid_sample"] == before_faults + 1, device.garbage
            assert device.sends[-2][0] == 0 and not any(device.sends[-2][1:])
        else:
            assert loop.faults["invalid_sample"] == before_faults, device.garbage
            assert loop.fingers[0].valid
    loop.stop()
    assert_sends_safe(device, 5.0, 0.05)
    print(f"garbage samples: {garbage_ticks} garbage ticks of 300, "
          f"{loop.faults['invalid_sample']} invalid samples counted, {len(device.sends)} sends, all finite")


def test_leaving_a_with_block_sends_zero_and_closes_the_device():
    device = PressingDevice(fingers=2)
    with pytest.raises(ZeroDivisionError):
        with loop_on_plane(device) as loop:
            loop.run(40)
            assert any(any(s[1:]) for s in device.sends[-4:])
            for _ in range(5):
                loop.tick()
            1 / 0
    assert device.closed == 1
    assert sorted(s[0] for s in device.sends[-2:]) == [0, 1] and not any(any(s[1:]) for s in device.sends[-2:])
    assert not loop.world.data.xfrc_applied.any()
    loop.close()  # twice is fine
    assert device.closed == 1
    with pytest.raises(RuntimeError, match="closed"):
        loop.tick()


def test_a_signal_during_the_zero_force_waits_until_it_is_sent():
    """SIGTERM arriving while stop() sends zero force (a second kill, a second Ctrl-C) is held
    until every finger got its zero, then ends the program (SystemExit 143)."""
    gc.collect()  # loops other tests dropped unclosed give their claim on the handlers back
    for other in list(servo._open_loops):
        other.close()
    if signal.getsignal(signal.SIGTERM) is not signal.SIG_DFL:
        pytest.skip("SIGTERM is handled by the test runner here")

    class KilledWhileStopping(PressingDevice):
        def send(self, finger, *w):
            super().send(finger, *w)
            if self.stopping and finger == 0:
                os.kill(os.getpid(), signal.SIGTERM)
                time.sleep(0.01)  # the handler runs here, in the middle of stop()

    device = KilledWhileStopping(fingers=2)
    device.stopping = False
    loop = loop_on_plane(device)
    loop.run(40)
    device.stopping = True
    with pytest.raises(SystemExit) as exit_:
        loop.close()
    assert exit_.value.code == 128 + signal.SIGTERM
    assert [s[0] for s in device.sends[-2:]] == [0, 1] and not any(any(s[1:]) for s in device.sends[-2:])
    assert device.closed == 1
    assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL  # handed back once the last loop closed


# -- signals against a real process ------------------------------------------------------------

CHILD = textwrap.dedent("""
    import sys, time
    from softproxy.run import open_device, build, run_scene
    from softproxy.scene import load_scene

    log = open(sys.argv[1], "w", buffering=1)

    class Logged:
        '''The scene's simulated device, every send and the close written to a log as they happen.'''
        def __init__(self, inner):
            self.inner = inner
            self.fingers, self.max_force, self.max_torque = inner.fingers, inner.max_force, inner.max_torque
        def read(self, t, samples):
            self.inner.read(t, samples)
        def send(self, finger, *w):
            log.write(f"send {finger} " + " ".join(repr(v) for v in w) + "\\n")
        def close(self):
            log.write("close\\n")
            self.inner.close()

    scene = load_scene("two_finger_grasp")
    device = Logged(open_device("sim", scene))
    how = sys.argv[2]
    if how == "cli":  # the softproxy command itself, with its device logged
        import softproxy.run as run_module
        from softproxy.cli import main
        run_module.open_device = lambda kind, scene: device
        sys.exit(main(["run", "two_finger_grasp", "--headless", "--realtime", "--duration", "60"]))
    loop = build(scene, device)
    if how == "embedded":  # an application's own loop: no with, no run(), no close()
        while True:
            loop.tick()
            time.sleep(0.0005)
    elif how == "thread":  # the servo in its own thread, the main thread waiting on it (no with, no close)
        thread = loop.run_in_thread(60_000, realtime=True)
        thread.join()
    elif how == "raises":
        def boom(lp):
            if lp.ticks == 3000:
                raise RuntimeError("the application's on_tick failed")
        loop.run(60_000, realtime=True, on_tick=boom)
    else:
        loop.run(60_000, realtime=True)
""")


def _last_sends(log: str) -> dict:
    last = {}
    for line in log.splitlines():
        if line.startswith("send "):
            _, finger, *w = line.split()
            last[int(finger)] = [float(v) for v in w]
    return last


@pytest.mark.parametrize("how, sig", [
    ("run", signal.SIGTERM), ("run", signal.SIGHUP), ("run", signal.SIGINT),
    ("embedded", signal.SIGTERM), ("embedded", signal.SIGHUP), ("cli", signal.SIGTERM), ("cli", signal.SIGHUP),
    ("thread", signal.SIGTERM), ("thread", signal.SIGQUIT), ("thread", signal.SIGUSR1), ("cli", signal.SIGQUIT),
    ("cli", signal.SIGUSR1), ("run", signal.SIGALRM), ("raises", None),
])
def test_every_way_out_of_a_run_sends_zero_force(tmp_path, how, sig):
    """A process running the grasp (holding ~3 N per finger), in the main thread or in a servo
    thread, is killed, hung up, interrupted, sent SIGQUIT, SIGUSR1 or SIGALRM, or its application
    raises: the last thing each finger was sent is zero, and the device was closed."""
    log = tmp_path / "sends.log"
    proc = subprocess.Popen([sys.executable, "-c", CHILD, str(log), how], stdout=subprocess.DEVNULL,
                            preexec_fn=_deadly_signals_by_default,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        # a hang guard, not a bound: on a loaded 2-core machine a child that first compiles the
        # servo tick (its cache stale) took over 120 s to hold the box
        deadline = time.monotonic() + 600
        while time.monotonic() < deadline and proc.poll() is None:  # until it holds the box
            text = log.read_text() if log.exists() else ""
            if text.count("\n") > 2600 and any(math.hypot(*w[:3]) > 1.0 for w in _last_sends(text).values()):
                break
            time.sleep(0.05)
        if sig is not None:
            assert proc.poll() is None, proc.stderr.read()
            os.kill(proc.pid, sig)
        code = proc.wait(30)
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    text = log.read_text()
    last = _last_sends(text)
    sends = text.count("send ")
    print(f"{how}, {signal.Signals(sig).name if sig else 'exception'}: exit {code}, {sends} sends, "
          f"last sends {last}, closed {'close' in text}")
    assert sorted(last) == [0, 1]
    assert all(w == [0.0] * 6 for w in last.values())
    assert text.rstrip().endswith("close")
    assert sends > 2000  # it had been holding the box
    if sig not in (None, signal.SIGINT):
        assert code == 128 + sig


def test_after_a_device_outage_the_force_ramps_back_in():
    """The device fails for 0.3 s while the hand pushes 15 mm deeper: when it is back, the
    force comes back over the soft start (0.1 s), not as a one-tick kick to the spring's 30 N."""
    from softproxy.device import DeviceError

    class Outage(PressingDevice):
        down = False
        depth = 0.0

        def read(self, t, samples):
            if self.down:
                raise DeviceError("unplugged")
            super().read(t, samples)
            samples[0].z -= self.depth

    device = Outage(max_force=40.0)
    loop = loop_on_plane(device, soft_start=0.1)
    loop.run(100)
    assert 3.0 < np.linalg.norm(device.sends[-2][1:4]) < 5.0
    device.down, device.depth = True, 0.015
    loop.run(300)
    assert loop.faults["device_error"] == 300
    device.down = False
    n = len(device.sends)
    loop.run(150)
    force = np.linalg.norm(np.array([s[1:4] for s in device.sends[n:-1]]), axis=1)
    print(f"after 0.3 s without a device: first force {force[0]:.2f} N, "
          f"at 50 ms {force[50]:.1f} N, at 140 ms {force[140]:.1f} N")
    assert force[0] < 0.5
    assert 10.0 < force[50] < 25.0  # half way up the ramp of the 40 N clamp
    assert force[140] > 29.0  # the spring's 30 N once the ramp is done
