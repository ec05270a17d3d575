"""Simulated haptic device: scripted finger trajectories that make runs reproducible.

Each finger follows keyframes (t, x, y, z, twist) in s, m and rad, with minimum-jerk timing
between them (zero velocity and acceleration at every keyframe, like a hand moving from pose
to pose). Optional sensor effects: Gaussian noise, latency, encoder quantisation; and the
motor's force saturation on what is sent back. Deterministic for a given seed.

Fault injection (`faults`, probabilities per read, drawn from their own seeded stream):
`nan` a NaN coordinate in one finger's sample; `drop` a missing sample (valid = False);
`spike` a 0.5 m jump of one finger's position for one read; `stall` the device stops
answering: the read blocks for `stall_s` (5 ms) and then fails with DeviceError. The device
counts what it injected (`injected`) and watches what it is sent: `max_force_sent` (N, before
its own saturation) and `nan_sends`, so a run can show that no fault reached the motor.
"""

from __future__ import annotations

import bisect
import math
import random
import time

from softproxy.device import DeviceError, DeviceSample

_CONFIG_KEYS = {"type", "noise_m", "noise_rad", "latency_s", "quantum_m", "quantum_rad",
                "max_force_N", "max_torque_Nm", "seed", "finger", "faults"}
FAULT_KINDS = ("nan", "drop", "spike", "stall")
SPIKE_M = 0.5
STALL_S = 0.005


def _fail(source: str, field: str, expected: str, got) -> ValueError:
    return ValueError(f"{source}: {field} must be {expected}, got {got!r}")


class SimulatedDevice:
    """A scripted multi-finger device implementing the `softproxy.device.Device` protocol."""

    def __init__(self, keyframes, *, noise_m: float = 0.0, noise_rad: float = 0.0, latency_s: float = 0.0,
                 quantum_m: float = 0.0, quantum_rad: float = 0.0, max_force: float = 20.0,
                 max_torque: float = 0.5, seed: int = 0, faults: dict | None = None) -> None:
        for name, value in (("noise_m", noise_m), ("noise_rad", noise_rad), ("latency_s", latency_s),
                            ("quantum_m", quantum_m), ("quantum_rad", quantum_rad),
                            ("max_force", max_force), ("max_torque", max_torque)):
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
                raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
        if not keyframes:
            raise ValueError("keyframes must list at least one finger")
        self._times: list[list[float]] = []
        self._poses: list[list[tuple[float, float, float, float]]] = []
        for i, frames in enumerate(keyframes):
            if not frames:
                raise ValueError(f"keyframes[{i}] must hold at least one keyframe")
            times, poses = [], []
            for j, key in enumerate(frames):
                if len(key) != 5 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in key):
                    raise ValueError(f"keyframes[{i}][{j}] must be 5 finite numbers [t, x, y, z, twist], got {key!r}")
                if times and key[0] <= times[-1]:
                    raise ValueError(f"keyframes[{i}][{j}]: times must increase, {key[0]} after {times[-1]}")
                times.append(float(key[0]))
                poses.append(tuple(float(v) for v in key[1:]))
            self._times.append(times)
            self._poses.append(poses)
        self.fingers = len(keyframes)
        self.noise_m, self.noise_rad = float(noise_m), float(noise_rad)
        self.latency_s = float(latency_s)
        self.quantum_m, self.quantum_rad = float(quantum_m), float(quantum_rad)
        self.max_force, self.max_torque = float(max_force), float(max_torque)
        self.seed = seed
        self._rng = random.Random(seed)
        self._segment = [0] * self.fingers
        self.last_force = [(0.0, 0.0, 0.0)] * self.fingers
        self.last_torque = [(0.0, 0.0, 0.0)] * self.fingers
        self.sends = 0
        self.nan_sends = 0
        self.max_force_sent = 0.0
        self.closed = False
        self.faults = {}
        for kind, rate in (faults or {}).items():
            if kind not in FAULT_KINDS:
                raise ValueError(f"faults: unknown fault {kind!r}; expected some of {', '.join(FAULT_KINDS)}")
            if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.0 <= rate <= 1.0:
                raise ValueError(f"faults.{kind} must be a probability per read in [0, 1], got {rate!r}")
            if rate > 0.0:
                self.faults[kind] = float(rate)
        self.injected = dict.fromkeys(FAULT_KINDS, 0)
        self._fault_rng = random.Random(seed + 7919)

    @property
    def duration(self) -> float:
        """Time of the last keyframe over all fingers (s)."""
        return max(times[-1] for times in self._times)

    def pose(self, finger: int, t: float) -> tuple[float, float, float, float]:
        """Noise-free scripted (x, y, z, twist) of a finger at time t (s)."""
        times = self._times[finger]
        poses = self._poses[finger]
        if t <= times[0]:
            return poses[0]
        if t >= times[-1]:
            return poses[-1]
        j = self._segment[finger]
        if not (times[j] <= t < times[j + 1]):  # time moved on (or back): find the segment
            j = bisect.bisect_right(times, t) - 1
            self._segment[finger] = j
        t0 = times[j]
        u = (t - t0) / (times[j + 1] - t0)
        s = u * u * u * (10.0 + u * (6.0 * u - 15.0))  # minimum jerk: s(0)=0, s(1)=1, s'=s''=0 at both
        a, b = poses[j], poses[j + 1]
        return (a[0] + s * (b[0] - a[0]), a[1] + s * (b[1] - a[1]), a[2] + s * (b[2] - a[2]), a[3] + s * (b[3] - a[3]))

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        if self.closed:
            raise DeviceError("simulated device is closed")
        ts = t - self.latency_s
        gauss = self._rng.gauss
        nm, nr, qm, qr = self.noise_m, self.noise_rad, self.quantum_m, self.quantum_rad
        for i in range(self.fingers):
            x, y, z, twist = self.pose(i, ts)
            if nm > 0.0:
                x += gauss(0.0, nm)
                y += gauss(0.0, nm)
                z += gauss(0.0, nm)
            if nr > 0.0:
                twist += gauss(0.0, nr)
            if qm > 0.0:
                x, y, z = round(x / qm) * qm, round(y / qm) * qm, round(z / qm) * qm
            if qr > 0.0:
                twist = round(twist / qr) * qr
            s = samples[i]
            s.t = t
            s.x, s.y, s.z, s.twist = x, y, z, twist
            s.qw, s.qx, s.qy, s.qz = 1.0, 0.0, 0.0, 0.0
            s.buttons = 0
            s.valid = True
        if self.faults:
            self._inject(samples)

    def _inject(self, samples: list[DeviceSample]) -> None:
        rnd = self._fault_rng.random
        for kind, rate in self.faults.items():
            if rnd() >= rate:
                continue
            self.injected[kind] += 1
            s = samples[int(rnd() * self.fingers)]
            if kind == "nan":
                s.x = math.nan
            elif kind == "drop":
                s.valid = False
            elif kind == "spike":
                s.z += SPIKE_M
            else:  # stall: no answer within the timeout
                time.sleep(STALL_S)
                raise DeviceError(f"simulated device: no answer within {STALL_S * 1e3:g} ms")

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        """Render a force (N) and torque (N·m); the motor saturates at max_force / max_torque."""
        self.sends += 1
        if not math.isfinite(fx + fy + fz + tx + ty + tz):
            self.nan_sends += 1  # the engine promises never to send this; the motor renders nothing
            self.last_force[finger] = (0.0, 0.0, 0.0)
            self.last_torque[finger] = (0.0, 0.0, 0.0)
            return
        f = math.sqrt(fx * fx + fy * fy + fz * fz)
        if f > self.max_force_sent:
            self.max_force_sent = f
        if f > self.max_force:
            k = self.max_force / f
            fx, fy, fz = fx * k, fy * k, fz * k
        m = math.sqrt(tx * tx + ty * ty + tz * tz)
        if m > self.max_torque:
            k = self.max_torque / m
            tx, ty, tz = tx * k, ty * k, tz * k
        self.last_force[finger] = (fx, fy, fz)
        self.last_torque[finger] = (tx, ty, tz)

    def close(self) -> None:
        self.closed = True

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>") -> "SimulatedDevice":
        """Build from a scene's [device] table (see scenes/*.toml); errors name the field."""
        if not isinstance(cfg, dict):
            raise _fail(source, "device", "a table", cfg)
        unknown = set(cfg) - _CONFIG_KEYS
        if unknown:
            raise ValueError(f"{source}: device has unknown field(s) {sorted(unknown)}; expected some of {sorted(_CONFIG_KEYS)}")
        kwargs = {}
        for key, arg in (("noise_m", "noise_m"), ("noise_rad", "noise_rad"), ("latency_s", "latency_s"),
                         ("quantum_m", "quantum_m"), ("quantum_rad", "quantum_rad"),
                         ("max_force_N", "max_force"), ("max_torque_Nm", "max_torque")):
            if key in cfg:
                v = cfg[key]
                if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                    raise _fail(source, f"device.{key}", "a finite number >= 0", v)
                kwargs[arg] = float(v)
        if "faults" in cfg:
            faults = cfg["faults"]
            if not isinstance(faults, dict):
                raise _fail(source, "device.faults", "a table of fault = probability per read", faults)
            for kind, rate in faults.items():
                if kind not in FAULT_KINDS:
                    raise _fail(source, f"device.faults.{kind}", f"one of {', '.join(FAULT_KINDS)}", kind)
                if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.0 <= rate <= 1.0:
                    raise _fail(source, f"device.faults.{kind}", "a probability per read in [0, 1]", rate)
            kwargs["faults"] = dict(faults)
        if "seed" in cfg:
            if isinstance(cfg["seed"], bool) or not isinstance(cfg["seed"], int):
                raise _fail(source, "device.seed", "an integer", cfg["seed"])
            kwargs["seed"] = cfg["seed"]
        fingers = cfg.get("finger")
        if not isinstance(fingers, list) or not fingers:
            raise _fail(source, "device.finger", "a list of [[device.finger]] tables with keyframes", fingers)
        keyframes = []
        for i, f in enumerate(fingers):
            if not isinstance(f, dict) or set(f) != {"keyframes"}:
                raise _fail(source, f"device.finger[{i}]", "a table with only `keyframes`", f)
            frames = f["keyframes"]
            if not isinstance(frames, list) or not frames:
                raise _fail(source, f"device.finger[{i}].keyframes", "a non-empty list of [t, x, y, z, twist]", frames)
            for j, key in enumerate(frames):
                ok = isinstance(key, list) and len(key) == 5 and all(
                    isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in key)
                if not ok:
                    raise _fail(source, f"device.finger[{i}].keyframes[{j}]", "5 finite numbers [t, x, y, z, twist]", key)
                if j and key[0] <= frames[j - 1][0]:
                    raise _fail(source, f"device.finger[{i}].keyframes[{j}]", f"later than t = {frames[j - 1][0]} s", key[0])
            keyframes.append(frames)
        return cls(keyframes, **kwargs)
