"""The device protocol as compiled code: `read` and `send` a compiled servo loop calls itself.

A device that can run compiled (the simulated and replay devices) offers, besides the plain
`softproxy.device.Device` protocol, an optional method

    compiled_io(self) -> CompiledIO | None

giving its `read` and `send` as numba `cfunc`s over raw addresses, so a loop kernel can call
them for a whole block of ticks without returning to the interpreter. It returns None when it
cannot (under `NUMBA_DISABLE_JIT=1`, or a device written in Python); the loop then calls the
plain `read`/`send`. Devices keep one implementation: their Python `read`/`send` run the same
`@njit` core on the same state arrays as the cfuncs, so both paths give the same samples and
every counter a device shows is current after a compiled run.

The C-level protocol (all pointers are 64-bit addresses, `types.uintp`):

    read(state, t, samples, n) -> int64   fill the n SAMPLE rows at `samples` for loop time
                                          t (s); n must be the device's finger count
    send(state, finger, fx, fy, fz, tx, ty, tz) -> int64   render a force (N) and torque
                                          (N·m) on one finger, in the device frame

Both return 0 when all went well and an error code > 0 otherwise (`error_code`: a kind in
the low `KIND_BITS` bits, an argument such as a read number above them); never raise, never
write outside the n rows they were given. `CompiledIO.read_error(code)` is the one-line
DeviceError message for any code either returned. A code equal to `CompiledIO.stall_code`
means the device did not answer: the Python path sleeps `stall_s` before raising, and a
compiled loop waits `stall_s` itself (its tick counts the wait).

A loop kernel takes the cfuncs as arguments (numba types them as `FunctionType[READ]`, so the
kernel itself stays cacheable), passes `CompiledIO.address` (a `np.uintp`: the cfunc types
must match exactly) and the address of a SAMPLE array it owns (`array.ctypes.data` inside the
kernel), and keeps the `CompiledIO` alive while it runs (its `state` arrays are what the
addresses point into). Nothing else may call the device while a kernel holds it.

Device kernels are cached by numba beside their own module, and numba checks only that file:
`drop_stale_kernels` drops a device module's cached kernels when this file (whose helpers and
constants they compile in) has changed since they were built.
"""

from __future__ import annotations

import hashlib
import math
from pathlib import Path
from typing import Callable, NamedTuple

import numba
import numpy as np
from numba import carray, cfunc, types
from numba.extending import intrinsic

from softproxy.compiled.cache import renew
from softproxy.compiled.kernel import kernel


JIT = not numba.config.DISABLE_JIT
"""False under NUMBA_DISABLE_JIT=1: no cfunc can be built, `compiled_io()` returns None."""

SAMPLE_FIELDS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "twist", "buttons", "valid")
SAMPLE = np.dtype([(name, np.float64) for name in SAMPLE_FIELDS[:9]] + [("buttons", np.int64), ("valid", np.bool_)],
                  align=True)
"""One finger's reading, as `softproxy.device.DeviceSample`: t (s), x y z (m), qw qx qy qz, twist
(rad), buttons (bit field), valid. 88 bytes: the 9 floats, buttons at byte 72, valid at 80."""
assert SAMPLE.itemsize == 11 * 8 and SAMPLE.fields["buttons"][1] == 72 and SAMPLE.fields["valid"][1] == 80
SAMPLE_TYPE = numba.from_dtype(SAMPLE)
SAMPLES = types.Array(SAMPLE_TYPE, 1, "C")
"""numba type of a C-contiguous array of SAMPLE rows."""

READ = types.int64(types.uintp, types.float64, types.uintp, types.int64)
"""read(state address, t (s), samples address, n rows) -> 0 or an error code."""
SEND = types.int64(types.uintp, types.int64, types.float64, types.float64, types.float64,
                   types.float64, types.float64, types.float64)
"""send(state address, finger, fx, fy, fz (N), tx, ty, tz (N·m)) -> 0 or an error code."""

# --- error codes --------------------------------------------------------------------------------

KIND_BITS = 4
"""An error code is kind | argument << KIND_BITS; kinds are 1..15."""
MAX_ARGUMENT = (1 << (63 - KIND_BITS)) - 1
CLOSED = 1  # the device was closed
ROWS = 2  # the samples array does not have one row per finger
TIME = 3  # the read time is not a number
NULL = 4  # a null state or samples address
FINGER = 5  # send to a finger the device does not have
DEVICE_KINDS = 8
"""Kinds from DEVICE_KINDS up are the device's own (a stall, a dropped recorded read, ...)."""


@kernel(inline="always", cache=False)
def error_code(kind, argument):
    """The code of an error `kind` (1..15) with an `argument` >= 0 (clamped to MAX_ARGUMENT)."""
    if argument < 0:
        argument = 0
    elif argument > MAX_ARGUMENT:
        argument = MAX_ARGUMENT
    return kind | (argument << KIND_BITS)


def split_code(code: int) -> tuple[int, int]:
    """(kind, argument) of an error code."""
    code = int(code)
    return code & ((1 << KIND_BITS) - 1), code >> KIND_BITS


def common_error(code: int, device: str, fingers: int) -> str | None:
    """The message for the kinds every device shares (None for a device's own kinds)."""
    kind, _ = split_code(code)
    if kind == CLOSED:
        return f"{device} is closed"
    if kind == ROWS:
        return f"{device}: the samples array must have one row per finger ({fingers})"
    if kind == TIME:
        return f"{device}: read time must be a number, got nan"
    if kind == NULL:
        return f"{device}: a null state or samples address"
    if kind == FINGER:
        return f"{device}: no such finger (the device has {fingers}: 0 to {fingers - 1})"
    return None


# --- addresses -> arrays --------------------------------------------------------------------------

def _pointer_to(target):
    """An intrinsic turning an integer address into a `target *` (for `carray`)."""
    pointer = types.CPointer(target)

    @intrinsic
    def as_pointer(typingctx, address):
        if not isinstance(address, types.Integer):
            return None

        def codegen(context, builder, signature, args):
            return builder.inttoptr(args[0], context.get_value_type(pointer))

        return pointer(address), codegen

    return as_pointer


_f64 = _pointer_to(types.float64)
_i64 = _pointer_to(types.int64)
_u64 = _pointer_to(types.uint64)
_u8 = _pointer_to(types.uint8)
_sample = _pointer_to(SAMPLE_TYPE)


@kernel(inline="always", cache=False)
def f64_at(address, n):
    """The n float64 at `address` as an array (no copy)."""
    return carray(_f64(address), n)


@kernel(inline="always", cache=False)
def i64_at(address, n):
    """The n int64 at `address` as an array (no copy)."""
    return carray(_i64(address), n)


@kernel(inline="always", cache=False)
def u64_at(address, n):
    """The n uint64 at `address` as an array (no copy)."""
    return carray(_u64(address), n)


@kernel(inline="always", cache=False)
def u8_at(address, n):
    """The n uint8 at `address` as an array (no copy)."""
    return carray(_u8(address), n)


@kernel(inline="always", cache=False)
def samples_at(address, n):
    """The n SAMPLE rows at `address` as an array (no copy)."""
    return carray(_sample(address), n)


@kernel(inline="always", cache=False)
def sample_table_at(address, rows, fingers):
    """The rows × fingers SAMPLE table at `address` as a 2-D array (no copy)."""
    return carray(_sample(address), (rows, fingers))


STATE_ARRAYS = 4
"""The arrays a device's state block holds, as [address, size] pairs (`pack_state`): read and
send get the same block, each using the arrays it needs."""


@kernel(inline="always", cache=False)
def state_at(address):
    """The [address, size] pairs of the state block at `address` (2 × STATE_ARRAYS int64)."""
    return i64_at(address, 2 * STATE_ARRAYS)


@kernel(inline="always", cache=False)
def read_refused(state, samples, n, fingers_at):
    """A compiled read's first checks, before it touches its arrays: NULL for a null state or
    samples address, ROWS when the device's finger count (int64 `fingers_at` of the first
    array of its state block) is not n; 0 to go on."""
    if state == 0 or samples == 0:
        return NULL
    block = state_at(state)
    if n != i64_at(block[0], block[1])[fingers_at]:
        return ROWS
    return 0


def pack_state(*arrays: np.ndarray) -> np.ndarray:
    """The state block a cfunc gets the address of: [address, size] of each array, int64.
    The arrays must be C-contiguous and outlive every call (keep them with the block)."""
    block = np.empty(2 * len(arrays), dtype=np.int64)
    for i, a in enumerate(arrays):
        if not a.flags.c_contiguous:
            raise ValueError("pack_state: every state array must be C-contiguous")
        block[2 * i] = a.ctypes.data
        block[2 * i + 1] = a.size
    return block


# --- random numbers -----------------------------------------------------------------------------
# splitmix64 (Steele, Lea, Flood 2014): one uint64 of state per stream, period 2^64, passes
# BigCrush; small enough to live in a device's state array and run inside a cfunc.

_GAMMA = 0x9E3779B97F4A7C15
_MIX1 = 0xBF58476D1CE4E5B9
_MIX2 = 0x94D049BB133111EB
_MASK = (1 << 64) - 1
_UNIT = 1.0 / (1 << 53)
_TWO_PI = 2.0 * math.pi


def stream_seed(seed: int, stream: int) -> int:
    """A splitmix64 state (0 ≤ s < 2^64) for stream number `stream` of an integer `seed`
    (any size or sign): different streams of one seed are unrelated."""
    z = (seed * _GAMMA + (stream + 1) * 0xD1B54A32D192ED03) & _MASK
    z = ((z ^ (z >> 30)) * _MIX1) & _MASK
    z = ((z ^ (z >> 27)) * _MIX2) & _MASK
    return z ^ (z >> 31)


if JIT:
    _G, _M1, _M2 = np.uint64(_GAMMA), np.uint64(_MIX1), np.uint64(_MIX2)
    _S11, _S27, _S30, _S31 = np.uint64(11), np.uint64(27), np.uint64(30), np.uint64(31)

    @kernel(inline="always", cache=False)
    def next_u64(state, k):
        """Advance stream `state[k]` (uint64 array) and return its next 64 random bits."""
        z = state[k] + _G
        state[k] = z
        z = (z ^ (z >> _S30)) * _M1
        z = (z ^ (z >> _S27)) * _M2
        return z ^ (z >> _S31)

    @kernel(inline="always", cache=False)
    def uniform(state, k):
        """The next number of stream `state[k]`, uniform in [0, 1) with 53 random bits."""
        return np.float64(next_u64(state, k) >> _S11) * _UNIT
else:  # interpreted: the same numbers through Python ints (numpy's uint64 scalars warn on wrap-around)
    def next_u64(state, k):
        """Advance stream `state[k]` (uint64 array) and return its next 64 random bits."""
        z = (int(state[k]) + _GAMMA) & _MASK
        state[k] = z
        z = ((z ^ (z >> 30)) * _MIX1) & _MASK
        z = ((z ^ (z >> 27)) * _MIX2) & _MASK
        return z ^ (z >> 31)

    def uniform(state, k):
        """The next number of stream `state[k]`, uniform in [0, 1) with 53 random bits."""
        return float(next_u64(state, k) >> 11) * _UNIT


@kernel(inline="always", cache=False)
def gauss_pair(state, k):
    """Two independent standard normal numbers from stream `state[k]` (Box–Muller: two draws)."""
    angle = _TWO_PI * uniform(state, k)
    radius = math.sqrt(-2.0 * math.log(1.0 - uniform(state, k)))  # 1 - u in (0, 1]: log is finite
    return radius * math.cos(angle), radius * math.sin(angle)  # libm's, compiled or not


# --- the Python side ----------------------------------------------------------------------------

class CompiledIO(NamedTuple):
    """A device's read and send as cfuncs, and what a compiled loop needs to call them.

    `read`, `send`: numba cfuncs of signatures READ and SEND. `address`: the state address to
    pass them (np.uintp). `fingers`: the rows a samples array must have. `state`: the arrays
    the address points into; keep this object alive while a kernel may call the cfuncs.
    `read_error(code)`: the one-line message for a code read or send returned.
    `stall_code`: the code meaning "no answer", after which the caller waits `stall_s` (s);
    0 when the device never stalls. `limits`: a float64 array [max_force (N), max_torque
    (N·m)] the device keeps current, which a compiled loop reads every tick (a device that
    derates mid-run is obeyed the next tick); None when the limits are constants of the
    device's class.
    """

    read: object
    send: object
    address: np.uintp
    fingers: int
    state: tuple
    read_error: Callable[[int], str]
    stall_code: int = 0
    stall_s: float = 0.0
    limits: np.ndarray | None = None


def build_cfuncs(read_c, send_c) -> tuple:
    """(read, send): a device's `read_c` and `send_c` compiled as cfuncs of signatures READ and
    SEND (or loaded from numba's cache, beside the device's module)."""
    return (cfunc(READ, cache=True, error_model="numpy")(read_c),
            cfunc(SEND, cache=True, error_model="numpy")(send_c))


def device_io(cfuncs: tuple, arrays, fingers: int, read_error, stall_code: int = 0,
              stall_s: float = 0.0, limits: np.ndarray | None = None) -> CompiledIO:
    """A device's CompiledIO: its (read, send) cfuncs over the state block of its first
    STATE_ARRAYS `arrays`, made here so it always holds these arrays' addresses; `limits`
    (float64, [max_force, max_torque], a view of its state) when they may change mid-run."""
    state = tuple(arrays[:STATE_ARRAYS])
    block = pack_state(*state)
    if limits is not None and (limits.dtype != np.float64 or limits.shape != (2,)):
        raise ValueError("device_io: limits must be a float64 array [max_force, max_torque]")
    return CompiledIO(cfuncs[0], cfuncs[1], np.uintp(block.ctypes.data), fingers, (block, *state), read_error,
                      stall_code, stall_s, limits)


class SampleBuffer:
    """The SAMPLE rows a device's Python `read` runs its kernel into, and their copy into the
    `DeviceSample` objects of the plain protocol (two `tolist` calls: the cheap way out of numpy)."""

    def __init__(self, fingers: int, array: np.ndarray | None = None) -> None:
        self.array = np.zeros(fingers, dtype=SAMPLE) if array is None else array
        self._floats = self.array.view(np.float64).reshape(fingers, 11)  # t .. twist, then 2 slots
        self._ints = self.array.view(np.int64).reshape(fingers, 11)[:, 9:]  # buttons; valid and padding

    def __reduce__(self):  # a copy's views are of the copy's array
        return SampleBuffer, (len(self.array), self.array)

    def copy_into(self, samples) -> None:
        """Copy every row into samples[i] (DeviceSample), as Python floats, int and bool."""
        rows, tails = self._floats.tolist(), self._ints.tolist()
        for i in range(len(rows)):
            s = samples[i]
            s.t, s.x, s.y, s.z, s.qw, s.qx, s.qy, s.qz, s.twist, _, _ = rows[i]
            s.buttons, valid = tails[i]
            s.valid = (valid & 255) != 0  # the bool's byte; the 7 padding bytes above it are not read


def drop_stale_kernels(probe) -> bool:
    """Drop the cached kernels of the module that defines `probe` (an `@njit(cache=True)`
    function of it) if they were built from another version of this file; True if so.
    Call it at the module's import, before any of its kernels is compiled or loaded."""
    cache = getattr(probe, "_cache", None)
    if not JIT or cache is None:
        return False
    module = Path(probe.py_func.__code__.co_filename).stem
    return renew(Path(cache.cache_path), f"{module}.device_kernel.stamp",
                 hashlib.sha256(Path(__file__).read_bytes()).hexdigest(), f"{module}.*.nb[ic]")
