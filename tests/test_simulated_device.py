"""The simulated device: scripted, smooth, reproducible, and honest about what it is sent."""

import math
import statistics

import pytest

from devices.simulated import SimulatedDevice
from softproxy.device import Device, DeviceError, DeviceSample

KEYS = [[(0.0, 0.0, 0.0, 0.1, 0.0), (1.0, 0.1, -0.2, 0.05, 0.5), (3.0, 0.1, -0.2, 0.05, 0.5)]]


def sample(dev, t, finger=0):
    samples = [DeviceSample() for _ in range(dev.fingers)]
    dev.read(t, samples)
    s = samples[finger]
    return s.x, s.y, s.z, s.twist


def test_protocol_and_keyframes_hit_exactly():
    dev = SimulatedDevice(KEYS)
    assert isinstance(dev, Device) and dev.fingers == 1 and dev.duration == 3.0
    assert sample(dev, 0.0) == (0.0, 0.0, 0.1, 0.0)
    assert sample(dev, 1.0) == (0.1, -0.2, 0.05, 0.5)
    assert sample(dev, -5.0) == (0.0, 0.0, 0.1, 0.0) and sample(dev, 99.0) == (0.1, -0.2, 0.05, 0.5)


def test_minimum_jerk_midpoint_and_rest_at_keyframes():
    dev = SimulatedDevice(KEYS)
    assert sample(dev, 0.5) == pytest.approx((0.05, -0.1, 0.075, 0.25))
    h = 1e-4
    for t in (0.0 + h, 1.0 - h, 1.0 + h):
        v = (sample(dev, t)[0] - sample(dev, t - h)[0]) / h
        assert abs(v) < 1e-5  # zero velocity at the keyframes: no kick
    # peak speed of minimum jerk is 15/8 of the mean
    v_mid = (sample(dev, 0.5 + h)[0] - sample(dev, 0.5 - h)[0]) / (2 * h)
    assert v_mid == pytest.approx(0.1 * 15 / 8, rel=1e-6)


def test_time_going_backwards_is_handled():
    dev = SimulatedDevice(KEYS)
    a = sample(dev, 2.0)
    assert sample(dev, 0.25) == pytest.approx(SimulatedDevice(KEYS).pose(0, 0.25))
    assert sample(dev, 2.0) == a


def test_latency_shifts_in_time():
    late = SimulatedDevice(KEYS, latency_s=0.1)
    assert sample(late, 0.6) == pytest.approx(SimulatedDevice(KEYS).pose(0, 0.5))


def test_quantisation_gives_multiples():
    dev = SimulatedDevice(KEYS, quantum_m=1e-4, quantum_rad=1e-3)
    for t in (0.13, 0.77, 1.5):
        x, y, z, tw = sample(dev, t)
        for v, q in ((x, 1e-4), (y, 1e-4), (z, 1e-4), (tw, 1e-3)):
            assert abs(v / q - round(v / q)) < 1e-9


def test_noise_is_seeded_and_of_the_right_size():
    a = [sample(SimulatedDevice(KEYS, noise_m=1e-3, seed=4), 1.5) for _ in range(1)]
    b = [sample(SimulatedDevice(KEYS, noise_m=1e-3, seed=4), 1.5) for _ in range(1)]
    c = [sample(SimulatedDevice(KEYS, noise_m=1e-3, seed=5), 1.5) for _ in range(1)]
    assert a == b and a != c
    dev = SimulatedDevice(KEYS, noise_m=1e-3, seed=1)
    xs = [sample(dev, 2.0)[0] - 0.1 for _ in range(4000)]
    assert statistics.pstdev(xs) == pytest.approx(1e-3, rel=0.05)
    assert abs(statistics.mean(xs)) < 1e-4


def test_send_saturates_and_refuses_nan():
    dev = SimulatedDevice(KEYS, max_force=10.0, max_torque=0.1)
    dev.send(0, 30.0, 40.0, 0.0, 0.0, 0.0, 0.3)
    assert dev.last_force[0] == pytest.approx((6.0, 8.0, 0.0))  # direction kept, |F| = 10
    assert dev.last_torque[0] == pytest.approx((0.0, 0.0, 0.1))
    assert dev.max_force_sent == pytest.approx(50.0)
    dev.send(0, math.nan, 0.0, 0.0, 0.0, 0.0, 0.0)
    assert dev.last_force[0] == (0.0, 0.0, 0.0) and dev.nan_sends == 1


def test_closed_device_raises():
    dev = SimulatedDevice(KEYS)
    dev.close()
    with pytest.raises(DeviceError, match="closed"):
        sample(dev, 0.0)


def test_from_config_round_trip():
    cfg = {"type": "sim", "noise_m": 0.0, "seed": 2, "max_force_N": 12.0,
           "finger": [{"keyframes": [list(k) for k in KEYS[0]]}, {"keyframes": [[0.0, 1.0, 2.0, 3.0, 0.0]]}]}
    dev = SimulatedDevice.from_config(cfg, source="s.toml")
    assert dev.fingers == 2 and dev.max_force == 12.0
    assert sample(dev, 1.0, 0) == (0.1, -0.2, 0.05, 0.5) and sample(dev, 1.0, 1) == (1.0, 2.0, 3.0, 0.0)


@pytest.mark.parametrize(
    "cfg, words",
    [
        ({"finger": []}, ["device.finger"]),
        ({"finger": [{"keyframes": [[0, 0, 0]]}]}, ["device.finger[0].keyframes[0]", "5 finite numbers"]),
        ({"finger": [{"keyframes": [[1, 0, 0, 0, 0], [0.5, 0, 0, 0, 0]]}]}, ["device.finger[0].keyframes[1]", "later"]),
        ({"finger": [{"keyframes": [[0, float("nan"), 0, 0, 0]]}]}, ["keyframes[0]"]),
        ({"noise_m": -1.0, "finger": [{"keyframes": [[0, 0, 0, 0, 0]]}]}, ["device.noise_m", ">= 0"]),
        ({"seed": 1.5, "finger": [{"keyframes": [[0, 0, 0, 0, 0]]}]}, ["device.seed", "integer"]),
        ({"colour": "red", "finger": [{"keyframes": [[0, 0, 0, 0, 0]]}]}, ["colour"]),
        ({"faults": {"nan": 2.0}, "finger": [{"keyframes": [[0, 0, 0, 0, 0]]}]}, ["device.faults.nan", "[0, 1]"]),
    ],
)
def test_bad_config_names_the_field(cfg, words):
    with pytest.raises(ValueError) as err:
        SimulatedDevice.from_config(cfg, source="s.toml")
    for w in ["s.toml", *words]:
        assert w in str(err.value)


def test_fault_injection_is_seeded():
    def run(seed):
        dev = SimulatedDevice(KEYS, faults={"nan": 0.2, "drop": 0.2}, seed=seed)
        out = []
        for i in range(200):
            out.append(sample(dev, i * 1e-3))
        return out, dict(dev.injected)

    a, b, c = run(1), run(1), run(2)
    assert repr(a) == repr(b) and repr(a) != repr(c)
    assert 20 < a[1]["nan"] < 60 and 20 < a[1]["drop"] < 60
