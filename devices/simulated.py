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

One implementation for both servo loops: the whole device lives in a few numpy arrays (script,
settings, counters, the two random streams) and `read`/`send` are `@njit` kernels over them.
The Python `read`/`send` call those kernels; `compiled_io()` hands a compiled loop cfuncs that
turn addresses back into the same arrays and call the same kernels
(`softproxy.device_kernel`). Counters and last wrenches are properties over the arrays, so
they are current whichever loop ran. The random streams are splitmix64 (Gaussian noise by
Box–Muller), deterministic per seed. `read` is the servo's hot path: about 1.2 µs for one
finger and 1.5 µs for two, noise and faults included (half of it the kernel call, the rest the
copy into `DeviceSample` objects).
"""

from __future__ import annotations

import functools
import math
import time
import warnings

import numpy as np
from numba import njit, types

from softproxy import device_kernel as dk
from softproxy.compiled.kernel import kernel
from softproxy.device import DeviceError
from softproxy.input_error import PLAUSIBLE_TWIST_RAD, implausible

from . import device_config as config
from .kernel_device import I_CLOSED, KernelDevice

FAULT_KINDS = ("nan", "drop", "spike", "stall")
SPIKE_M = 0.5
STALL_S = 0.005
STALL = dk.DEVICE_KINDS  # the error kind, and code, of a stalled read
NAME = "simulated device"

# The state arrays. ints (int64): flags, counters, and per finger its keyframe rows in `track`.
I_SENDS, I_NAN_SENDS = 1, 2  # after I_CLOSED (0)
I_INJECTED = 3  # one counter per fault kind, in FAULT_KINDS order
I_FINGERS = 7
I_TRACKS = 8  # per finger: first row in track, number of keyframes, segment the last read was in
# floats (float64): settings, the largest force sent, fault rates, then per finger the wrench rendered
F_NOISE_M, F_NOISE_RAD, F_LATENCY, F_QUANTUM_M, F_QUANTUM_RAD, F_MAX_FORCE, F_MAX_TORQUE, F_MAX_SENT = range(8)
F_RATES = 8  # one rate per fault kind, in FAULT_KINDS order (0: off)
F_WRENCH = 12  # per finger fx fy fz tx ty tz: what the motor renders (N, N·m)
# rng (uint64): the noise stream and the fault stream
R_NOISE, R_FAULTS = 0, 1
# track (float64, one row per keyframe): its time and pose, then the segment to the next keyframe
# (duration and change of pose; zero on a finger's last keyframe), so a read is a few multiply-adds.
K_T, K_X, K_Y, K_Z, K_W, K_SPAN, K_DX, K_DY, K_DZ, K_DW = range(10)
TRACK_COLUMNS = 10
_FAULT_NAN, _FAULT_DROP, _FAULT_SPIKE = 0, 1, 2


def _is_keyframe(key) -> bool:
    return isinstance(key, (list, tuple)) and len(key) == 5 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in key)


def _fail(source: str, field: str, expected: str, got) -> ValueError:
    return ValueError(f"{source}: {field} must be {expected}, got {got!r}")


# --- kernels ------------------------------------------------------------------------------------

@kernel(entry=True)
def _probe():
    """A cached function of this module: where numba keeps its kernels."""
    return 0


dk.drop_stale_kernels(_probe)  # before the kernels below are compiled or loaded


@kernel(cache=False)
def _scripted(ints, track, finger, ts):
    """(x, y, z, twist) of `finger` as scripted at time ts (s): minimum-jerk between keyframes,
    held outside them. The segment of the last call is tried first (reads move forward)."""
    base = I_TRACKS + 3 * finger
    first = ints[base]
    last = first + ints[base + 1] - 1
    if ts <= track[first, K_T]:
        return track[first, K_X], track[first, K_Y], track[first, K_Z], track[first, K_W]
    if ts >= track[last, K_T]:
        return track[last, K_X], track[last, K_Y], track[last, K_Z], track[last, K_W]
    j = first + ints[base + 2]
    if not (track[j, K_T] <= ts and ts < track[j + 1, K_T]):  # moved to another segment (or back in time)
        lo, hi = first, last  # times[lo] <= ts < times[hi]
        while hi - lo > 1:
            mid = (lo + hi) // 2
            if track[mid, K_T] <= ts:
                lo = mid
            else:
                hi = mid
        j = lo
        ints[base + 2] = j - first
    u = (ts - track[j, K_T]) / track[j, K_SPAN]
    s = u * u * u * (10.0 + u * (6.0 * u - 15.0))  # minimum jerk: s' = s'' = 0 at both keyframes
    return (track[j, K_X] + s * track[j, K_DX], track[j, K_Y] + s * track[j, K_DY],
            track[j, K_Z] + s * track[j, K_DZ], track[j, K_W] + s * track[j, K_DW])


_INTS, _FLOATS = types.int64[::1], types.float64[::1]


@njit(types.UniTuple(types.float64, 4)(_INTS, types.float64[:, ::1], types.int64, types.float64),
      cache=True, error_model="numpy")
def _pose(ints, track, finger, ts):
    return _scripted(ints, track, finger, ts)


@njit(types.int64(types.float64, _INTS, types.uint64[::1], _FLOATS, types.float64[:, ::1], dk.SAMPLES),
      cache=True, error_model="numpy")
def _read(t, ints, rng, floats, track, samples):
    """Fill samples[i] with finger i's pose scripted at t - latency, plus noise, quantisation and
    injected faults; 0, or an error code (closed, wrong rows, NaN t, a stall)."""
    if ints[I_CLOSED] != 0:
        return dk.CLOSED
    fingers = ints[I_FINGERS]
    if samples.shape[0] != fingers:
        return dk.ROWS
    if t != t:
        return dk.TIME
    ts = t - floats[F_LATENCY]
    nm, nr = floats[F_NOISE_M], floats[F_NOISE_RAD]
    qm, qr = floats[F_QUANTUM_M], floats[F_QUANTUM_RAD]
    noisy = nm > 0.0 or nr > 0.0
    for i in range(fingers):
        x, y, z, twist = _scripted(ints, track, i, ts)
        if noisy:
            # Two Box-Muller pairs, one for x, y and one for z, twist. All four are drawn even if
            # a std is zero, so the position noise does not depend on whether twist noise is on.
            gx, gy = dk.gauss_pair(rng, R_NOISE)
            gz, gw = dk.gauss_pair(rng, R_NOISE)
            x += nm * gx
            y += nm * gy
            z += nm * gz
            twist += nr * gw
        if qm > 0.0:  # the nearest encoder count (ties to even)
            x, y, z = np.rint(x / qm) * qm, np.rint(y / qm) * qm, np.rint(z / qm) * qm
        if qr > 0.0:
            twist = np.rint(twist / qr) * qr
        s = samples[i]
        s["t"] = t  # when the host got it; the pose itself is latency_s old
        s["x"] = x
        s["y"] = y
        s["z"] = z
        s["qw"] = 1.0
        s["qx"] = 0.0
        s["qy"] = 0.0
        s["qz"] = 0.0
        s["twist"] = twist
        s["buttons"] = 0
        s["valid"] = True
    for kind in range(len(FAULT_KINDS)):  # only the kinds switched on draw from the fault stream
        rate = floats[F_RATES + kind]
        if rate <= 0.0 or dk.uniform(rng, R_FAULTS) >= rate:
            continue
        ints[I_INJECTED + kind] += 1
        s = samples[int(dk.uniform(rng, R_FAULTS) * fingers)]
        if kind == _FAULT_NAN:
            s["x"] = np.nan
        elif kind == _FAULT_DROP:
            s["valid"] = False
        elif kind == _FAULT_SPIKE:
            s["z"] += SPIKE_M
        else:  # stall: no answer within the timeout; the caller waits STALL_S
            return STALL
    return 0


@kernel(cache=False)
def _saturate(a, b, c, limit):
    """(a, b, c) scaled, direction kept, to a norm of at most `limit`, and its norm before
    (computed without overflow for any finite components)."""
    m = max(abs(a), abs(b), abs(c))
    if m == 0.0:
        return a, b, c, 0.0
    p, q, r = a / m, b / m, c / m
    root = math.sqrt(p * p + q * q + r * r)
    size = m * root
    if size > limit:
        k = limit / root
        return p * k, q * k, r * k, size
    return a, b, c, size


@njit(types.int64(_INTS, _FLOATS, types.int64, types.float64, types.float64, types.float64,
                  types.float64, types.float64, types.float64), cache=True, error_model="numpy")
def _send(ints, floats, finger, fx, fy, fz, tx, ty, tz):
    """Render a force (N) and torque (N·m) on `finger`; the motor saturates at its limits."""
    if finger < 0 or finger >= ints[I_FINGERS]:
        return dk.FINGER
    ints[I_SENDS] += 1
    w = F_WRENCH + 6 * finger
    if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz)
            and math.isfinite(tx) and math.isfinite(ty) and math.isfinite(tz)):
        ints[I_NAN_SENDS] += 1  # the engine promises never to send this; the motor renders nothing
        for k in range(6):
            floats[w + k] = 0.0
        return 0
    fx, fy, fz, f = _saturate(fx, fy, fz, floats[F_MAX_FORCE])
    if f > floats[F_MAX_SENT]:
        floats[F_MAX_SENT] = f
    tx, ty, tz, _ = _saturate(tx, ty, tz, floats[F_MAX_TORQUE])
    floats[w], floats[w + 1], floats[w + 2] = fx, fy, fz
    floats[w + 3], floats[w + 4], floats[w + 5] = tx, ty, tz
    return 0


def _read_c(state, t, samples, n):
    """`_read` on the arrays whose [address, size] pairs `state` holds (device_kernel.READ)."""
    refused = dk.read_refused(state, samples, n, I_FINGERS)
    if refused:
        return refused
    block = dk.state_at(state)
    ints = dk.i64_at(block[0], block[1])
    track = dk.f64_at(block[6], block[7]).reshape((block[7] // TRACK_COLUMNS, TRACK_COLUMNS))
    return _read(t, ints, dk.u64_at(block[2], block[3]), dk.f64_at(block[4], block[5]), track,
                 dk.samples_at(samples, n))


def _send_c(state, finger, fx, fy, fz, tx, ty, tz):
    """`_send` on the arrays whose [address, size] pairs `state` holds (device_kernel.SEND)."""
    if state == 0:
        return dk.NULL
    block = dk.state_at(state)
    return _send(dk.i64_at(block[0], block[1]), dk.f64_at(block[4], block[5]), finger, fx, fy, fz, tx, ty, tz)


@functools.cache
def _cfuncs():
    """The read and send cfuncs, built (or loaded from numba's cache) on first use."""
    return dk.build_cfuncs(_read_c, _send_c)


# --- the device -----------------------------------------------------------------------------------

def _setting(name: str, value) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be a finite number >= 0, got {value!r}")
    return float(value)


def _limit(index: int, doc: str) -> property:
    """A motor limit (N or N·m) kept in the state, so the kernels see a change."""
    def get(self) -> float:
        return float(self._floats[index])

    def set_(self, value) -> None:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise TypeError(f"{NAME}: a motor limit must be a number, got {value!r}")
        self._floats[index] = value

    return property(get, set_, doc=doc)


def _setting_property(index: int, doc: str) -> property:
    return property(lambda self: float(self._floats[index]), doc=doc)


def _warn_implausible(frames: list, path: str, source: str) -> None:
    """A UnitWarning for the first twist beyond PLAUSIBLE_TWIST_RAD of one finger's keyframes
    (a position in mm is warned of when a loop starts, for every device: `ServoLoop.start`)."""
    turn = next(((j, key[4]) for j, key in enumerate(frames) if abs(key[4]) > PLAUSIBLE_TWIST_RAD), None)
    if turn is not None:
        warnings.warn(implausible(f"{path}[{turn[0]}] twist", turn[1], "rad", "in degrees? the twist is in rad "
                                  "(beyond a full turn)", source=source), stacklevel=3)


class SimulatedDevice(KernelDevice):
    """A scripted multi-finger device implementing the `softproxy.device.Device` protocol: `read`
    fills samples[i] with finger i's pose as scripted at t - latency_s, plus sensor effects."""

    _read_kernel = staticmethod(_read)
    _cfuncs = staticmethod(_cfuncs)
    compiled_io = KernelDevice.compiled_io  # declared beside send and the limits it belongs with (servo._compiled_io)

    def __init__(self, keyframes, *, noise_m: float = 0.0, noise_rad: float = 0.0, latency_s: float = 0.0,
                 quantum_m: float = 0.0, quantum_rad: float = 0.0, max_force: float = 20.0,
                 max_torque: float = 0.5, seed: int = 0, faults: dict | None = None,
                 max_stiffness: float | None = None, max_damping: float | None = None) -> None:
        settings = [_setting(name, value) for name, value in (
            ("noise_m", noise_m), ("noise_rad", noise_rad), ("latency_s", latency_s), ("quantum_m", quantum_m),
            ("quantum_rad", quantum_rad), ("max_force", max_force), ("max_torque", max_torque))]
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise ValueError(f"seed must be an integer, got {seed!r}")
        if not isinstance(keyframes, (list, tuple)) or not keyframes:
            raise ValueError(f"keyframes must be a list with one list of keyframes per finger, got {keyframes!r}")
        rows = []
        for i, frames in enumerate(keyframes):
            if not isinstance(frames, (list, tuple)) or not frames:
                raise ValueError(f"keyframes[{i}] must be a non-empty list of (t, x, y, z, twist), got {frames!r}")
            for j, key in enumerate(frames):
                if not _is_keyframe(key):
                    raise ValueError(f"keyframes[{i}][{j}] must be 5 finite numbers (t, x, y, z, twist), got {key!r}")
                if j and key[0] <= frames[j - 1][0]:
                    raise ValueError(f"keyframes[{i}][{j}]: times must increase, {key[0]} after {frames[j - 1][0]}")
            rows.append([[float(v) for v in key] for key in frames])
        rates = [0.0] * len(FAULT_KINDS)
        for kind, rate in (faults or {}).items():
            if kind not in FAULT_KINDS:
                raise ValueError(f"faults: unknown fault {kind!r}; expected some of {', '.join(FAULT_KINDS)}")
            if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not 0.0 <= rate <= 1.0:
                raise ValueError(f"faults.{kind} must be a probability per read in [0, 1], got {rate!r}")
            rates[FAULT_KINDS.index(kind)] = float(rate)
        for name, value, low in (("max_stiffness", max_stiffness, 10.0), ("max_damping", max_damping, 0.0)):
            if value is not None and (isinstance(value, bool) or not isinstance(value, (int, float))
                                      or not (math.isfinite(value) and value >= low)):
                raise ValueError(f"{name} must be None (no limit) or a finite number >= {low:g}, got {value!r}")
        self.max_stiffness = None if max_stiffness is None else float(max_stiffness)
        """The stiffest coupling (N/m) a finger may ask of this device (`softproxy.stiffness_cap`); None: no limit."""
        self.max_damping = None if max_damping is None else float(max_damping)
        """The most coupling damping (N·s/m) a finger may ask of it; None: no limit."""
        self.fingers = len(keyframes)
        self.seed = seed
        self._duration = max(frames[-1][0] for frames in rows)

        self._ints = np.zeros(I_TRACKS + 3 * self.fingers, dtype=np.int64)
        self._ints[I_FINGERS] = self.fingers
        self._floats = np.zeros(F_WRENCH + 6 * self.fingers)
        self._floats[:F_MAX_SENT] = settings
        self._floats[F_RATES:F_RATES + len(FAULT_KINDS)] = rates
        self._rng = np.array([dk.stream_seed(seed, 0), dk.stream_seed(seed, 1)], dtype=np.uint64)
        self._track = np.zeros((sum(map(len, rows)), TRACK_COLUMNS))
        first = 0
        for i, frames in enumerate(rows):
            self._ints[I_TRACKS + 3 * i:I_TRACKS + 3 * i + 2] = first, len(frames)
            for j, (t, *pose) in enumerate(frames):
                row = self._track[first + j]
                row[K_T], row[K_X:K_W + 1] = t, pose
                if j + 1 < len(frames):
                    t1, *pose1 = frames[j + 1]
                    row[K_SPAN] = t1 - t
                    row[K_DX:K_DW + 1] = [b - a for a, b in zip(pose, pose1)]
            first += len(frames)
        self._buffer = dk.SampleBuffer(self.fingers)
        self._arrays = (self._ints, self._rng, self._floats, self._track, self._buffer.array)

    # settings, fixed at construction (the kernels read them from the state)
    noise_m = _setting_property(F_NOISE_M, "Standard deviation of the position noise (m).")
    noise_rad = _setting_property(F_NOISE_RAD, "Standard deviation of the twist noise (rad).")
    latency_s = _setting_property(F_LATENCY, "How old the pose a read returns is (s).")
    quantum_m = _setting_property(F_QUANTUM_M, "Encoder resolution of the position (m; 0: none).")
    quantum_rad = _setting_property(F_QUANTUM_RAD, "Encoder resolution of the twist (rad; 0: none).")
    max_force = _limit(F_MAX_FORCE, "The force the motor saturates at (N).")
    max_torque = _limit(F_MAX_TORQUE, "The torque the motor saturates at (N·m).")

    @property
    def faults(self) -> dict:
        """The fault rates switched on, {kind: probability per read} (a copy)."""
        rates = self._floats[F_RATES:F_RATES + len(FAULT_KINDS)].tolist()
        return {kind: rate for kind, rate in zip(FAULT_KINDS, rates) if rate > 0.0}

    @property
    def injected(self) -> dict:
        """How many faults of each kind were injected, {kind: count} (a copy)."""
        return dict(zip(FAULT_KINDS, self._ints[I_INJECTED:I_INJECTED + len(FAULT_KINDS)].tolist()))

    @property
    def sends(self) -> int:
        """Calls to send (with a finger the device has)."""
        return int(self._ints[I_SENDS])

    @property
    def nan_sends(self) -> int:
        """Sends with a component that was not finite (rendered as zero)."""
        return int(self._ints[I_NAN_SENDS])

    @property
    def max_force_sent(self) -> float:
        """Largest |F| sent (N), before the motor's saturation."""
        return float(self._floats[F_MAX_SENT])

    @property
    def last_force(self) -> list[tuple[float, float, float]]:
        """Per finger, the force the motor renders now (N)."""
        w = self._floats[F_WRENCH:].reshape(self.fingers, 6)
        return [tuple(f) for f in w[:, :3].tolist()]

    @property
    def last_torque(self) -> list[tuple[float, float, float]]:
        """Per finger, the torque the motor renders now (N·m)."""
        w = self._floats[F_WRENCH:].reshape(self.fingers, 6)
        return [tuple(m) for m in w[:, 3:].tolist()]

    @property
    def duration(self) -> float:
        """Time of the last keyframe over all fingers (s)."""
        return self._duration

    def pose(self, finger: int, t: float) -> tuple[float, float, float, float]:
        """Noise-free scripted (x, y, z, twist) of a finger at time t (s), before latency."""
        finger = range(self.fingers)[finger]  # IndexError for a finger the device does not have
        t = float(t)
        if math.isnan(t):
            raise ValueError(f"{NAME}: read time must be a number, got {t!r}")
        return _pose(self._ints, self._track, finger, t)

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        """Render a force (N) and torque (N·m); the motor saturates at max_force / max_torque."""
        if _send(self._ints, self._floats, finger, fx, fy, fz, tx, ty, tz):
            raise IndexError(self.read_error(dk.FINGER))

    def read_error(self, code: int) -> str:
        """The one-line message for an error code of read or send."""
        if dk.split_code(code)[0] == STALL:
            return f"{NAME}: no answer within {STALL_S * 1e3:g} ms"
        return dk.common_error(code, NAME, self.fingers) or f"{NAME}: error code {code}"

    def _raise(self, code: int) -> None:
        kind = dk.split_code(code)[0]
        if kind == STALL:
            time.sleep(STALL_S)
        if kind == dk.TIME:
            raise ValueError(self.read_error(code))
        raise DeviceError(self.read_error(code))

    def _compiled_io_extras(self) -> tuple:
        # a stall waits STALL_S; the motor limits are the state the send kernel saturates at,
        # read by the loop every tick
        return STALL, STALL_S, self._floats[F_MAX_FORCE:F_MAX_TORQUE + 1]

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>") -> "SimulatedDevice":
        """Build from a scene's [device] table (see scenes/*.toml; its fields are declared in
        `softproxy.schema.SimDeviceTable`); errors name the field."""
        if not isinstance(cfg, dict):
            raise _fail(source, "device", "a table", cfg)
        table = config.check_type(cfg, source, "sim")
        kwargs = {arg: getattr(table, key) for key, arg in (
            ("noise_m", "noise_m"), ("noise_rad", "noise_rad"), ("latency_s", "latency_s"), ("quantum_m", "quantum_m"),
            ("quantum_rad", "quantum_rad"), ("max_force_N", "max_force"), ("max_torque_Nm", "max_torque"),
            ("seed", "seed"), ("faults", "faults"), ("max_stiffness_N_per_m", "max_stiffness"),
            ("max_damping_Ns_per_m", "max_damping")) if key in cfg}
        keyframes = []
        for i, f in enumerate(table.finger):
            frames = [list(key) for key in f.keyframes]
            for j in range(1, len(frames)):
                if frames[j][0] <= frames[j - 1][0]:
                    raise _fail(source, f"device.finger[{i}].keyframes[{j}]", f"later than t = {frames[j - 1][0]} s",
                                frames[j][0])
            _warn_implausible(frames, f"device.finger[{i}].keyframes", source)
            keyframes.append(frames)
        return cls(keyframes, **kwargs)
