"""The simulated device (devices/simulated.py): minimum-jerk keyframes, sensor effects (latency,
noise, quantisation), the motor's saturation, and the [device] table of a scene."""

import math
import statistics
import tomllib

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from softproxy.devices.simulated import SimulatedDevice
from softproxy.device import Device, DeviceError, DeviceSample

# (t, x, y, z, twist): a reach, a hold, a move back with a twist
KEYS = [(0.0, 0.0, 0.0, 0.1, 0.0), (1.0, 0.02, -0.01, 0.05, 0.4), (1.5, 0.02, -0.01, 0.05, 0.4),
        (3.0, -0.03, 0.01, 0.08, -0.2)]


def read(dev, t, finger=0):
    """(x, y, z, twist) of one finger read at loop time t."""
    samples = [DeviceSample() for _ in range(dev.fingers)]
    dev.read(t, samples)
    s = samples[finger]
    return (s.x, s.y, s.z, s.twist)


def min_jerk(u):
    return 10 * u**3 - 15 * u**4 + 6 * u**5


# --- trajectory -------------------------------------------------------------------------------

def test_keyframes_are_hit_exactly_and_held_outside_the_script():
    dev = SimulatedDevice([KEYS])
    for t, *pose in KEYS:
        assert read(dev, t) == tuple(pose)
    assert read(dev, -5.0) == KEYS[0][1:]
    assert read(dev, 99.0) == KEYS[-1][1:]
    assert read(dev, math.inf) == KEYS[-1][1:]
    for t, *pose in reversed(KEYS):  # and again going back in time
        assert read(dev, t) == tuple(pose)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.floats(1e-3, 10.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0), st.floats(-1.0, 1.0),
                          st.floats(-3.0, 3.0)), min_size=1, max_size=6))
def test_random_scripts_pass_through_every_keyframe(steps):
    t, keys = 0.0, []
    for dt, *pose in steps:
        t += dt
        keys.append((t, *pose))
    dev = SimulatedDevice([keys])
    for t, *pose in keys:
        assert read(dev, t) == tuple(pose)


def test_segment_midpoint_is_the_midpoint_and_timing_is_minimum_jerk():
    dev = SimulatedDevice([KEYS])
    (t0, *a), (t1, *b) = KEYS[2], KEYS[3]
    mid = read(dev, (t0 + t1) / 2)
    assert mid == pytest.approx([(p + q) / 2 for p, q in zip(a, b)], abs=1e-15)
    for u in (0.1, 0.25, 0.8):
        s = min_jerk(u)
        assert read(dev, t0 + u * (t1 - t0)) == pytest.approx([p + s * (q - p) for p, q in zip(a, b)], abs=1e-12)
    assert min_jerk(0.25) == 0.103515625  # not linear (0.25) nor cubic smoothstep (0.15625)


def test_velocity_and_acceleration_vanish_at_keyframes():
    """A hand, not a robot: no velocity kick at a keyframe; peak speed 1.875 Δ/T mid-segment."""
    dev = SimulatedDevice([KEYS])
    h = 1e-4
    for t, *_ in KEYS:
        before, at, after = read(dev, t - h), read(dev, t), read(dev, t + h)
        for axis in range(4):
            assert abs(after[axis] - at[axis]) / h < 1e-6
            assert abs(at[axis] - before[axis]) / h < 1e-6
            assert abs(after[axis] - 2 * at[axis] + before[axis]) / h**2 < 1e-2
    (t0, *a), (t1, *b) = KEYS[0], KEYS[1]
    tm = (t0 + t1) / 2
    vz = (read(dev, tm + h)[2] - read(dev, tm - h)[2]) / (2 * h)
    assert vz == pytest.approx(1.875 * (b[2] - a[2]) / (t1 - t0), rel=1e-6)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-1.0, 4.0), min_size=1, max_size=40))
def test_reads_in_any_time_order_match_the_script(times):
    """The remembered segment is only a hint: jumps forward, back and repeats give the same poses."""
    dev = SimulatedDevice([KEYS, KEYS[1:]])
    for t in times:
        for finger in (0, 1):
            assert read(dev, t, finger) == dev.pose(finger, t)
    fresh = SimulatedDevice([KEYS, KEYS[1:]])
    assert [fresh.pose(0, t) for t in times] == [dev.pose(0, t) for t in times]


def test_fingers_follow_their_own_scripts_and_a_single_keyframe_stands_still():
    still = [(0.5, 0.01, 0.02, 0.03, 0.1)]
    dev = SimulatedDevice([KEYS, still])
    assert dev.fingers == 2 and dev.duration == 3.0
    samples = [DeviceSample(), DeviceSample()]
    for t in (0.0, 0.7, 2.0, 5.0):
        dev.read(t, samples)
        assert (samples[0].x, samples[0].y, samples[0].z, samples[0].twist) == dev.pose(0, t)
        assert (samples[1].x, samples[1].y, samples[1].z, samples[1].twist) == still[0][1:]
        for s in samples:
            assert s.t == t and s.valid and s.buttons == 0 and s.is_finite()
            assert (s.qw, s.qx, s.qy, s.qz) == (1.0, 0.0, 0.0, 0.0)


def test_read_fills_stale_samples_completely():
    dev = SimulatedDevice([KEYS])
    s = DeviceSample()
    s.valid, s.buttons, s.qw, s.qx = False, 7, 0.0, 1.0
    dev.read(0.3, [s])
    assert s.valid and s.buttons == 0 and (s.qw, s.qx) == (1.0, 0.0)


def test_nan_time_is_refused():
    with pytest.raises(ValueError, match="read time"):
        SimulatedDevice([KEYS]).read(math.nan, [DeviceSample()])


# --- sensor effects ---------------------------------------------------------------------------

def test_latency_delays_the_trajectory_but_not_the_timestamp():
    late = SimulatedDevice([KEYS], latency_s=0.2)
    on_time = SimulatedDevice([KEYS])
    for t in (0.1, 0.5, 1.2, 1.7, 2.9, 3.1):
        s = DeviceSample()
        late.read(t, [s])
        assert (s.x, s.y, s.z, s.twist) == read(on_time, t - 0.2)
        assert s.t == t
    assert read(late, 0.5) != read(on_time, 0.5)


def test_quantisation_gives_exact_multiples_of_the_resolution():
    qm, qr = 1e-4, 2e-3
    exact = SimulatedDevice([KEYS], noise_m=3e-4, noise_rad=1e-2, seed=5)
    coarse = SimulatedDevice([KEYS], noise_m=3e-4, noise_rad=1e-2, seed=5, quantum_m=qm, quantum_rad=qr)
    for k in range(300):
        t = k * 0.01
        raw, q = read(exact, t), read(coarse, t)
        for value, r, step in zip(q, raw, (qm, qm, qm, qr)):
            n = round(value / step)
            assert value == n * step  # exactly what the encoder count gives
            assert abs(value - r) <= step / 2 * (1 + 1e-9)  # nearest count to the true reading


def test_same_seed_same_samples_other_seed_other_noise():
    def run(seed, **kw):
        dev = SimulatedDevice([KEYS, KEYS], noise_m=1e-3, noise_rad=1e-2, seed=seed, **kw)
        return [read(dev, k * 0.013, finger) for k in range(100) for finger in (0, 1)]

    assert run(7) == run(7)
    a, b = run(7), run(8)
    assert all(p != q for pa, pb in zip(a, b) for p, q in zip(pa, pb))


def test_fault_injection_is_seeded():
    def run(seed):
        dev = SimulatedDevice([KEYS], faults={"nan": 0.2, "drop": 0.2}, seed=seed)
        samples = [DeviceSample()]
        out = []
        for k in range(200):
            dev.read(k * 1e-3, samples)
            out.append(repr((samples[0].x, samples[0].valid)))  # repr: NaN == NaN
        return out, dict(dev.injected)

    a, b, c = run(1), run(1), run(2)
    assert a == b and a != c
    assert 20 < a[1]["nan"] < 60 and 20 < a[1]["drop"] < 60


def test_position_noise_does_not_depend_on_twist_noise_or_faults():
    """Turning twist noise or fault injection on leaves the position noise of a seed unchanged."""
    def positions(**kw):
        dev = SimulatedDevice([KEYS], noise_m=1e-3, seed=3, **kw)
        return [read(dev, k * 0.01)[:3] for k in range(200)]

    base = positions()
    assert positions(noise_rad=0.05) == base
    assert positions(faults={"drop": 0.3}) == base


def test_noise_has_the_configured_standard_deviation():
    nm, nr = 2e-4, 5e-3
    dev = SimulatedDevice([KEYS], noise_m=nm, noise_rad=nr, seed=11)
    readings = [read(dev, 10.0) for _ in range(20000)]
    truth = KEYS[-1][1:]
    for axis, std in zip(range(4), (nm, nm, nm, nr)):
        errors = [r[axis] - truth[axis] for r in readings]
        assert statistics.fmean(errors) == pytest.approx(0.0, abs=4 * std / math.sqrt(len(errors)))
        assert statistics.pstdev(errors) == pytest.approx(std, rel=0.03)
    dx = [r[0] - truth[0] for r in readings]
    dy = [r[1] - truth[1] for r in readings]
    assert abs(statistics.correlation(dx, dy)) < 0.03  # the two of a Box-Muller pair are independent


# --- motor ------------------------------------------------------------------------------------

vectors = st.tuples(*[st.floats(-1e6, 1e6, allow_subnormal=False)] * 3)


@settings(max_examples=200, deadline=None)
@given(vectors, vectors)
def test_send_saturates_magnitude_and_keeps_direction(force, torque):
    dev = SimulatedDevice([KEYS, KEYS], max_force=20.0, max_torque=0.5)
    dev.send(1, *force, *torque)
    for sent, rendered, limit in ((force, dev.last_force[1], 20.0), (torque, dev.last_torque[1], 0.5)):
        size = math.hypot(*sent)
        assert math.hypot(*rendered) <= limit * (1 + 1e-12)
        if size <= limit:
            assert rendered == sent
        else:
            scale = limit / size
            assert rendered == pytest.approx([c * scale for c in sent], rel=1e-12, abs=1e-300)
    assert dev.last_force[0] == (0.0, 0.0, 0.0) and dev.sends == 1 and dev.nan_sends == 0


def test_send_clamp_example_and_zero_capacity():
    dev = SimulatedDevice([KEYS], max_force=5.0, max_torque=0.0)
    dev.send(0, 30.0, 0.0, -40.0, 0.0, 0.0, 0.2)
    assert dev.last_force[0] == pytest.approx((3.0, 0.0, -4.0))
    assert dev.last_torque[0] == (0.0, 0.0, 0.0)
    assert dev.max_force_sent == 50.0  # what the engine asked for, before the motor's saturation


@pytest.mark.parametrize("bad", [math.nan, math.inf, -math.inf])
@pytest.mark.parametrize("slot", range(6))
def test_non_finite_send_renders_nothing_and_is_counted(bad, slot):
    dev = SimulatedDevice([KEYS])
    dev.send(0, 1.0, 2.0, 3.0, 0.01, 0.02, 0.03)
    values = [1.0, 2.0, 3.0, 0.01, 0.02, 0.03]
    values[slot] = bad
    dev.send(0, *values)
    assert dev.last_force[0] == (0.0, 0.0, 0.0) and dev.last_torque[0] == (0.0, 0.0, 0.0)
    assert dev.nan_sends == 1 and dev.sends == 2
    dev.send(0, 1e308, 1e308, 0.0, 0.0, 0.0, 0.0)  # huge but finite (their sum is not): saturated, not refused
    assert dev.nan_sends == 1 and math.hypot(*dev.last_force[0]) == pytest.approx(20.0)


# --- protocol ---------------------------------------------------------------------------------

def test_implements_the_device_protocol():
    dev = SimulatedDevice([KEYS], max_force=12.0, max_torque=0.3)
    assert isinstance(dev, Device)
    assert (dev.fingers, dev.max_force, dev.max_torque) == (1, 12.0, 0.3)


def test_read_after_close_raises_device_error():
    dev = SimulatedDevice([KEYS])
    dev.read(0.0, [DeviceSample()])
    dev.close()
    with pytest.raises(DeviceError, match="simulated device is closed"):
        dev.read(0.1, [DeviceSample()])


# --- configuration ----------------------------------------------------------------------------

TOML = """
[device]
type = "sim"
noise_m = 1e-4
noise_rad = 2e-3
latency_s = 0.004
quantum_m = 1e-5
quantum_rad = 1e-3
max_force_N = 15.0
max_torque_Nm = 0.25
seed = 42

[[device.finger]]
keyframes = [[0.0, 0.0, 0.0, 0.1, 0.0], [1.0, 0.0, 0.0, 0.05, 0.0]]

[[device.finger]]
keyframes = [[0.0, 0.01, 0.0, 0.1, 0.0], [0.5, 0.01, 0.0, 0.06, 0.3], [2.0, 0.01, 0.0, 0.06, 0.3]]
"""


def test_from_config_round_trip():
    cfg = tomllib.loads(TOML)["device"]
    dev = SimulatedDevice.from_config(cfg, source="hand.toml")
    assert (dev.fingers, dev.max_force, dev.max_torque, dev.duration) == (2, 15.0, 0.25, 2.0)
    assert (dev.noise_m, dev.noise_rad, dev.latency_s, dev.quantum_m, dev.quantum_rad, dev.seed) == (
        1e-4, 2e-3, 0.004, 1e-5, 1e-3, 42)
    direct = SimulatedDevice([f["keyframes"] for f in cfg["finger"]], noise_m=1e-4, noise_rad=2e-3, latency_s=0.004,
                             quantum_m=1e-5, quantum_rad=1e-3, max_force=15.0, max_torque=0.25, seed=42)
    for k in range(50):
        assert read(dev, k * 0.05, 1) == read(direct, k * 0.05, 1)


def test_from_config_defaults_match_the_constructor():
    dev = SimulatedDevice.from_config({"finger": [{"keyframes": [[0.0, 0.0, 0.0, 0.1, 0.0]]}]})
    assert (dev.noise_m, dev.noise_rad, dev.latency_s, dev.quantum_m, dev.quantum_rad) == (0.0,) * 5
    assert (dev.max_force, dev.max_torque, dev.seed) == (20.0, 0.5, 0)


def good_config():
    return tomllib.loads(TOML)["device"]


def keyframe(i, j, value):
    def mutate(cfg):
        cfg["finger"][i]["keyframes"][j] = value
    return mutate


def set_key(key, value):
    def mutate(cfg):
        cfg[key] = value
    return mutate


def add_keyframe(value):
    def mutate(cfg):
        cfg["finger"][1]["keyframes"].append(value)
    return mutate


@pytest.mark.parametrize("mutate, field, expected", [
    (set_key("noize_m", 0.1), "noize_m", "unknown"),
    (set_key("noise_m", "0.1"), "device.noise_m", "finite number >= 0"),
    (set_key("noise_rad", True), "device.noise_rad", "finite number >= 0"),
    (set_key("latency_s", math.nan), "device.latency_s", "finite number >= 0"),
    (set_key("max_force_N", math.inf), "device.max_force_N", "finite number >= 0"),
    (set_key("quantum_m", -1e-5), "device.quantum_m", "finite number >= 0"),
    (set_key("quantum_rad", -1.0), "device.quantum_rad", "finite number >= 0"),
    (set_key("max_torque_Nm", -0.1), "device.max_torque_Nm", "finite number >= 0"),
    (set_key("seed", 1.5), "device.seed", "integer"),
    (set_key("finger", []), "device.finger", "[[device.finger]]"),
    (lambda cfg: cfg.pop("finger"), "device.finger", "[[device.finger]]"),
    (lambda cfg: cfg["finger"][1].update(colour="red"), "device.finger[1]", "unknown field(s) ['colour']"),
    (lambda cfg: cfg["finger"][0].update(keyframes=[]), "device.finger[0].keyframes", "non-empty list"),
    (add_keyframe([3.0, 0.0, 0.0, 0.1]), "device.finger[1].keyframes[3]", "5 finite numbers"),
    (add_keyframe([3.0, 0.0, 0.0, 0.1, 0.0, 0.0]), "device.finger[1].keyframes[3]", "5 finite numbers"),
    (add_keyframe([3.0, 0.0, math.nan, 0.1, 0.0]), "device.finger[1].keyframes[3]", "5 finite numbers"),
    (add_keyframe([3.0, 0.0, "0", 0.1, 0.0]), "device.finger[1].keyframes[3]", "5 finite numbers"),
    (add_keyframe(3.0), "device.finger[1].keyframes[3]", "5 finite numbers"),
    (add_keyframe([2.0, 0.0, 0.0, 0.1, 0.0]), "device.finger[1].keyframes[3]", "later than t = 2.0"),
    (keyframe(1, 2, [0.2, 0.0, 0.0, 0.1, 0.0]), "device.finger[1].keyframes[2]", "later than t = 0.5"),
    (lambda cfg: cfg.update(faults={"gremlins": 0.1}), "device.faults.gremlins", "one of"),
    (lambda cfg: cfg.update(faults={"nan": 2.0}), "device.faults.nan", "[0, 1]"),
])
def test_bad_config_is_refused_naming_source_and_field(mutate, field, expected):
    cfg = good_config()
    mutate(cfg)
    with pytest.raises(ValueError) as err:
        SimulatedDevice.from_config(cfg, source="scenes/hand.toml")
    message = str(err.value)
    assert message.startswith("scenes/hand.toml: ")
    assert field in message and expected in message


def test_config_that_is_not_a_table_is_refused():
    with pytest.raises(ValueError, match=r"<config>: device must be a table"):
        SimulatedDevice.from_config([1, 2])


@pytest.mark.parametrize("kwargs, words", [
    (dict(noise_m=-1e-3), "noise_m"),
    (dict(noise_rad=math.nan), "noise_rad"),
    (dict(latency_s=math.inf), "latency_s"),
    (dict(quantum_m="1e-5"), "quantum_m"),
    (dict(quantum_rad=-1.0), "quantum_rad"),
    (dict(max_force=-1.0), "max_force"),
    (dict(max_torque=math.nan), "max_torque"),
    (dict(seed=2.5), "seed"),
    (dict(faults={"nan": 2.0}), "faults.nan"),
])
def test_constructor_errors_name_the_parameter(kwargs, words):
    with pytest.raises(ValueError, match=words):
        SimulatedDevice([KEYS], **kwargs)


@pytest.mark.parametrize("keyframes, words", [
    ([], "keyframes must be a list"),
    ([KEYS, []], r"keyframes\[1\]"),
    ([[(0.0, 0.0, 0.0, 0.1)]], r"keyframes\[0\]\[0\] must be 5 finite numbers"),
    ([[0.0]], r"keyframes\[0\]\[0\] must be 5 finite numbers"),
    ([KEYS[:2] + [KEYS[0]]], r"keyframes\[0\]\[2\]: times must increase"),
])
def test_constructor_refuses_bad_keyframes(keyframes, words):
    with pytest.raises(ValueError, match=words):
        SimulatedDevice(keyframes)
