"""Simulated haptic device: scripted finger trajectories that make runs reproducible.

Each finger follows keyframes (t, x, y, z, twist) in s, m and rad, with minimum-jerk timing
between them (zero velocity and acceleration at every keyframe, like a hand moving from pose
to pose). Optional sensor effects: Gaussian noise, latency, encoder quantisation; and the
motor's force saturation on what is sent back. Deterministic for a given seed. `read` is the
servo's hot path: plain scalar Python, about 1.5 µs per finger (4-5 µs with noise and quantisation).

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
from math import cos, log, sin, sqrt

from softproxy.device import DeviceError, DeviceSample

_CONFIG_KEYS = {"type", "noise_m", "noise_rad", "latency_s", "quantum_m", "quantum_rad",
                "max_force_N", "max_torque_Nm", "seed", "finger", "faults"}
FAULT_KINDS = ("nan", "drop", "spike", "stall")
SPIKE_M = 0.5
STALL_S = 0.005
TWO_PI = 2.0 * math.pi


def _min_jerk(u: float) -> float:
    """Minimum-jerk timing 10u³ - 15u⁴ + 6u⁵: s(0) = 0, s(1) = 1, s' = s'' = 0 at both ends."""
    return u * u * u * (10.0 + u * (6.0 * u - 15.0))


def _is_keyframe(key) -> bool:
    return isinstance(key, (list, tuple)) and len(key) == 5 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in key)


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
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ValueError(f"seed must be an integer, got {seed!r}")
        if not isinstance(keyframes, (list, tuple)) or not keyframes:
            raise ValueError(f"keyframes must be a list with one list of keyframes per finger, got {keyframes!r}")
        self._times: list[list[float]] = []
        self._poses: list[list[tuple[float, float, float, float]]] = []
        # Per segment: (t0, duration, x0, y0, z0, twist0, dx, dy, dz, dtwist), so a read is one
        # tuple unpack and a few multiply-adds.
        self._segments: list[list[tuple[float, ...]]] = []
        for i, frames in enumerate(keyframes):
            if not isinstance(frames, (list, tuple)) or not frames:
                raise ValueError(f"keyframes[{i}] must be a non-empty list of (t, x, y, z, twist), got {frames!r}")
            times, poses = [], []
            for j, key in enumerate(frames):
                if not _is_keyframe(key):
                    raise ValueError(f"keyframes[{i}][{j}] must be 5 finite numbers (t, x, y, z, twist), got {key!r}")
                if times and key[0] <= times[-1]:
                    raise ValueError(f"keyframes[{i}][{j}]: times must increase, {key[0]} after {times[-1]}")
                times.append(float(key[0]))
                poses.append(tuple(float(v) for v in key[1:]))
            self._times.append(times)
            self._poses.append(poses)
            self._segments.append([
                (t0, t1 - t0, *a, b[0] - a[0], b[1] - a[1], b[2] - a[2], b[3] - a[3])
                for t0, t1, a, b in zip(times, times[1:], poses, poses[1:])
            ])
        self.fingers = len(keyframes)
        self.noise_m, self.noise_rad = float(noise_m), float(noise_rad)
        self.latency_s = float(latency_s)
        self.quantum_m, self.quantum_rad = float(quantum_m), float(quantum_rad)
        self.max_force, self.max_torque = float(max_force), float(max_torque)
        self.seed = seed
        self._rng = random.Random(seed)
        self._segment = [0] * self.fingers  # per finger, the segment the last read was in
        self._tracks = list(zip(range(self.fingers), self._times, self._poses, self._segments))
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
        """Noise-free scripted (x, y, z, twist) of a finger at time t (s), before latency."""
        times = self._times[finger]
        if t <= times[0]:
            return self._poses[finger][0]
        if t >= times[-1]:
            return self._poses[finger][-1]
        t0, span, x, y, z, w, dx, dy, dz, dw = self._segments[finger][self._find_segment(finger, t)]
        s = _min_jerk((t - t0) / span)
        return (x + s * dx, y + s * dy, z + s * dz, w + s * dw)

    def _find_segment(self, finger: int, t: float) -> int:
        """Index j of the segment with times[j] <= t < times[j + 1], for t strictly inside the script."""
        if not math.isfinite(t):  # NaN: no segment holds it (±inf never gets here)
            raise ValueError(f"simulated device: read time must be a number, got {t!r}")
        j = bisect.bisect_right(self._times[finger], t) - 1
        self._segment[finger] = j
        return j

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        """Fill samples[i] with finger i's pose as scripted at t - latency_s, plus sensor effects."""
        if self.closed:
            raise DeviceError("simulated device is closed")
        ts = t - self.latency_s
        nm, nr, qm, qr = self.noise_m, self.noise_rad, self.quantum_m, self.quantum_rad
        noisy = nm > 0.0 or nr > 0.0
        rnd = self._rng.random
        segment = self._segment
        for i, times, poses, segments in self._tracks:
            if ts <= times[0]:
                x, y, z, twist = poses[0]
            elif ts >= times[-1]:
                x, y, z, twist = poses[-1]
            else:
                j = segment[i]
                if not (times[j] <= ts < times[j + 1]):  # moved to another segment (or back in time)
                    j = self._find_segment(i, ts)
                t0, span, x, y, z, twist, dx, dy, dz, dw = segments[j]
                u = (ts - t0) / span
                s = u * u * u * (10.0 + u * (6.0 * u - 15.0))  # _min_jerk, inlined
                x += s * dx
                y += s * dy
                z += s * dz
                twist += s * dw
            if noisy:
                # Box-Muller (what random.gauss does, without its call overhead): one pair for x, y
                # and one for z, twist. All four are drawn even if a std is zero, so the position
                # noise does not depend on whether twist noise is on.
                angle = TWO_PI * rnd()
                radius = sqrt(-2.0 * log(1.0 - rnd()))
                x += nm * radius * cos(angle)
                y += nm * radius * sin(angle)
                angle = TWO_PI * rnd()
                radius = sqrt(-2.0 * log(1.0 - rnd()))
                z += nm * radius * cos(angle)
                twist += nr * radius * sin(angle)
            if qm > 0.0:
                x, y, z = round(x / qm) * qm, round(y / qm) * qm, round(z / qm) * qm
            if qr > 0.0:
                twist = round(twist / qr) * qr
            sample = samples[i]
            sample.t = t  # when the host got it; the pose itself is latency_s old
            sample.x = x
            sample.y = y
            sample.z = z
            sample.twist = twist
            sample.qw, sample.qx, sample.qy, sample.qz = 1.0, 0.0, 0.0, 0.0
            sample.buttons = 0
            sample.valid = True
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
        isfinite = math.isfinite
        if not (isfinite(fx) and isfinite(fy) and isfinite(fz) and isfinite(tx) and isfinite(ty) and isfinite(tz)):
            self.nan_sends += 1  # the engine promises never to send this; the motor renders nothing
            self.last_force[finger] = (0.0, 0.0, 0.0)
            self.last_torque[finger] = (0.0, 0.0, 0.0)
            return
        f = math.hypot(fx, fy, fz)
        if f > self.max_force_sent:
            self.max_force_sent = f
        if f > self.max_force:
            k = self.max_force / f
            fx, fy, fz = fx * k, fy * k, fz * k
        m = math.hypot(tx, ty, tz)
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
            if not isinstance(frames, (list, tuple)) or not frames:
                raise _fail(source, f"device.finger[{i}].keyframes", "a non-empty list of [t, x, y, z, twist]", frames)
            for j, key in enumerate(frames):
                if not _is_keyframe(key):
                    raise _fail(source, f"device.finger[{i}].keyframes[{j}]", "5 finite numbers [t, x, y, z, twist]", key)
                if j and key[0] <= frames[j - 1][0]:
                    raise _fail(source, f"device.finger[{i}].keyframes[{j}]", f"later than t = {frames[j - 1][0]} s", key[0])
            keyframes.append(frames)
        return cls(keyframes, **kwargs)
