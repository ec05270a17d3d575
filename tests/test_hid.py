"""HID devices: profile validation, report parsing fuzzed with random / truncated / oversized
bytes, recorded reports, and HidDevice over a fake `hid.device` transport (no hardware here)."""

import io
import json
import math
import random
import struct
import time
import tomllib
from collections import deque

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from conftest import Clock, box_loop, oh_state

from softproxy.devices.hid import HidDevice, devices_main, list_devices
from softproxy.devices.hid_profile import (
    PROFILE_DIR,
    ProfileError,
    ReportError,
    build_output,
    load_profile,
    parse_input,
    parse_output,
    parse_profile,
    zero_output,
)
from softproxy.device import Device, DeviceError, DeviceSample

SHIPPED = ["spacemouse", "open_haptic", "open_haptic_rawhid"]

# A test-only profile exercising what the shipped ones do not: float32, big-endian, uint8
# sequence, int8, and float32 output fields.
FLOAT_BE = {
    "name": "float_be",
    "max_force": 3.0,
    "max_torque": 0.2,
    "finger_axis": "-y",
    "match": [{"vendor_id": 0x1234, "product_id": 0x5678}],
    "input": {"reporting": "periodic", "stale_ms": 10, "max_bytes": 32, "report": [
        {"id": 5, "size": 18, "fields": {
            "sequence": {"offset": 0, "type": "uint8"},
            "x": {"offset": 1, "type": "float32", "endian": "big", "rate_scale": 1.0},
            "y": {"offset": 5, "type": "float32", "endian": "big", "rate_scale": 1.0},
            "z": {"offset": 9, "type": "float32", "endian": "big", "rate_scale": 1.0},
            "tw": {"offset": 13, "type": "float32", "endian": "big", "scale": 2.0, "rate_scale": 2.0},
            "trim": {"offset": 17, "type": "int8", "scale": 1e-3},
        }},
        {"id": 6, "size": 2, "fields": {"buttons": {"offset": 0, "type": "uint16", "endian": "big"}}},
    ]},
    "axes": {"x": "x", "y": "-z", "z": "y", "twist": "tw"},
    "output": {"id": 7, "size": 16, "fields": {
        "fx": {"offset": 0, "type": "float32", "endian": "big", "source": "fx", "scale": 1.0, "min": -2.5, "max": 2.5},
        "fy": {"offset": 4, "type": "float32", "endian": "big", "source": "-fz", "scale": 1.0},
        "fz": {"offset": 8, "type": "int16", "endian": "big", "source": "fy", "scale": 100.0},
        "twist": {"offset": 10, "type": "int32", "source": "twist", "scale": 1e6, "min": -100000, "max": 100000},
        "seq": {"offset": 14, "type": "uint8", "source": "sequence"},
        "on": {"offset": 15, "type": "uint8", "source": "enable"},
    }},
}
ALL = SHIPPED + ["float_be"]


def profile(name):
    return parse_profile(FLOAT_BE, "tests/float_be.toml") if name == "float_be" else load_profile(name)


PROFILES = {name: profile(name) for name in ALL}
FUZZ_COUNTS: dict[str, int] = {}


def _count(key, n):
    FUZZ_COUNTS[key] = FUZZ_COUNTS.get(key, 0) + n


def check_parse(p, data, key):
    """Parse in every mode the profile has: ReportError or None or finite values, nothing else."""
    _count(key, 1)
    for mode in p.modes:
        try:
            rep = parse_input(p, data, mode)
        except ReportError:
            continue
        if rep is None:
            continue
        for name, v in rep.values.items():
            assert isinstance(v, (int, float)) and math.isfinite(v), (name, v, data)
        assert rep.size <= p.max_bytes


class FakeHid:
    """The `hid.device` subset HidDevice uses, fed with scripted reports."""

    def __init__(self, *reports):
        self.pending = deque(bytes(r) for r in reports)
        self.writes = []
        self.closed = False
        self.nonblocking = None
        self.read_error = None
        self.write_result = None
        self.read_sizes = set()

    def feed(self, *reports):
        self.pending.extend(bytes(r) for r in reports)

    def set_nonblocking(self, v):
        self.nonblocking = v
        return 0

    def read(self, max_length, timeout_ms=0):
        if self.closed:
            raise ValueError("not open")
        if self.read_error is not None:
            raise self.read_error
        self.read_sizes.add(max_length)
        if not self.pending:
            return []
        return list(self.pending.popleft()[:max_length])  # hidapi truncates to the buffer

    def write(self, buff):
        if self.closed:
            raise ValueError("not open")
        data = bytes(buff)
        self.writes.append(data)
        return len(data) if self.write_result is None else self.write_result

    def close(self):
        self.closed = True


def make(name="open_haptic", *reports, **kw):
    t = FakeHid(*reports)
    clock = kw.pop("clock", None) or Clock()
    return HidDevice(name, t, clock=clock, **kw), t, clock


# ---------------------------------------------------------------------------------------------
# fuzzing the parsers


def report_strategy(p):
    """Random reports biased toward the profile's ids and sizes: plain noise, right id with a
    payload around each layout's size (truncated / exact / padded), and oversized ones."""
    ids = sorted(p.reports)
    sizes = sorted({layout.size for layouts in p.reports.values() for layout in layouts})
    prefix = st.sampled_from(ids).map(lambda i: bytes([i]) if p.numbered else b"")
    near = st.tuples(prefix, st.sampled_from(sizes), st.integers(-3, 3)).flatmap(
        lambda a: st.binary(min_size=max(0, a[1] + a[2]), max_size=max(0, a[1] + a[2])).map(lambda b: a[0] + b))
    oversized = st.binary(min_size=p.max_bytes + 1, max_size=p.max_bytes + 40)
    return st.one_of(st.binary(max_size=p.max_bytes + 8), near, near, oversized)


def bulk_report(p, rng):
    """One more random report from a seeded Random: cheap volume on top of the drawn ones."""
    kind = rng.random()
    if kind < 0.25:
        return rng.randbytes(rng.randint(0, p.max_bytes + 8))
    rid = rng.choice(sorted(p.reports))
    head = bytes([rid]) if p.numbered else b""
    if kind < 0.35:
        return head + rng.randbytes(rng.randint(p.max_bytes, p.max_bytes + 40))  # oversized
    size = rng.choice(p.reports[rid]).size + rng.randint(-3, 3)
    return head + rng.randbytes(max(0, size))


@pytest.mark.parametrize("name", ALL)
@settings(max_examples=100, deadline=None, suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
@given(data=st.data(), seed=st.integers(0, 2**64 - 1))
def test_fuzz_random_reports_never_raise_or_nan(name, data, seed):
    """Random, truncated and oversized reports: only ReportError, never NaN/Inf; every prefix too."""
    p = PROFILES[name]
    reports = data.draw(st.lists(report_strategy(p), min_size=1, max_size=20))
    for r in reports:
        check_parse(p, r, "random")
        for k in range(len(r)):  # every truncation of it
            check_parse(p, r[:k], "truncated")
        check_parse(p, r + bytes(p.max_bytes + 1 - len(r)) if len(r) <= p.max_bytes else r, "oversized")
        check_parse(p, list(r), "as-list")  # hid.device.read returns a list of ints
    rng = random.Random(seed)  # a seeded generator: shown in a failing example, replayable
    for _ in range(150):
        check_parse(p, bulk_report(p, rng), "random")


def _special_floats():
    return st.sampled_from([math.nan, -math.nan, math.inf, -math.inf, 3.4e38, -3.4e38, 1e-45, 0.0, -0.0])


@settings(max_examples=300, deadline=None)
@given(st.lists(st.one_of(_special_floats(), st.floats(width=32)), min_size=4, max_size=4), st.integers(0, 255),
       st.integers(-128, 127))
def test_fuzz_float32_nan_inf_is_report_error(vals, seq, trim):
    """A float32 NaN/Inf anywhere in a report is a ReportError, and a finite one parses finite."""
    p = PROFILES["float_be"]
    data = bytes([5, seq]) + struct.pack(">ffff", *vals) + struct.pack("b", trim)
    _count("float32", 1)
    for mode in p.modes:
        if all(math.isfinite(v) for v in vals):
            rep = parse_input(p, data, mode)
            assert all(math.isfinite(v) for v in rep.values.values())
            assert rep.values["sequence"] == seq
        else:
            with pytest.raises(ReportError, match="non-finite"):
                parse_input(p, data, mode)


def test_parse_edges():
    p = PROFILES["open_haptic"]
    with pytest.raises(ReportError, match="empty"):
        parse_input(p, b"")
    with pytest.raises(ReportError, match="truncated report id 1: 19 payload bytes"):
        parse_input(p, oh_state(1)[:-1])
    with pytest.raises(ReportError, match="oversized"):
        parse_input(p, oh_state(1) + bytes(64))
    with pytest.raises(ReportError, match="not a byte string"):
        parse_input(p, [1, 2, 300])
    with pytest.raises(ReportError, match="not a byte string"):
        parse_input(p, ["a"])
    assert parse_input(p, bytes([9]) + bytes(20)) is None  # an id the profile does not use
    assert parse_input(p, oh_state(3) + bytes(5)).values["sequence"] == 3  # padded: ignored tail


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(["open_haptic", "open_haptic_rawhid", "float_be"]), st.integers(0, 2**20),
       st.lists(st.one_of(st.floats(allow_nan=True, allow_infinity=True), st.floats(-50, 50)), min_size=6, max_size=6),
       st.booleans())
def test_fuzz_build_output_is_finite_and_clamped(name, seq, wrench, enable):
    """Any wrench, NaN and Inf included: the report decodes to a finite wrench within the limits."""
    p = PROFILES[name]
    report = build_output(p, seq, *wrench, enable=enable)
    _count("output", 1)
    assert len(report) == 1 + p.output.size and report[0] == p.output.id
    back = parse_output(p, report)
    finite = all(math.isfinite(v) for v in wrench)
    for f in p.output.fields:
        v = back[f.name]
        assert math.isfinite(v)
        if f.source == "enable":
            assert v == (1 if finite and enable else 0)
        elif f.source != "sequence":
            assert f.lo <= v * f.scale * f.sign <= f.hi or math.isclose(v * f.scale * f.sign, f.lo) or \
                math.isclose(v * f.scale * f.sign, f.hi)
            limit = p.max_force if f.source[-2:] in ("fx", "fy", "fz") else p.max_torque
            assert abs(v) <= limit  # counts round toward zero: never over, not even by one
            if not finite:
                assert v == 0.0


# ---------------------------------------------------------------------------------------------
# recorded reports


def test_spacemouse_recorded_reports():
    p = PROFILES["spacemouse"]
    # SpaceNavigator, cap pushed right to full scale (350) and pulled up (raw z = -350)
    r = parse_input(p, bytes.fromhex("01 5e01 0000 a2fe"))
    assert r.report_id == 1 and r.size == 6
    assert r.values == pytest.approx({"tx": 0.035, "ty": 0.0, "tz": -0.035})
    # rotation report: raw rz = -100 (cap turned counter-clockwise seen from above)
    assert parse_input(p, bytes.fromhex("02 0000 0000 9cff")).values == pytest.approx({"rx": 0, "ry": 0, "rz": -0.4})
    # SpaceMouse Wireless: one 13-byte report; rx = 3 is inside the 5-count deadband
    r = parse_input(p, bytes.fromhex("01 88ff 2d00 c800 0300 f9ff 2100"))
    assert r.size == 12
    assert r.values == pytest.approx({"tx": -0.012, "ty": 0.0045, "tz": 0.02, "rx": 0.0, "ry": -0.028, "rz": 0.132})
    # rate mode reads the same counts as velocities
    assert parse_input(p, bytes.fromhex("01 6400 0000 0000"), "rate").values["tx"] == pytest.approx(0.03)
    # buttons: SpaceNavigator 3-byte report, and a Windows-padded one
    assert parse_input(p, bytes.fromhex("03 0300")).values == {"buttons": 3}
    assert parse_input(p, bytes.fromhex("03 0100 0000 0000")).values == {"buttons": 1}
    assert parse_input(p, bytes.fromhex("17 64")) is None  # battery report: not ours
    with pytest.raises(ReportError, match="truncated"):
        parse_input(p, bytes.fromhex("01 5e01 00"))


def test_spacemouse_axis_mapping_to_sample():
    """Cap right +x, pushed away from the user +y, pulled up +z, turned counter-clockwise +twist."""
    dev, t, _ = make("spacemouse", bytes.fromhex("01 6400 38ff 9cff"), bytes.fromhex("02 0000 0000 9cff"))
    s = [DeviceSample()]
    dev.read(0.0, s)
    assert (s[0].x, s[0].y, s[0].z, s[0].twist) == pytest.approx((0.01, 0.02, 0.01, 0.4))
    assert s[0].valid and s[0].buttons == 0


def test_open_haptic_recorded_report():
    p = PROFILES["open_haptic"]
    data = bytes.fromhex("01 3412 05 02 39300000 7be5ffff a0860100 1408e8ff")
    r = parse_input(p, data)
    assert r.values == pytest.approx({"sequence": 0x1234, "status": 5, "buttons": 2, "x": 0.012345,
                                      "y": -0.006789, "z": 0.1, "twist": -1.570796})
    raw = PROFILES["open_haptic_rawhid"]  # same payload, unnumbered, padded to 64 bytes
    assert parse_input(raw, data[1:] + bytes(44)).values == r.values


def test_float_be_recorded_report():
    p = PROFILES["float_be"]
    r = parse_input(p, bytes.fromhex("05 07 3c4ccccd bf000000 3a83126f 3e800000 fe"))
    assert r.values == pytest.approx({"sequence": 7, "x": 0.0125, "y": -0.5, "z": 0.001, "tw": 0.5, "trim": -0.002})
    assert parse_input(p, bytes.fromhex("06 0102")).values == {"buttons": 0x0102}


# ---------------------------------------------------------------------------------------------
# output reports


def test_output_report_for_known_force():
    dev, t, _ = make()
    dev.send(0, 1.0, -2.0, 0.5, 0.0, 0.0, 0.01)
    # id 2 | seq 1 | enable 1 | 0 | fx 1000 mN | fy -2000 | fz 500 | torque 0.01 N·m = 1000 counts
    assert t.writes == [bytes.fromhex("02 0100 01 00 e803 30f8 f401 e803")]
    dev.send(0, 100.0, 0.0, 0.0, 0.0, 0.0, -1.0)  # clamped to max_force 5 N and max_torque 0.05 N·m
    assert t.writes[-1] == bytes.fromhex("02 0200 01 00 8813 0000 0000 78ec")
    # torque about the finger axis only: tx, ty do not reach a twist motor
    dev.send(0, 0.0, 0.0, 0.0, 0.03, 0.0, 0.0)
    assert t.writes[-1][-2:] == bytes(2)


def test_nan_request_sends_zero_force_report():
    dev, t, _ = make()
    dev.send(0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)
    dev.send(0, math.nan, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert t.writes[-1] == bytes.fromhex("02 0200 00 00 0000 0000 0000 0000")
    dev.send(0, 0.0, 0.0, 0.0, 0.0, math.inf, 0.0)
    assert t.writes[-1] == bytes.fromhex("02 0300 00 00 0000 0000 0000 0000")
    assert dev.nan_sends == 2 and dev.sends == 3
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)  # and back
    assert t.writes[-1] == bytes.fromhex("02 0400 01 00 0000 0000 e803 0000")
    dev.send(0, 1e308, 1e308, 0.0, 0.0, 0.0, 0.0)  # huge but finite: clamped, direction kept
    # 5 N at 45 degrees: 3535.53 mN each, sent as 3535 (rounded toward zero: 3536 each would be 5.0006 N)
    assert t.writes[-1] == bytes.fromhex("02 0500 01 00 cf0d cf0d 0000 0000") and dev.nan_sends == 2


def test_close_sends_zero_force_first():
    dev, t, _ = make()
    dev.send(0, 0.0, 0.0, 3.0, 0.0, 0.0, 0.02)
    dev.close()
    assert t.writes[-1] == bytes.fromhex("02 0200 00 00 0000 0000 0000 0000") == zero_output(dev.profile, 2)
    assert t.closed
    dev.close()  # idempotent
    assert len(t.writes) == 2
    with pytest.raises(DeviceError, match="closed"):
        dev.read(0.0, [DeviceSample()])
    with pytest.raises(DeviceError, match="closed"):
        dev.send(0, 0, 0, 0, 0, 0, 0)


def test_rawhid_output_is_unnumbered_64_bytes():
    dev, t, _ = make("open_haptic_rawhid")
    dev.send(0, 0.0, 0.0, -1.5, 0.0, 0.0, 0.0)
    w = t.writes[-1]
    assert len(w) == 65 and w[0] == 0  # hidapi wants the 0 report id byte first
    assert w[1:13] == bytes.fromhex("0100 01 00 0000 0000 24fa 0000") and w[13:] == bytes(52)


def test_lower_force_limit_from_config():
    dev = HidDevice.from_config({"type": "hid", "profile": "open_haptic", "max_force_N": 2.0,
                                 "max_torque_Nm": 0.01}, source="scene.toml", transport=FakeHid())
    assert (dev.max_force, dev.max_torque) == (2.0, 0.01)
    dev.send(0, 0.0, 10.0, 0.0, 0.0, 0.0, 1.0)
    back = parse_output(dev.profile, dev.last_output)
    assert back["fy"] == pytest.approx(2.0) and back["torque"] == pytest.approx(0.01)


def test_input_only_device_renders_nothing():
    dev, t, _ = make("spacemouse")
    assert dev.max_force == 0.0 and dev.max_torque == 0.0
    dev.send(0, 1.0, 2.0, 3.0, 0.0, 0.0, 0.0)
    dev.send(0, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0)
    dev.close()
    assert t.writes == [] and dev.nan_sends == 1 and dev.sends == 2 and t.closed
    with pytest.raises(ValueError, match="no output report"):
        build_output(dev.profile, 0, 0, 0, 0, 0, 0, 0)


# ---------------------------------------------------------------------------------------------
# the device over the fake transport


def test_is_a_device_and_reads_nonblocking():
    dev, t, _ = make()
    assert isinstance(dev, Device)
    assert dev.fingers == 1 and t.nonblocking == 1
    dev.read(0.0, [DeviceSample()])
    assert t.read_sizes == {65}  # max_bytes + 1: an oversized report shows as such


def test_normal_stream():
    dev, t, clock = make()
    s = [DeviceSample()]
    dev.read(0.0, s)
    assert not s[0].valid  # a periodic device before its first report
    for k in range(1, 200):
        clock.now += 0.001
        t.feed(oh_state(k, x_um=10 * k, y_um=-k, z_um=50_000, twist_urad=1000 * k, buttons=k & 3))
        dev.read(k * 0.001, s)
        assert s[0].valid
        assert (s[0].x, s[0].y, s[0].z, s[0].twist) == pytest.approx((1e-5 * k, -1e-6 * k, 0.05, 1e-3 * k))
        assert s[0].buttons == k & 3 and s[0].t == k * 0.001
    assert dev.invalid_samples == 1 and dev.reports == 199 and dev.sequence_errors == 0


def test_drains_backlog_and_keeps_latest():
    dev, t, clock = make()
    t.feed(*(oh_state(k, x_um=k) for k in range(1, 11)))
    s = [DeviceSample()]
    dev.read(0.0, s)
    assert s[0].valid and s[0].x == pytest.approx(10e-6) and dev.reports == 10
    dev2, t2, _ = make(max_reports_per_read=4)
    t2.feed(*(oh_state(k, x_um=k) for k in range(1, 11)))
    dev2.read(0.0, s)
    assert s[0].x == pytest.approx(4e-6) and dev2.backlogs == 1 and len(t2.pending) == 6


def test_disconnect_mid_run_raises_clean_device_error():
    dev, t, clock = make(label="open_haptic at /dev/hidraw7")
    s = [DeviceSample()]
    for k in range(1, 6):
        t.feed(oh_state(k))
        dev.read(k * 1e-3, s)
        dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    t.read_error = OSError("read error")
    with pytest.raises(DeviceError) as exc:
        dev.read(0.006, s)
    msg = str(exc.value)
    assert "open_haptic at /dev/hidraw7" in msg and "disappeared" in msg and "read error" in msg
    assert "zero force" in msg
    with pytest.raises(DeviceError, match="disappeared"):  # failed: no force written
        dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert parse_output(dev.profile, t.writes[-1])["enable"] == 1 and len(t.writes) == 5
    t.read_error = None  # the transport is back: zero force first, then a fresh sample
    dev.read(0.007, s)
    assert t.writes[-1] == zero_output(dev.profile, 6) and not s[0].valid  # nothing fresh yet
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert t.writes[-1] == zero_output(dev.profile, 7)  # no force before a valid sample
    t.feed(oh_state(6))
    dev.read(0.008, s)
    assert s[0].valid and dev.recoveries == 1 and dev.failures == 1
    dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    assert parse_output(dev.profile, t.writes[-1])["fz"] == pytest.approx(1.0)
    dev.close()
    assert t.writes[-1] == zero_output(dev.profile, 9) and t.closed


def test_write_failure_is_device_error():
    dev, t, _ = make()
    t.write_result = -1
    with pytest.raises(DeviceError, match="sending a force"):
        dev.send(0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0)
    dev2, t2, _ = make()
    t2.close()  # cython-hidapi raises ValueError('not open') on a closed handle
    with pytest.raises(DeviceError, match="not open"):
        dev2.read(0.0, [DeviceSample()])


def test_fault_and_calibration_status():
    dev, t, clock = make()
    s = [DeviceSample()]
    t.feed(oh_state(1, status=0x01, x_um=100))
    dev.read(0.000, s)
    assert s[0].valid
    t.feed(oh_state(2, status=0x03, x_um=999_999))  # FAULT: its numbers are not used
    dev.read(0.001, s)
    assert not s[0].valid and s[0].x == pytest.approx(100e-6)
    dev.read(0.002, s)  # no new report: still faulted
    assert not s[0].valid
    t.feed(oh_state(3, status=0x00, x_um=200))  # not calibrated
    dev.read(0.003, s)
    assert not s[0].valid
    t.feed(oh_state(4, status=0x05, x_um=300))  # calibrated + MOTORS_ON (info bit)
    dev.read(0.004, s)
    assert s[0].valid and s[0].x == pytest.approx(300e-6)
    assert dev.status_faults == 2 and dev.invalid_samples == 3 and dev.status == 0x05


def test_sequence_gaps_duplicates_out_of_order():
    dev, t, clock = make()
    s = [DeviceSample()]
    valid = []
    for seq in (65533, 65534, 65535, 0, 1, 4, 5, 5, 6, 3, 4, 5):
        t.feed(oh_state(seq))
        dev.read(0.0, s)
        valid.append(s[0].valid)
    #            wraps to 0 fine ^  gap^     dup^    back^
    assert valid == [True, True, True, True, True, False, True, False, True, False, True, True]
    assert (dev.dropped, dev.duplicates, dev.out_of_order, dev.sequence_errors) == (2, 1, 1, 3)
    assert dev.invalid_samples == 3


def test_stale_after_stale_ms_then_recovers():
    dev, t, clock = make()
    s = [DeviceSample()]
    t.feed(oh_state(1, z_um=1234))
    dev.read(0.0, s)
    assert s[0].valid
    clock.now += 0.019  # 19 ms without a report: fine (stale_ms = 20)
    dev.read(0.019, s)
    assert s[0].valid
    clock.now += 0.002
    dev.read(0.021, s)
    assert not s[0].valid and s[0].z == pytest.approx(1234e-6)  # last values kept, marked invalid
    assert dev.stale_samples == 1
    t.feed(oh_state(2, z_um=99))
    dev.read(0.022, s)
    assert s[0].valid and s[0].z == pytest.approx(99e-6)
    dev2, t2, clock2 = make(stale_ms=0)  # 0 = never stale
    t2.feed(oh_state(1))
    dev2.read(0.0, s)
    clock2.now += 10.0
    dev2.read(10.0, s)
    assert s[0].valid


def test_garbage_and_foreign_reports():
    dev, t, clock = make()
    s = [DeviceSample()]
    t.feed(oh_state(1, x_um=5))
    dev.read(0.0, s)
    t.feed(bytes([1, 2, 3]), oh_state(2, x_um=6))  # a truncated report this tick: invalid, counted
    dev.read(0.001, s)
    assert not s[0].valid and dev.bad_reports == 1 and "truncated" in dev.last_report_error
    assert s[0].x == pytest.approx(6e-6)  # the good report still counts
    t.feed(bytes([0x42, 0, 0]), oh_state(3, x_um=7))  # an id this profile does not use: ignored
    dev.read(0.002, s)
    assert s[0].valid and dev.ignored_reports == 1


def test_spacemouse_on_change_is_valid_at_rest_and_merges_reports():
    dev, t, clock = make("spacemouse")
    s = [DeviceSample()]
    dev.read(0.0, s)
    assert s[0].valid and (s[0].x, s[0].y, s[0].z, s[0].twist) == (0.0, 0.0, 0.0, 0.0)
    t.feed(bytes.fromhex("01 6400 0000 0000"))
    dev.read(0.001, s)
    t.feed(bytes.fromhex("02 0000 0000 38ff"), bytes.fromhex("03 0200"))
    dev.read(0.002, s)
    assert (s[0].x, s[0].twist, s[0].buttons) == pytest.approx((0.01, 0.8, 2))
    clock.now += 60.0  # silent for a minute: at rest, never stale
    dev.read(60.0, s)
    assert s[0].valid and dev.stale_samples == 0


def test_spacemouse_position_mode_workspace_scale_and_offset():
    dev, t, _ = make("spacemouse", workspace_scale=2.0, workspace_offset=(0.0, 0.1, 0.05))
    t.feed(bytes.fromhex("01 6400 9cff 6400 0000 0000 6400"))
    s = [DeviceSample()]
    dev.read(0.0, s)
    assert (s[0].x, s[0].y, s[0].z, s[0].twist) == pytest.approx((0.02, 0.12, 0.03, -0.4))


def test_spacemouse_rate_mode_integrates_and_clamps_to_box():
    dev, t, clock = make("spacemouse", mode="rate", workspace_offset=(0.0, 0.0, 0.05),
                         workspace_half_m=(0.05, 0.05, 0.02), twist_limit_rad=1.0)
    s = [DeviceSample()]
    dev.read(0.0, s)
    assert (s[0].x, s[0].y, s[0].z) == pytest.approx((0.0, 0.0, 0.05))
    # 100 counts right = 0.03 m/s, 100 counts down = -0.03 m/s in z, twist 50 counts = -0.2 rad/s
    t.feed(bytes.fromhex("01 6400 0000 6400 0000 0000 3200"))
    for k in range(1, 1001):
        dev.read(k * 1e-3, s)  # the device sends nothing more: on_change, velocity held
    assert s[0].x == pytest.approx(0.03) and s[0].y == 0.0
    assert s[0].z == pytest.approx(0.03)  # 0.05 - 0.03 clamped at 0.05 - 0.02
    assert s[0].twist == pytest.approx(-0.2)
    for k in range(1001, 3001):
        dev.read(k * 1e-3, s)
    assert s[0].x == pytest.approx(0.05) and s[0].twist == pytest.approx(-0.6)
    t.feed(bytes.fromhex("01 0000 0000 0000 0000 0000 0000"))  # cap released: stays put
    dev.read(3.001, s)
    x = s[0].x
    dev.read(3.5, s)
    assert s[0].x == x and s[0].valid
    dev.read(100.0, s)  # a long stall integrates at most MAX_DT
    assert s[0].x == x


def test_rate_mode_needs_rate_scales():
    with pytest.raises(ValueError, match="mode must be one of \\['position'\\]"):
        make("open_haptic", mode="rate")


def test_device_with_float_profile_marks_nan_invalid():
    p = PROFILES["float_be"]
    dev, t, clock = make(p)
    s = [DeviceSample()]
    t.feed(bytes([5, 1]) + struct.pack(">ffff", 0.01, 0.02, 0.03, 0.1) + b"\x00")
    dev.read(0.0, s)
    assert s[0].valid and (s[0].x, s[0].y, s[0].z, s[0].twist) == pytest.approx((0.01, -0.03, 0.02, 0.2))
    t.feed(bytes([5, 2]) + struct.pack(">ffff", math.nan, 0.0, 0.0, 0.0) + b"\x00")
    dev.read(0.001, s)
    assert not s[0].valid and s[0].is_finite() and dev.bad_reports == 1
    dev.send(0, 0.0, 0.0, 0.0, 0.0, -0.1, 0.0)  # finger axis -y: torque -0.1 about y is +0.1 twist
    assert parse_output(p, t.writes[-1])["twist"] == pytest.approx(0.1)


WILD = [math.nan, math.inf, -math.inf, 1e308, -1e308, 5e-324, 0.0, 1.0, -3.0, 40.0, 0.04, -0.2]


@settings(max_examples=120, deadline=None)
@given(st.sampled_from(ALL), st.integers(0, 1), st.integers(0, 2**64 - 1), st.integers(0, 60), st.booleans())
def test_fuzz_device_stream(name, mode_index, seed, n_ticks, unplug):
    """A device fed random streams (garbage, good, faulted, gaps, silence, backlogs) never raises
    but DeviceError, never yields a non-finite sample, and never writes a NaN or unclamped force."""
    p = PROFILES[name]
    dev, t, clock = make(p, mode=p.modes[mode_index % len(p.modes)])
    rng = random.Random(seed)
    s = [DeviceSample()]
    tt = 0.0
    for _ in range(n_ticks):
        batch = []
        for _ in range(rng.choice([0, 0, 1, 1, 1, 2, 5, 40])):
            if name.startswith("open_haptic") and rng.random() < 0.5:  # plausible state, wild numbers
                r = oh_state(rng.randint(0, 70000), rng.choice([0, 1, 1, 1, 3, 5, 0xFF]),
                             *(rng.randint(-2**31, 2**31 - 1) for _ in range(4)))
                batch.append(r if name == "open_haptic" else r[1:] + bytes(44))
            else:
                batch.append(bulk_report(p, rng))
        t.feed(*batch)
        _count("device", len(batch))
        dt = rng.choice([0.0, 0.001, 0.001, 0.004, 0.03, 1.0])
        clock.now += dt
        tt += dt
        dev.read(tt, s)
        assert s[0].is_finite()
        wrench = [rng.choice(WILD) if rng.random() < 0.3 else rng.uniform(-20, 20) for _ in range(6)]
        dev.send(0, *wrench)
    for report in t.writes:
        back = parse_output(p, report)
        assert all(math.isfinite(v) for v in back.values())
        for f in p.output.fields:
            if f.source[-2:] in ("fx", "fy", "fz"):
                assert abs(back[f.name]) <= dev.max_force
            elif f.source not in ("sequence", "enable"):
                assert abs(back[f.name]) <= dev.max_torque
    if unplug:
        t.read_error = OSError("gone")
        with pytest.raises(DeviceError):
            dev.read(tt, s)
    dev.close()
    if p.output is not None and not unplug:
        assert parse_output(p, t.writes[-1])["on" if name == "float_be" else "enable"] == 0


# ---------------------------------------------------------------------------------------------
# profiles: shipped ones load, broken ones name the file and the field


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_profiles_load(name):
    p = load_profile(name)
    assert p.name == name and p.matches and p.source.endswith(f"{name}.toml")
    assert (p.output is None) == (p.max_force == 0.0 and p.max_torque == 0.0)


def _doc(name="open_haptic"):
    with open(PROFILE_DIR / f"{name}.toml", "rb") as fh:
        return tomllib.load(fh)


def _set(path, value):
    def mutate(doc):
        *head, last = path
        node = doc
        for key in head:
            node = node[key]
        if value is _DEL:
            del node[last]
        else:
            node[last] = value
    return mutate


_DEL = object()

BROKEN = [
    (_set(["input", "report", 0, "fields", "x", "type"], "int64"), "input.report[0].fields.x.type", "one of"),
    (_set(["input", "report", 0, "fields", "x", "offset"], 18), "input.report[0].fields.x.offset", "ends within"),
    (_set(["input", "report", 0, "fields", "x", "scale"], math.nan), "input.report[0].fields.x.scale", "finite"),
    (_set(["input", "report", 0, "fields", "x", "offset"], _DEL), "input.report[0].fields.x.offset", "required"),
    (_set(["input", "report", 0, "fields", "sequence", "type"], "int16"), "input.report[0].fields.sequence.type",
     "unsigned"),
    (_set(["input", "report", 0, "id"], 256), "input.report[0].id", "0..255"),
    (_set(["input", "report", 0, "size"], 70), "input.report[0].size", "max_bytes"),
    (_set(["input", "reporting"], "sometimes"), "input.reporting", "one of"),
    (_set(["input", "stale_ms"], -1), "input.stale_ms", ">= 0"),
    (_set(["input", "report"], []), "input.report", "non-empty list"),
    (_set(["input", "colour"], "red"), "input has unknown field(s) ['colour']", ""),
    (_set(["axes", "x"], "xx"), "axes.x", "scaled input field"),
    (_set(["axes", "y"], "sequence"), "axes.y", "scaled input field"),
    (_set(["axes", "z"], _DEL), "axes.z is required", ""),
    (_set(["mode"], "rate"), "mode", "rate_scale"),
    (_set(["mode"], "velocity"), "mode", "one of"),
    (_set(["max_force"], -1.0), "max_force", ">= 0"),
    (_set(["finger_axis"], "w"), "finger_axis", "\"x\", \"y\" or \"z\""),
    (_set(["match", 0, "vendor_id"], 0x10000), "match[0].vendor_id", "0..0xFFFF"),
    (_set(["status", "require_clear"], 0x01), "status.require_clear", "disjoint"),
    (_set(["output", "fields", "fx", "scale"], _DEL), "output.fields.fx.scale is required", ""),
    (_set(["output", "fields", "fx", "source"], "fw"), "output.fields.fx.source", "one of"),
    (_set(["output", "fields", "fx", "min"], 10), "output.fields.fx", "min must be <= 0"),
    (_set(["output", "fields", "fx", "max"], 40000), "output.fields.fx.max", "int16 range"),
    (_set(["output", "fields", "fy", "offset"], 5), "output.fields.fy overlaps output.fields.fx", ""),
    (_set(["output"], _DEL), "max_force", "no force"),
    (_set(["wheels"], 4), "unknown field(s) ['wheels']", ""),
]


@pytest.mark.parametrize("mutate,field,expected", BROKEN, ids=[b[1] for b in BROKEN])
def test_profile_errors_name_file_and_field(mutate, field, expected, tmp_path):
    doc = _doc()
    mutate(doc)
    source = str(tmp_path / "my_device.toml")
    with pytest.raises(ProfileError) as exc:
        parse_profile(doc, source)
    msg = str(exc.value)
    assert msg.startswith(f"{source}: "), msg
    assert field in msg and expected in msg, msg


def test_profile_file_errors(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("name = \n")
    with pytest.raises(ProfileError, match=r"bad\.toml: not valid TOML"):
        load_profile(str(bad))
    text = (PROFILE_DIR / "spacemouse.toml").read_text().replace('deadband = 5 }', 'deadband = -5 }', 1)
    broken = tmp_path / "mouse.toml"
    broken.write_text(text)
    with pytest.raises(ProfileError, match=r"mouse\.toml: input\.report\[0\]\.fields\.tx\.deadband must be a finite"):
        load_profile(str(broken))
    with pytest.raises(ProfileError, match="no HID profile named 'nope'; have: .*spacemouse"):
        load_profile("nope")
    with pytest.raises(ProfileError, match="profile file not found"):
        load_profile(str(tmp_path / "missing.toml"))


def test_user_profile_dir(tmp_path, monkeypatch):
    text = (PROFILE_DIR / "open_haptic.toml").read_text().replace('name = "open_haptic"', 'name = "my_arm"')
    text = text.replace("product_id = 0x0001", "product_id = 0x4242")
    (tmp_path / "my_arm.toml").write_text(text)
    monkeypatch.setenv("SOFTPROXY_HID_PROFILES", str(tmp_path))
    p = load_profile("my_arm")
    assert p.name == "my_arm" and p.ids() == ["1209:4242"]
    rows = list_devices(lambda: [{"vendor_id": 0x1209, "product_id": 0x4242, "path": b"/dev/hidraw9"}])
    assert rows[0]["profile"] == "my_arm"


# ---------------------------------------------------------------------------------------------
# listing and configuration

FAKE_ENUM = [
    {"path": b"/dev/hidraw0", "vendor_id": 0x046D, "product_id": 0xC626, "serial_number": "",
     "release_number": 0x0437, "manufacturer_string": "3Dconnexion", "product_string": "SpaceNavigator",
     "usage_page": 1, "usage": 8, "interface_number": 0},
    {"path": b"/dev/hidraw1", "vendor_id": 0x046D, "product_id": 0xC52B, "serial_number": "",
     "release_number": 0x1211, "manufacturer_string": "Logitech", "product_string": "USB Receiver",
     "usage_page": 1, "usage": 6, "interface_number": 0},
    {"path": b"/dev/hidraw2", "vendor_id": 0x16C0, "product_id": 0x0486, "serial_number": "123",
     "release_number": 0x0100, "manufacturer_string": "Teensyduino", "product_string": "Teensyduino RawHID",
     "usage_page": 0xFFAB, "usage": 0x0200, "interface_number": 0},
    {"path": b"/dev/hidraw3", "vendor_id": 0x16C0, "product_id": 0x0486, "serial_number": "123",
     "release_number": 0x0100, "manufacturer_string": "Teensyduino", "product_string": "Teensyduino RawHID",
     "usage_page": 0xFFC9, "usage": 0x0004, "interface_number": 1},
]


def test_list_devices_matches_profiles():
    rows = list_devices(lambda: FAKE_ENUM)
    assert [(r["id"], r["profile"]) for r in rows] == [
        ("046d:c626", "spacemouse"), ("046d:c52b", None), ("16c0:0486", "open_haptic_rawhid"), ("16c0:0486", None)]
    assert rows[0]["model"] == "SpaceNavigator" and rows[0]["path"] == "/dev/hidraw0"


def test_devices_main_table_and_json():
    out = io.StringIO()
    assert devices_main(False, enumerate_fn=lambda: FAKE_ENUM, out=out) == 0
    text = out.getvalue()
    assert "046d:c626  spacemouse" in text and "/dev/hidraw2" in text and "profiles: open_haptic" in text
    out = io.StringIO()
    assert devices_main(True, enumerate_fn=lambda: FAKE_ENUM, out=out) == 0
    doc = json.loads(out.getvalue())
    assert doc["devices"][0]["profile"] == "spacemouse" and doc["devices"][1]["profile"] is None
    assert {p["name"] for p in doc["profiles"]} >= set(SHIPPED)
    out = io.StringIO()
    assert devices_main(False, enumerate_fn=lambda: [], out=out) == 0
    assert "no HID devices connected" in out.getvalue()

    def broken():
        raise OSError("hidapi exploded")
    err = io.StringIO()
    assert devices_main(True, enumerate_fn=broken, out=io.StringIO(), err=err) == 1
    assert "hidapi exploded" in err.getvalue()


def test_list_devices_real_hid_module():
    """With the real hidapi module: one row per device `hid.enumerate()` reports, in its order,
    with its vendor and product ids (this machine may have none: then both are empty)."""
    hid = pytest.importorskip("hid")
    want = [(info.get("vendor_id"), info.get("product_id")) for info in hid.enumerate()]
    assert [(row["vendor_id"], row["product_id"]) for row in list_devices()] == want


class FakeHidModule:
    def __init__(self, infos):
        self.infos = infos
        self.opened = []

    def enumerate(self, vendor_id=0, product_id=0):
        return list(self.infos)

    def device(self):
        module = self

        class Dev(FakeHid):
            def open_path(self, path):
                if not isinstance(path, bytes):
                    raise TypeError("path must be bytes")
                if path == b"/dev/denied":
                    raise OSError("open failed")
                module.opened.append(path)
        return Dev()


def test_open_finds_the_matching_device():
    mod = FakeHidModule(FAKE_ENUM)
    dev = HidDevice.open("spacemouse", hid_module=mod)
    assert mod.opened == [b"/dev/hidraw0"] and "/dev/hidraw0" in dev.label
    dev = HidDevice.open("open_haptic_rawhid", hid_module=mod)  # the Raw HID interface, not the serial one
    assert mod.opened[-1] == b"/dev/hidraw2"
    dev = HidDevice.open("spacemouse", "/dev/hidraw5", hid_module=mod)  # a str path is encoded
    assert mod.opened[-1] == b"/dev/hidraw5"
    with pytest.raises(DeviceError, match="no connected HID device matches profile 'open_haptic' \\(ids 1209:0001\\)"):
        HidDevice.open("open_haptic", hid_module=mod)
    with pytest.raises(DeviceError, match="cannot open HID device '/dev/denied'.*open failed.*udev"):
        HidDevice.open("spacemouse", "/dev/denied", hid_module=mod)


def test_from_config(tmp_path):
    dev = HidDevice.from_config({"type": "hid", "profile": "spacemouse", "mode": "rate",
                                 "workspace_offset": [0, 0, 0.05], "workspace_half_m": [0.1, 0.1, 0.05],
                                 "workspace_scale": 0.5, "twist_limit_rad": 2.0},
                                source="scene.toml", transport=FakeHid())
    assert dev.mode == "rate" and dev.workspace_offset == (0.0, 0.0, 0.05) and dev.twist_limit_rad == 2.0
    mod = FakeHidModule(FAKE_ENUM)
    dev = HidDevice.from_config({"profile": "spacemouse", "path": "/dev/hidraw0"}, source="s.toml", hid_module=mod)
    assert mod.opened == [b"/dev/hidraw0"] and dev.mode == "position"
    # a profile path relative to the scene file
    scene = tmp_path / "scene.toml"
    scene.write_text("")
    (tmp_path / "profiles").mkdir()
    (tmp_path / "profiles" / "arm.toml").write_text((PROFILE_DIR / "open_haptic.toml").read_text())
    dev = HidDevice.from_config({"type": "hid", "profile": "profiles/arm.toml", "stale_ms": 5},
                                source=str(scene), transport=FakeHid())
    assert dev.profile.name == "open_haptic" and dev.stale_ms == 5.0


@pytest.mark.parametrize("cfg,message", [
    ({"type": "sim", "profile": "spacemouse"}, "s.toml: device.type must be \"hid\""),
    ({"type": "hid"}, "s.toml: device.profile is required: the name of a HID profile"),
    ({"profile": "nope"}, "s.toml: device.profile: no HID profile named 'nope'"),
    ({"profile": "open_haptic", "mode": "rate"}, "s.toml: device.mode must be one of ['position']"),
    ({"profile": "spacemouse", "workspace_offset": [0, 0]}, "s.toml: device.workspace_offset must be 3 finite"),
    ({"profile": "spacemouse", "workspace_half_m": [0.1, 0, 0.1]},
     "s.toml: device.workspace_half_m[1] must be a finite number > 0 m, got 0"),
    ({"profile": "spacemouse", "workspace_scale": math.inf}, "s.toml: device.workspace_scale must be a finite"),
    ({"profile": "open_haptic", "max_force_N": 50.0}, "s.toml: device.max_force_N must be a finite number in [0, 5]"),
    ({"profile": "spacemouse", "max_torque_Nm": 0.1}, "s.toml: device.max_torque_Nm must be a finite number in [0, 0]"),
    ({"profile": "spacemouse", "stale_ms": -1}, "s.toml: device.stale_ms must be a finite number >= 0"),
    ({"profile": "spacemouse", "path": 3}, "s.toml: device.path must be a HID device path"),
    ({"profile": "spacemouse", "keyframes": []}, "s.toml: device has unknown field(s) ['keyframes']"),
    ("spacemouse", "s.toml: device must be a table"),
])
def test_from_config_errors_name_the_field(cfg, message):
    with pytest.raises(ValueError) as exc:
        HidDevice.from_config(cfg, source="s.toml", transport=FakeHid())
    assert str(exc.value).startswith(message), str(exc.value)


def test_from_argument_for_any_scene():
    """`--device hid:PROFILE,key=value`: replaces a scripted scene's [device], overrides a HID one."""
    class Scene:
        device = {"type": "sim", "finger": [{"keyframes": [[0, 0, 0, 0, 0]]}]}
    dev = HidDevice.from_argument("spacemouse,mode=rate,workspace_offset=0:0:0.05,twist_limit_rad=1",
                                  Scene(), transport=FakeHid())
    assert dev.profile.name == "spacemouse" and dev.mode == "rate"
    assert dev.workspace_offset == (0.0, 0.0, 0.05) and dev.twist_limit_rad == 1.0
    Scene.device = {"type": "hid", "profile": "open_haptic", "max_force_N": 1.0, "stale_ms": 5}
    dev = HidDevice.from_argument("stale_ms=8", Scene(), transport=FakeHid())
    assert dev.profile.name == "open_haptic" and dev.max_force == 1.0 and dev.stale_ms == 8.0
    mod = FakeHidModule(FAKE_ENUM)
    HidDevice.from_argument("spacemouse,path=/dev/hidraw0", None, hid_module=mod)
    assert mod.opened == [b"/dev/hidraw0"]
    with pytest.raises(ValueError, match="--device hid:spacemouse,mode: expected PROFILE"):
        HidDevice.from_argument("spacemouse,mode", None, transport=FakeHid())
    with pytest.raises(ValueError, match="stale_ms must be a number"):
        HidDevice.from_argument("spacemouse,stale_ms=soon", None, transport=FakeHid())
    with pytest.raises(ValueError, match="device.workspace_offset must be 3 finite"):
        HidDevice.from_argument("spacemouse,workspace_offset=0:1", None, transport=FakeHid())
    with pytest.raises(ValueError, match="device.profile is required: the name of a HID profile"):
        HidDevice.from_argument("", None, transport=FakeHid())


def test_from_config_without_device_is_device_error():
    with pytest.raises(DeviceError, match="no connected HID device matches profile 'spacemouse'"):
        HidDevice.from_config({"type": "hid", "profile": "spacemouse"}, source="s.toml",
                              hid_module=FakeHidModule([]))


# ---------------------------------------------------------------------------------------------
# in the servo loop

class StreamingHid(FakeHid):
    """A firmware stand-in: one report per read call, the fingertip descending onto the box."""

    def __init__(self):
        super().__init__()
        self.seq = 0
        self.calls = 0

    def read(self, max_length, timeout_ms=0):
        if self.read_error is not None:
            raise self.read_error
        self.calls += 1
        if self.calls % 2 == 0:  # every other call: nothing pending (the drain loop's end)
            return []
        self.seq += 1
        z_um = max(57_000, 80_000 - 50 * self.seq)  # down to 1 mm into the top face (z = 0.06 + 8 mm radius)
        return list(oh_state(self.seq, 0x01, 0, 0, z_um, 0))


def test_servo_loop_renders_through_hid_and_survives_disconnect():

    t = StreamingHid()
    dev = HidDevice("open_haptic", t, clock=time.monotonic, stale_ms=0)
    loop = box_loop(dev)
    loop.run(600)
    forces = [parse_output(dev.profile, w) for w in t.writes]
    assert all(abs(f["fz"]) <= 5.0 and abs(f["torque"]) <= 0.05 for f in forces)
    assert max(f["fz"] for f in forces) > 0.5  # pressing down: the box pushes up
    assert loop.faults["device_error"] == 0 and loop.faults["invalid_sample"] == 0
    t.read_error = OSError("read error")  # unplugged
    n = len(t.writes)
    loop.run(5)
    assert loop.faults["device_error"] == 5
    assert loop.faults["send_error"] == 6  # 5 ticks + the zero force sent when a run ends
    after = [parse_output(dev.profile, w) for w in t.writes[n:]]  # the writes still go through:
    assert len(after) == 4 and all(w["enable"] == 0 and w["fz"] == 0.0 for w in after)  # zero force only
    dev.close()
    assert parse_output(dev.profile, t.writes[-1])["enable"] == 0


# keep last: counts what the fuzz tests above parsed
def test_fuzz_total_count():
    """The fuzz tests in this file fed at least 10^5 reports to the parsers (when run together)."""
    if not {"random", "truncated", "oversized", "float32", "device"} <= set(FUZZ_COUNTS):
        pytest.skip("run with the fuzz tests")
    total = sum(v for k, v in FUZZ_COUNTS.items() if k != "output")
    print(f"\nfuzzed reports: {FUZZ_COUNTS}; parsed in total {total}")
    assert total >= 100_000, FUZZ_COUNTS
