"""The compiled device protocol (softproxy/device_kernel.py) of the simulated and replay devices:
their read/send cfuncs, called from a compiled kernel that takes them as arguments, give the
samples, counters and error messages of the Python read/send bit for bit; garbage inputs give
an error code, never a crash or a write outside the rows given."""

import copy
import json
import math
import os
import struct
import subprocess
import sys
import textwrap
import types

import numpy as np
import pytest
from numba import njit

from softproxy.devices.replay import ReplayDevice
from softproxy.devices.simulated import FAULT_KINDS, STALL_S, SimulatedDevice
from softproxy import device_kernel as dk
from softproxy.device import DeviceError, DeviceSample

KEYS = [(0.0, 0.0, 0.0, 0.1, 0.0), (0.2, 0.02, -0.01, 0.05, 0.4), (0.3, 0.02, -0.01, 0.05, 0.4),
        (0.6, -0.03, 0.01, 0.08, -0.2)]
OTHER = [(0.1, 0.01, 0.02, 0.03, 0.1), (0.5, -0.01, 0.0, 0.06, 0.3)]
pytestmark = pytest.mark.skipif(not dk.JIT, reason="no cfunc under NUMBA_DISABLE_JIT=1; the interpreted kernels "
                                "are compared with the compiled ones in a subprocess here")

EVERYTHING = dict(noise_m=2e-4, noise_rad=3e-3, latency_s=0.004, quantum_m=1e-5, quantum_rad=1e-3, seed=17,
                  faults={"nan": 0.03, "drop": 0.03, "spike": 0.03, "stall": 0.01})


def sim(**kw):
    return SimulatedDevice([KEYS, OTHER], **kw)


def script_times():
    """Loop times (s): forward at 1 ms through the script and past its end, a jump back, a jump
    before the start and the infinities (NaN is garbage, tested apart)."""
    t = [k * 1e-3 for k in range(700)]
    return np.array(t + [0.25, 0.1, -1.0, 0.45, math.inf, -math.inf, 0.31, 5.0])


# --- compiled kernels taking the device's cfuncs as arguments (what the servo loop does) -------------

@njit(cache=True)
def run_reads(read, address, times, out, codes):
    """read(t) for each time, into out[k] (one row per finger): the codes."""
    for k in range(times.shape[0]):
        row = out[k]
        codes[k] = read(address, times[k], row.ctypes.data, row.shape[0])


@njit(cache=True)
def read_raw(read, address, t, samples_address, n):
    """One read with whatever addresses and row count (garbage included)."""
    return read(address, t, samples_address, n)


@njit(cache=True)
def run_sends(send, address, fingers, wrenches, codes):
    """send(fingers[k], *wrenches[k]) for each k: the codes."""
    for k in range(fingers.shape[0]):
        w = wrenches[k]
        codes[k] = send(address, fingers[k], w[0], w[1], w[2], w[3], w[4], w[5])


def compiled_reads(device, times):
    """(SAMPLE rows, codes) of reading `device` through its cfunc at each time."""
    io = device.compiled_io()
    out = np.zeros((len(times), device.fingers), dtype=dk.SAMPLE)
    codes = np.zeros(len(times), dtype=np.int64)
    run_reads(io.read, io.address, times, out, codes)
    return out, codes


def python_reads(device, times):
    """(SAMPLE rows, messages) of reading `device` through its Python read at each time:
    a row of a failed read is left zero and its message kept."""
    out = np.zeros((len(times), device.fingers), dtype=dk.SAMPLE)
    messages = [""] * len(times)
    samples = [DeviceSample() for _ in range(device.fingers)]
    for k, t in enumerate(times):
        try:
            device.read(float(t), samples)
        except (DeviceError, ValueError) as exc:
            messages[k] = str(exc)
            continue
        out[k] = [tuple(getattr(s, name) for name in dk.SAMPLE_FIELDS) for s in samples]
    return out, messages


def raw(rows):
    """The bytes of each read's rows (a uint8 view: a copy of a structured array may not keep
    its padding bytes)."""
    return rows.view(np.uint8).reshape(len(rows), -1)


def assert_same_reads(a, b):
    """Two devices of the same settings, one read through Python and one through its cfunc:
    every read gives the same bytes or the same one-line message. Returns the cfunc's codes."""
    times = script_times()
    py, messages = python_reads(a, times)
    out, codes = compiled_reads(b, times)
    io = b.compiled_io()
    failed = codes != 0
    assert [m != "" for m in messages] == failed.tolist()
    assert [io.read_error(c) for c in codes[failed]] == [m for m in messages if m]
    assert all("\n" not in m for m in messages)
    assert np.array_equal(raw(py)[~failed], raw(out)[~failed])  # bit for bit, NaN and padding included
    return codes


# --- the simulated device -------------------------------------------------------------------------

def test_sim_cfunc_reads_are_the_python_reads_bit_for_bit():
    """Noise, quantisation, latency, every fault kind (stall included), jumps back and past the
    script: the cfunc and the Python read give the same samples and the same failures."""
    a, b = sim(**EVERYTHING), sim(**EVERYTHING)
    codes = assert_same_reads(a, b)
    io = b.compiled_io()
    assert io.stall_code == codes.max() and io.stall_s == STALL_S  # the only failure was a stall
    assert a.injected == b.injected and all(a.injected[kind] > 0 for kind in FAULT_KINDS)
    assert (codes == io.stall_code).sum() == b.injected["stall"]


def test_sim_python_and_compiled_reads_share_one_state():
    """Reads alternating between Python and the cfunc continue one noise and fault stream: the
    same samples as a device read only from Python (nothing to sync after a compiled run)."""
    settings = dict(EVERYTHING, faults={"nan": 0.05, "drop": 0.05, "spike": 0.05})
    times = script_times()
    only_python, _ = python_reads(sim(**settings), times)
    mixed = sim(**settings)
    io = mixed.compiled_io()
    rows = np.zeros((len(times), 2), dtype=dk.SAMPLE)
    samples = [DeviceSample(), DeviceSample()]
    for k, t in enumerate(times):
        if k % 3:
            mixed.read(float(t), samples)
            rows[k] = [tuple(getattr(s, name) for name in dk.SAMPLE_FIELDS) for s in samples]
        else:
            assert read_raw(io.read, io.address, t, address(rows[k]), 2) == 0
    assert rows.tobytes() == only_python.tobytes()


def test_a_copied_device_runs_on_its_own_state():
    """copy.deepcopy of a device midway: both continue the same stream, and the copy's cfuncs
    and Python read touch the copy's arrays only (no address of the original survives)."""
    settings = dict(EVERYTHING, faults={"nan": 0.05, "drop": 0.05, "spike": 0.05})
    times = script_times()
    original = sim(**settings)
    python_reads(original, times[:100])
    twin = copy.deepcopy(original)
    before = [a.copy() for a in original.compiled_io().state]
    mine, _ = compiled_reads(twin, times[100:300])
    assert all(np.array_equal(x, y) for x, y in zip(before, original.compiled_io().state))
    theirs, _ = compiled_reads(original, times[100:300])
    assert np.array_equal(raw(mine), raw(theirs))
    assert python_reads(twin, times[300:])[0].tobytes() == python_reads(original, times[300:])[0].tobytes()


def test_sim_sends_through_the_cfunc_count_what_python_sends_count():
    """The same wrenches (inside and beyond the clamps, NaN, infinite, huge) sent from Python and
    through the cfunc leave the same counters, largest force and rendered wrenches."""
    rng = np.random.default_rng(4)
    wrenches = rng.normal(0.0, 15.0, (60, 6))
    wrenches[5, 2] = math.nan
    wrenches[9, 4] = -math.inf
    wrenches[13] = (1e308, 1e308, 0.0, 0.0, 0.0, 1e300)
    wrenches[20] = 0.0
    fingers = rng.integers(0, 2, 60)
    a, b = sim(max_force=12.0, max_torque=0.3), sim(max_force=12.0, max_torque=0.3)
    for f, w in zip(fingers.tolist(), wrenches.tolist()):
        a.send(f, *w)
    io = b.compiled_io()
    codes = np.ones(60, dtype=np.int64)
    run_sends(io.send, io.address, fingers, wrenches, codes)
    assert not codes.any()
    assert (b.sends, b.nan_sends, b.max_force_sent) == (a.sends, a.nan_sends, a.max_force_sent)
    assert (b.sends, b.nan_sends) == (60, 2)
    assert b.max_force_sent > 1e308  # what was asked, before the saturation
    assert b.last_force == a.last_force and b.last_torque == a.last_torque
    assert all(math.hypot(*f) <= 12.0 * (1 + 1e-12) for f in b.last_force)


def test_sim_garbage_sends_are_refused_and_touch_nothing():
    """A finger the device does not have: an error code through the cfunc and IndexError from
    Python, with the same message; no counter and no wrench changes."""
    dev = sim()
    dev.send(1, 1.0, 2.0, 3.0, 0.0, 0.0, 0.1)
    io = dev.compiled_io()
    before = [a.copy() for a in io.state]
    codes = np.zeros(4, dtype=np.int64)
    run_sends(io.send, io.address, np.array([-1, 2, 2**62, -2**63]), np.ones((4, 6)), codes)
    assert (codes > 0).all() and len(set(codes.tolist())) == 1
    assert all(np.array_equal(x, y) for x, y in zip(before, io.state))
    with pytest.raises(IndexError) as err:
        dev.send(2, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert str(err.value) == io.read_error(codes[0]) == "simulated device: no such finger (the device has 2: 0 to 1)"
    assert dev.sends == 1


def test_sim_closed_and_stalled_reads_say_what_python_says():
    """A stall: the Python read waits stall_s and raises; the cfunc returns the stall code at once
    and the loop is told how long to wait. A closed device: the same message both ways."""
    dev = sim(faults={"stall": 1.0})
    io = dev.compiled_io()
    rows = np.zeros(2, dtype=dk.SAMPLE)
    code = read_raw(io.read, io.address, 0.1, address(rows), 2)
    assert code == io.stall_code and io.stall_s == STALL_S
    with pytest.raises(DeviceError) as err:
        dev.read(0.1, [DeviceSample(), DeviceSample()])
    assert str(err.value) == io.read_error(code) == "simulated device: no answer within 5 ms"
    dev.close()
    code = read_raw(io.read, io.address, 0.1, address(rows), 2)
    with pytest.raises(DeviceError) as err:
        dev.read(0.1, [DeviceSample(), DeviceSample()])
    assert code > 0 and str(err.value) == io.read_error(code) == "simulated device is closed"
    assert dev.injected["stall"] == 2


def address(rows):
    """The address of a SAMPLE array as the cfuncs take it (np.uintp: a FunctionType call must
    match its signature exactly)."""
    return np.uintp(rows.ctypes.data)


def sentinel_rows(n):
    rows = np.zeros(n, dtype=dk.SAMPLE)
    rows.view(np.uint8)[:] = 0xAB
    return rows


@pytest.mark.parametrize("make", [lambda tmp: sim(**EVERYTHING), lambda tmp: ReplayDevice(write_v2(tmp / "r.rec"))],
                         ids=["sim", "replay"])
def test_garbage_reads_give_an_error_code_and_write_nothing(make, tmp_path):
    """NaN time, a row count other than the device's fingers (more, fewer, negative), a null
    samples or state address: an error code, nothing written to the rows, no random number or
    recorded read used up (the next good read is a fresh device's first)."""
    dev, fresh = make(tmp_path), make(tmp_path)
    io = dev.compiled_io()
    rows = sentinel_rows(io.fingers + 1)
    untouched = rows.tobytes()
    for t, n in ((math.nan, io.fingers), (0.1, io.fingers + 1), (0.1, io.fingers - 1), (0.1, 0), (0.1, -1),
                 (0.1, 2**62)):
        code = read_raw(io.read, io.address, t, address(rows), n)
        assert code > 0, (t, n)
        assert rows.tobytes() == untouched, (t, n)
        assert "\n" not in io.read_error(code)
    assert read_raw(io.read, io.address, 0.1, np.uintp(0), io.fingers) > 0
    assert read_raw(io.read, np.uintp(0), 0.1, address(rows), io.fingers) > 0
    assert rows.tobytes() == untouched
    code = read_raw(io.read, io.address, math.nan, address(rows), io.fingers)
    assert io.read_error(code).endswith("read time must be a number, got nan")
    with pytest.raises((DeviceError, ValueError), match="read time must be a number"):
        dev.read(math.nan, [DeviceSample() for _ in range(io.fingers)])
    code = read_raw(io.read, io.address, 0.1, address(rows), io.fingers + 1)
    name = "simulated device" if isinstance(dev, SimulatedDevice) else "replay device"
    assert io.read_error(code) == f"{name}: the samples array must have one row per finger ({io.fingers})"
    good, _ = compiled_reads(dev, np.array([0.1, 0.2]))
    expected, _ = compiled_reads(fresh, np.array([0.1, 0.2]))
    assert good.tobytes() == expected.tobytes()


def test_fault_rates_and_noise_through_the_cfunc():
    """20 000 reads in one compiled call: each fault kind is injected at its rate (within 4.5
    binomial standard deviations) and the noise has the configured standard deviation."""
    rates = {"nan": 0.02, "drop": 0.05, "spike": 0.01, "stall": 0.03}
    dev = SimulatedDevice([KEYS], noise_m=1e-3, noise_rad=2e-2, seed=5, faults=rates)
    reads = 20000
    out, codes = compiled_reads(dev, np.full(reads, 10.0))
    io = dev.compiled_io()
    assert (codes == io.stall_code).sum() == dev.injected["stall"]
    drawn = reads  # nan, drop and spike draw on every read; stall is drawn last, so on every read too
    for kind, rate in rates.items():
        sd = math.sqrt(drawn * rate * (1 - rate))
        assert abs(dev.injected[kind] - drawn * rate) < 4.5 * sd, (kind, dev.injected[kind])
    rows = out[:, 0]
    clean = (codes == 0) & rows["valid"] & np.isfinite(rows["x"]) & (rows["z"] < KEYS[-1][3] + 0.25)
    for field, truth, std in (("x", KEYS[-1][1], 1e-3), ("y", KEYS[-1][2], 1e-3), ("z", KEYS[-1][3], 1e-3),
                              ("twist", KEYS[-1][4], 2e-2)):
        errors = rows[field][clean] - truth
        assert abs(errors.mean()) < 4 * std / math.sqrt(len(errors))
        assert errors.std() == pytest.approx(std, rel=0.03)


def test_the_interpreted_kernels_give_the_compiled_numbers():
    """Under NUMBA_DISABLE_JIT=1 the same kernels run as Python (the random streams through
    Python ints): the samples of a noisy, faulty script are the compiled ones to the bit, and
    compiled_io() says None."""
    script = textwrap.dedent(f"""
        import json
        from softproxy.devices.simulated import SimulatedDevice
        from softproxy.device import DeviceSample
        dev = SimulatedDevice({[KEYS, OTHER]!r}, noise_m=2e-4, noise_rad=3e-3, quantum_m=1e-5, seed=9,
                              faults={{"nan": 0.1, "drop": 0.1, "spike": 0.1}})
        samples = [DeviceSample(), DeviceSample()]
        out = []
        for k in range(150):
            dev.read(k * 4e-3, samples)
            out.append([repr((s.t, s.x, s.y, s.z, s.twist, s.valid)) for s in samples])
        dev.send(0, 30.0, 0.0, -40.0, 0.0, 0.0, 0.2)
        print(json.dumps([out, dev.injected, dev.last_force, dev.compiled_io() is None]))
    """)

    def run(disable_jit: str):
        env = dict(os.environ, NUMBA_DISABLE_JIT=disable_jit)
        done = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True, text=True, timeout=120,
                              cwd=os.path.dirname(os.path.dirname(__file__)))
        assert done.returncode == 0, done.stderr[-2000:]
        assert "Warning" not in done.stderr, done.stderr[-2000:]
        return json.loads(done.stdout)

    interpreted, injected, last_force, no_io = run("1")
    compiled, compiled_injected, compiled_force, compiled_no_io = run("0")
    assert no_io and not compiled_no_io
    assert interpreted == compiled and injected == compiled_injected and last_force == compiled_force


# --- the replay device ----------------------------------------------------------------------------

def write_v2(path, fingers=2, records=None, reads=None):
    """A version-2 recording (the format in softproxy/recording.py) of `records`: (read, error)
    pairs, each finger's sample made from the read number; an end record when `reads` is given."""
    if records is None:  # read 3 dropped by the recorder, read 5 a device failure, then 4 good reads
        records = [(0, 0), (1, 0), (2, 0), (4, 0), (5, 1), (6, 0), (7, 0), (8, 0), (9, 0)]
    size = 16 + 88 * fingers
    header = {"format": "softproxy-recording", "version": 2, "fingers": fingers, "record_bytes": size,
              "byte_order": "little"}
    body = bytearray()
    for read, error in records:
        body += struct.pack("<IIq", 1, error, read)
        for f in range(fingers):
            x = math.nan if read == 7 and f == 1 else 0.01 * read + f
            body += struct.pack("<9dq?7x", read * 1e-3, x, -0.002 * read, 0.05 + f, 1.0, 0.0, 0.0, 0.0,
                                0.1 * f, read * 10 + f, read != 8)
    if reads is not None:
        body += struct.pack("<IIqq", 2, 0, reads, reads - len(records)) + bytes(size - 24)
    path.write_bytes(json.dumps(header).encode() + b"\n" + bytes(body))
    return str(path)


def test_replay_cfunc_reads_are_the_python_reads_bit_for_bit(tmp_path):
    """A recording with a dropped read, a recorded device failure, a NaN and an invalid sample,
    held past its end: the cfunc gives the Python read's samples and messages, read for read."""
    path = write_v2(tmp_path / "gaps.rec")
    codes = assert_same_reads(ReplayDevice(path), ReplayDevice(path))
    io = ReplayDevice(path).compiled_io()
    assert [io.read_error(c) for c in codes[:7] if c] == [
        f"{path}: read 3 was not recorded (the recorder dropped it); zero force",
        "the recorded device failed on read 5"]
    assert io.stall_code == 0 and (codes[10:] == 0).all()  # held past the end


def test_replay_gaps_after_the_last_record_and_an_empty_recording(tmp_path):
    """Reads the end record counts beyond the last record are dropped reads; a recording with no
    records fails every read. Same messages from Python and from the cfunc."""
    path = write_v2(tmp_path / "tail.rec", records=[(0, 0), (1, 0)], reads=4)
    a, b = ReplayDevice(path), ReplayDevice(path)
    times = np.zeros(6)
    _, messages = python_reads(a, times)
    out, codes = compiled_reads(b, times)
    assert messages == ["", "", f"{path}: read 2 was not recorded (the recorder dropped it); zero force",
                        f"{path}: read 3 was not recorded (the recorder dropped it); zero force", "", ""]
    assert [b.compiled_io().read_error(c) if c else "" for c in codes] == messages
    assert out[4].tobytes() == out[5].tobytes() == out[1].tobytes() and a.reads == b.reads == 6
    empty = write_v2(tmp_path / "empty.rec", records=[])
    dev = ReplayDevice(empty)
    _, codes = compiled_reads(dev, np.zeros(2))
    with pytest.raises(DeviceError) as err:
        dev.read(0.0, [DeviceSample(), DeviceSample()])
    assert dev.compiled_io().read_error(codes[0]) == str(err.value) == f"{empty}: the recording holds no samples"
    assert dev.reads == 3


def test_replay_sends_and_close(tmp_path):
    """Sends render nothing (code 0) to a finger the replay has, and are refused for another; a
    closed replay fails its reads both ways with one message."""
    dev = ReplayDevice(write_v2(tmp_path / "r.rec"))
    io = dev.compiled_io()
    codes = np.ones(3, dtype=np.int64)
    run_sends(io.send, io.address, np.array([0, 1, 2]), np.full((3, 6), math.nan), codes)
    assert codes.tolist()[:2] == [0, 0] and codes[2] > 0
    with pytest.raises(IndexError, match="no such finger"):
        dev.send(-1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dev.send(1, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dev.close()
    rows = np.zeros(2, dtype=dk.SAMPLE)
    code = read_raw(io.read, io.address, 0.0, address(rows), 2)
    with pytest.raises(DeviceError) as err:
        dev.read(0.0, [DeviceSample(), DeviceSample()])
    assert io.read_error(code) == str(err.value) == "replay device is closed" and dev.reads == 0


def test_one_loop_kernel_serves_every_compiled_device(tmp_path):
    """The cfuncs of both devices have one numba type: a loop kernel compiled for one calls the
    other without compiling again."""
    compiled_reads(sim(), np.zeros(1))
    compiled_reads(ReplayDevice(write_v2(tmp_path / "r.rec")), np.zeros(1))
    assert len(run_reads.signatures) == 1


# --- the protocol's own pieces ---------------------------------------------------------------------

def test_error_codes_carry_their_argument():
    """kind | argument << KIND_BITS, the argument clamped so a code stays > 0."""
    assert dk.split_code(dk.error_code(9, 12345)) == (9, 12345)
    assert dk.split_code(dk.error_code(3, -7)) == (3, 0)
    assert dk.error_code(10, 2**63 - 1) > 0 and dk.split_code(dk.error_code(10, 2**63 - 1)) == (10, dk.MAX_ARGUMENT)


def test_stale_device_kernels_are_dropped(tmp_path):
    """A device module's cached kernels are deleted when device_kernel.py is not the file they
    were built from (the stamp differs), and kept when it is; other modules' are never touched."""
    def probe():
        return 0

    probe.__code__ = probe.__code__.replace(co_filename=str(tmp_path / "mydevice.py"))
    fake = types.SimpleNamespace(_cache=types.SimpleNamespace(cache_path=str(tmp_path)), py_func=probe)
    mine = [tmp_path / "mydevice._read-10.py311.nbi", tmp_path / "mydevice._read-10.py311.1.nbc"]
    other = tmp_path / "otherdevice._read-10.py311.nbi"
    for path in (*mine, other):
        path.write_bytes(b"kernel")
    assert dk.drop_stale_kernels(fake)  # no stamp yet: built from an unknown version
    assert not any(p.exists() for p in mine) and other.exists()
    for path in mine:
        path.write_bytes(b"kernel")
    assert not dk.drop_stale_kernels(fake)  # same source: kept
    assert all(p.exists() for p in mine)
    (tmp_path / "mydevice.device_kernel.stamp").write_text("an older device_kernel.py")
    assert dk.drop_stale_kernels(fake) and not any(p.exists() for p in mine)
