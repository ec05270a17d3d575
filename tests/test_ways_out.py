"""Every way out of every run path: the motor's last command is zero, and nothing follows it.

The paths a servo loop runs on: `tick()` from an application's loop, `run()` lockstep and
paced, with a Python device (called each tick) and with a compiled one (blocks of ticks
without the GIL), and `run_in_thread`. The ways out: every signal whose default ends the
process (in this process's main thread, as a terminal or a service manager sends them), an
exception in the application's code or in `on_tick`, a BaseException raised by a device's
zero send, `close()` from another thread while a block runs. Each case asserts what a
safety reviewer asks: every finger's last send is zero, the device was closed, and no send
happens after `close()` returns. Signals against a whole process: tests/test_safety.py.
"""

import gc
import math
import os
import signal
import threading
import time

import mujoco
import numpy as np
import pytest

from softproxy import servo, termination
from softproxy.device import DeviceSample
from softproxy.devices.simulated import SimulatedDevice
from softproxy.finger import FingerParams, SoftFingerProxy
from softproxy.fingertip import model
from softproxy.servo import ServoLoop
from softproxy.world import World

PLANE = """<mujoco><worldbody><geom name="floor" type="plane" size="1 1 0.1"/></worldbody></mujoco>"""
PRESS = 0.004  # m: how far below the floor's surface the fingers' devices go


class LoggingDevice:
    """Two fingers pressing into the floor (Python device); every send kept, with a lock-free
    append, and whether (and after how many sends) it was closed."""

    fingers = 2

    def __init__(self, max_force=5.0, max_torque=0.05):
        self.max_force, self.max_torque = max_force, max_torque
        self.sends = []
        self.closed = 0
        self.sends_at_close = None

    def read(self, t, samples):
        for i, s in enumerate(samples):
            s.x, s.y, s.z, s.twist = 0.03 * i, 0.0, 0.005 - min(t, 0.02) / 0.02 * (0.005 + PRESS), 0.0
            s.valid = True

    def send(self, finger, fx, fy, fz, tx, ty, tz):
        self.sends.append((finger, fx, fy, fz, tx, ty, tz))

    def close(self):
        self.closed += 1
        self.sends_at_close = len(self.sends)


def sim_device():
    """The simulated device (compiled read and send), two fingers pressing into the floor."""
    keys = [[(0.0, 0.03 * i, 0.0, 0.005, 0.0), (0.02, 0.03 * i, 0.0, -PRESS, 0.0), (1e4, 0.03 * i, 0.0, -PRESS, 0.0)]
            for i in range(2)]
    return SimulatedDevice(keys, max_force=5.0, max_torque=0.05)


def loop_for(device, **kwargs):
    world = World(mujoco.MjModel.from_xml_string(PLANE))
    fingers = [SoftFingerProxy(FingerParams(name=f"f{i}", radius=0.005, device_finger=i, soft_start=0.0),
                               world.shapes, model("CH")) for i in range(device.fingers)]
    return ServoLoop(world, fingers, device, 1000.0, overrun_watchdog=False, **kwargs)


def pressing(device) -> bool:
    """True once the device is being sent a force (the fingers press)."""
    if isinstance(device, SimulatedDevice):
        return any(math.hypot(*f) > 1.0 for f in device.last_force)
    return any(math.hypot(*s[1:4]) > 1.0 for s in device.sends[-2:])


def wait_pressing(device, thread=None, timeout=60.0):
    deadline = time.monotonic() + timeout
    while not pressing(device):
        assert time.monotonic() < deadline, "the fingers never pressed"
        assert thread is None or thread.is_alive(), "the servo thread ended early"
        time.sleep(0.002)


def sends_of(device) -> int:
    return device.sends if isinstance(device, SimulatedDevice) else len(device.sends)


def assert_left_safe(device, sends_when_closed):
    """Every finger's last send zero, the device closed, no send after close() returned."""
    time.sleep(0.05)  # a servo thread that had not stopped would send meanwhile
    assert sends_of(device) == sends_when_closed, "a send after close() returned"
    if isinstance(device, SimulatedDevice):
        assert device.closed
        assert all(f == (0.0, 0.0, 0.0) for f in device.last_force)
        assert all(t == (0.0, 0.0, 0.0) for t in device.last_torque)
    else:
        assert device.closed == 1
        last = {}
        for s in device.sends:
            last[s[0]] = s[1:]
        assert sorted(last) == [0, 1] and all(w == (0.0,) * 6 for w in last.values()), last
        assert device.sends_at_close == len(device.sends)  # closing came after the last zero


def _ending_signals():
    """Signals the termination module turns into an exit; one a test runner ignores (SIGHUP
    under nohup, SIGPIPE in every Python) is set back to its default for the test, as an
    application that wants it back does."""
    names = ("SIGTERM", "SIGHUP", "SIGINT", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGALRM", "SIGPIPE")
    return [getattr(signal, n) for n in names if hasattr(signal, n)]


@pytest.fixture
def default_signal(request):
    """The signal under test at its default disposition for the test's length (restored after)."""
    sig = request.param
    for other in list(servo._open_loops):  # loops other tests left open hold the handlers
        other.close()
    gc.collect()  # ... and those they dropped unclosed, until collected
    before = signal.getsignal(sig)
    if before is signal.SIG_IGN:  # Python ignores PIPE; nohup, HUP; a shell's background job, INT
        signal.signal(sig, termination._default(sig))
    elif before is not termination._default(sig):
        pytest.skip(f"{signal.Signals(sig).name} is handled by the test runner here")
    yield sig
    signal.signal(sig, before)


PATHS = ["thread-python", "thread-compiled", "run-python", "run-compiled", "tick"]


def _device_for(path):
    return sim_device() if path.endswith("compiled") else LoggingDevice()


def _signal_soon(sig, device, thread=None):
    """From a helper thread: once the fingers press, the signal to this process."""
    def fire():
        wait_pressing(device, thread)
        os.kill(os.getpid(), sig)
    threading.Thread(target=fire, daemon=True).start()


@pytest.mark.parametrize("default_signal", _ending_signals(), indirect=True,
                         ids=[signal.Signals(s).name for s in _ending_signals()])
@pytest.mark.parametrize("path", PATHS)
def test_a_deadly_signal_on_every_path_leaves_zero_and_nothing_after(default_signal, path):
    """SIGTERM, SIGHUP, SIGINT, SIGQUIT, SIGUSR1/2, SIGALRM, SIGPIPE while the fingers press:
    the signal becomes an exception in the main thread (`softproxy.termination`), the `with`
    block closes the loop, a servo thread is stopped before the zero goes out."""
    sig = default_signal
    device = _device_for(path)
    expected = KeyboardInterrupt if sig == signal.SIGINT else SystemExit
    with pytest.raises(expected) as out:
        with loop_for(device) as loop:
            if path.startswith("thread"):
                thread = loop.run_in_thread(10 ** 7, realtime=True)
                _signal_soon(sig, device, thread)
                thread.join(120)
                pytest.fail("the servo thread ran out before the signal came")
            elif path.startswith("run"):
                _signal_soon(sig, device)
                loop.run(120_000, realtime=True)
                pytest.fail("the run ended before the signal came")
            else:
                _signal_soon(sig, device)
                for _ in range(120_000):
                    loop.tick()
                    time.sleep(0.0002)
                pytest.fail("the ticks ended before the signal came")
    if expected is SystemExit:
        assert out.value.code == 128 + sig
    assert_left_safe(device, sends_of(device))


@pytest.mark.parametrize("path", ["thread-python", "thread-compiled"])
def test_an_exception_in_the_application_stops_the_servo_thread_first(path):
    """The application's own code raises inside `with ServoLoop(...)` while the servo thread
    runs: close() stops the thread, then sends zero; nothing is sent after it."""
    device = _device_for(path)
    with pytest.raises(ZeroDivisionError):
        with loop_for(device) as loop:
            thread = loop.run_in_thread(10 ** 7, realtime=True)
            wait_pressing(device, thread)
            1 / 0
    assert not thread.is_alive()
    assert_left_safe(device, sends_of(device))


@pytest.mark.parametrize("path", ["thread-python", "thread-compiled", "run-python", "run-compiled"])
def test_an_exception_in_on_tick_ends_the_run_with_zero(path):
    """on_tick raises: the run ends with zero force on every finger; in a thread, the
    exception is kept in `loop.error`."""
    device = _device_for(path)

    def on_tick(lp):
        if pressing(device):
            raise RuntimeError("the application's on_tick failed")

    loop = loop_for(device)
    if path.startswith("thread"):
        thread = loop.run_in_thread(10 ** 6, realtime=False, on_tick=on_tick, every=5)
        thread.join(120)
        assert isinstance(loop.error, RuntimeError)
    else:
        with pytest.raises(RuntimeError, match="on_tick failed"):
            loop.run(10 ** 6, on_tick=on_tick, every=5)
    if isinstance(device, SimulatedDevice):
        assert all(f == (0.0, 0.0, 0.0) for f in device.last_force)
    else:
        assert [s[1:] for s in device.sends[-2:]] == [(0.0,) * 6] * 2
    loop.close()
    assert_left_safe(device, sends_of(device))


@pytest.mark.parametrize("path", ["run-python", "run-compiled", "thread-python", "thread-compiled"])
def test_close_from_another_thread_stops_the_block_and_nothing_follows(path):
    """A block of ticks runs (here in the main thread, or in the servo thread) while another
    thread calls close(): the block stops, the last send is zero, nothing is sent after
    close() returns (counted over 50 ms)."""
    device = _device_for(path)
    loop = loop_for(device)
    closed = {}

    def closer():
        wait_pressing(device)
        loop.close()
        closed["sends"] = sends_of(device)

    other = threading.Thread(target=closer)
    other.start()
    if path.startswith("run"):
        loop.run(10 ** 7, realtime=True)  # returns once the other thread closed the loop
    else:
        thread = loop.run_in_thread(10 ** 7, realtime=True)
        thread.join(120)
        assert not thread.is_alive()
    other.join(120)
    assert loop.ticks < 10 ** 6
    assert_left_safe(device, closed["sends"])
    with pytest.raises(RuntimeError, match="closed"):
        loop.tick()


@pytest.mark.parametrize("raised", [KeyboardInterrupt, SystemExit])
def test_a_base_exception_in_one_zero_send_still_zeroes_every_finger(raised):
    """Finger 0's zero send raises KeyboardInterrupt (or an application's SystemExit): finger 1
    still gets its zero, the device is still closed, and the exception goes on up."""
    class Interrupted(LoggingDevice):
        armed = False

        def send(self, finger, fx, fy, fz, tx, ty, tz):
            super().send(finger, fx, fy, fz, tx, ty, tz)
            if self.armed and finger == 0 and not (fx or fy or fz):
                raise raised()

    device = Interrupted()
    loop = loop_for(device)
    loop.run(50)
    assert max(math.hypot(*s[1:4]) for s in device.sends) > 1.0  # it pressed
    device.armed = True
    with pytest.raises(raised):
        loop.close()
    assert [s[0] for s in device.sends[-2:]] == [0, 1] and not any(device.sends[-1][1:])
    assert device.closed == 1 and loop.closed


# -- limits re-read every tick, on every path ----------------------------------------------------

@pytest.mark.parametrize("path", ["run-python", "run-compiled", "thread-python", "thread-compiled", "tick"])
def test_a_device_that_derates_mid_run_is_obeyed_on_every_path(path):
    """The device's max_force drops from 5 N to 0.5 N while a run is in progress (from another
    thread, as firmware derating a hot motor would, in the middle of a block of compiled
    ticks): from the next tick on, every force the loop sends is within 0.5 N."""
    device = _device_for(path)
    loop = loop_for(device)
    derated, mark, seen = threading.Event(), [], []

    def derate():
        wait_pressing(device)
        device.max_force = 0.5
        mark.append(sends_of(device))
        derated.set()

    def sent(lp):  # what the loop sent each finger on its last tick (N)
        return max(math.hypot(*f.sent_force) for f in lp.rows.data)

    def on_tick(lp):
        if derated.is_set():
            seen.append(sent(lp))  # (the first may be of a tick begun before the derating)
            if len(seen) == 6:
                lp.request_stop()

    if path == "tick":
        threading.Thread(target=derate).start()
        while len(seen) < 6:
            loop.tick()
            time.sleep(0.0002)
            on_tick(loop)
    else:
        threading.Thread(target=derate).start()
        if path.startswith("thread"):
            loop.run_in_thread(10 ** 6, realtime=True, on_tick=on_tick, every=20).join(120)
        else:
            loop.run(10 ** 6, realtime=True, on_tick=on_tick, every=20)
    print(f"{path}: largest force sent after the derating, block by block: {np.round(seen, 3)} N")
    assert all(0.4 < f <= 0.5 + 1e-12 for f in seen[1:])  # still pressing, at the new clamp
    if not isinstance(device, SimulatedDevice):
        after = np.array([s[1:4] for s in device.sends[mark[0] + 4:]])  # (a tick in flight: 2 sends)
        assert (np.linalg.norm(after, axis=1) <= 0.5 + 1e-12).all()
    loop.close()


class RaisingLimit(LoggingDevice):
    """A device whose max_force property raises once broken."""

    broken = False

    @property
    def max_force(self):
        if self.broken:
            raise OSError("the motor driver stopped answering")
        return 5.0

    @max_force.setter
    def max_force(self, value):
        pass


@pytest.mark.parametrize("bad", [math.nan, -1.0, math.inf, 1e9, None, "2", "raises"])
@pytest.mark.parametrize("path", ["run-python", "run-compiled", "thread-python"])
def test_a_limit_that_turns_invalid_renders_zero_and_counts_a_fault(path, bad):
    """A limit outside [0, 1e6] (inf and 1e9 included: no clamp is not a clamp) or no number
    at all, set mid-run: zero force and an `unsafe_output` fault on every tick, whatever the path."""
    if bad == "raises":
        if path.endswith("compiled"):
            pytest.skip("the simulated device's limits are plain numbers in its state")
        device = RaisingLimit()
    else:
        device = _device_for(path)
        if path.endswith("compiled") and not isinstance(bad, float):
            pytest.skip("the simulated device refuses a limit that is no number (TypeError)")
    loop = loop_for(device)
    loop.run(60)
    if bad == "raises":
        device.broken = True
    else:
        device.max_force = bad
    faults = loop.faults["unsafe_output"]
    before = sends_of(device)
    if path.startswith("thread"):
        loop.run_in_thread(40, realtime=False).join(120)
    else:
        loop.run(40)
    assert loop.faults["unsafe_output"] == faults + 2 * 40  # two fingers, 40 ticks
    if isinstance(device, SimulatedDevice):
        assert device.sends == before + 2 * 40 + 2
        assert all(f == (0.0, 0.0, 0.0) for f in device.last_force)
        assert all(math.hypot(*f.sent_force) == 0.0 for f in loop.rows.data)
    else:
        assert not any(any(s[1:]) for s in device.sends[before:])
    loop.close()


# -- samples: whatever a device puts there ---------------------------------------------------------

class Breaks(Exception):
    pass


class BadFloat:
    def __float__(self):
        raise Breaks("no float here")


def _spoil(samples, how):
    if how == "valid-array":
        samples[0].valid = np.array([True, False])
    elif how == "float-raises":
        samples[0].x = BadFloat()
    elif how == "none":
        samples[0] = None
    elif how == "object":
        samples[0] = object()
    elif how == "shortened":
        samples.pop()
    elif how == "emptied":
        samples.clear()
    elif how == "lengthened":
        samples.append(DeviceSample())
    elif how == "numpy-valid":
        samples[0].valid = np.array(True)  # one truth value: a valid sample


@pytest.mark.parametrize("how", ["valid-array", "float-raises", "none", "object", "shortened", "emptied",
                                 "lengthened", "numpy-valid"])
def test_no_exception_escapes_a_tick_from_a_sample(how):
    """What a device leaves in the sample list is untrusted: an array for `valid`, a field whose
    `__float__` raises, None or another object in place of a sample, a list shortened or
    emptied. tick() never raises; the finger whose sample is broken renders zero and counts an
    invalid sample; the list is repaired so the next read has DeviceSamples to fill."""
    class Spoiling(LoggingDevice):
        spoil = False

        def read(self, t, samples):
            super().read(t, samples)
            if self.spoil:
                _spoil(samples, how)

    device = Spoiling()
    loop = loop_for(device)
    loop.run(50)
    device.spoil = True
    invalid = loop.faults["invalid_sample"]
    n = len(device.sends)
    for _ in range(10):
        loop.tick()
    sent = device.sends[n:]
    assert len(sent) == 20 and len(loop.samples) == 2
    assert all(isinstance(s, DeviceSample) for s in loop.samples)
    broken = {"valid-array": [0], "float-raises": [0], "none": [0], "object": [0], "shortened": [1],
              "emptied": [0, 1], "lengthened": [], "numpy-valid": []}[how]
    assert loop.faults["invalid_sample"] == invalid + 10 * len(broken)
    for finger in (0, 1):
        forces = [math.hypot(*s[1:4]) for s in sent if s[0] == finger]
        if finger in broken:
            assert forces == [0.0] * 10
        else:
            assert min(forces) > 1.0  # still pressing
    device.spoil = False
    loop.run(5)
    assert pressing(device) or device.sends[-1][1:] == (0.0,) * 6
    loop.close()


# -- one device, one open loop -------------------------------------------------------------------

def test_a_device_belongs_to_one_open_loop_at_a_time():
    """A second loop on a device an open loop drives is refused (two loops would send it two
    forces, and closing one would leave the other driving a closed device); once the first is
    closed, or dropped, the device is free."""
    device = LoggingDevice()
    first = loop_for(device)
    with pytest.raises(ValueError, match="already driven by an open ServoLoop"):
        loop_for(device)
    first.close()
    second = loop_for(device)
    del second
    import gc
    gc.collect()
    third = loop_for(device)
    third.close()
