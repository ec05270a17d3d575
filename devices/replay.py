"""Replay a recorded run (`softproxy run --record FILE`) as a device: `--device replay:FILE`.

Read for read, the samples come back exactly as recorded — NaN, invalid samples and device
failures included — so a lockstep run replayed from its recording gives the same result.
Forces sent to it go nowhere. Past the end of the recording it holds the last sample.

A recording is checked whole before its first read (`softproxy.recording.load_recording`):
its checksums (version 3) and the reads it claims against the records it holds, so a
damaged or forged file is one RecordingError naming the record, never a replay of it.

An incomplete recording still replays: a read the recorder dropped (its writer fell
behind) raises DeviceError on that read, so the run renders zero force that tick and
counts a device error naming the read; a recording cut short by a kill replays up to its
last whole record (`truncated` says a partial one was dropped, `complete` that the end
record is missing).

One implementation for both servo loops: the records are copied once into a table of
`softproxy.device_kernel.SAMPLE` rows, and `read` is an `@njit` kernel over it and a few
counters. The Python `read` calls that kernel; `compiled_io()` hands a compiled loop cfuncs
that call it on the same arrays, so `reads` is current whichever loop ran.
"""

from __future__ import annotations

import dataclasses
import functools

import numpy as np
from numba import njit, types

from softproxy import device_kernel as dk
from softproxy.compiled.kernel import kernel
from softproxy.device import DeviceError
from softproxy.recording import dropped_error, load_recording, replay_error

from .kernel_device import I_CLOSED, KernelDevice

NAME = "replay device"
EMPTY = dk.DEVICE_KINDS  # the recording holds no samples
DROPPED = dk.DEVICE_KINDS + 1  # argument: the read the recorder dropped
FAILED = dk.DEVICE_KINDS + 2  # argument: the record of a read the recorded device failed on

# ints (int64): the state of the replay
I_READS, I_NEXT, I_RECORDS, I_RECORDED_READS, I_FINGERS = range(1, 6)  # after I_CLOSED (0)


@kernel(entry=True)
def _probe():
    """A cached function of this module: where numba keeps its kernels."""
    return 0


dk.drop_stale_kernels(_probe)  # before the kernels below are compiled or loaded


@njit(types.int64(types.float64, types.int64[::1], types.int64[::1], types.uint8[::1],
                  types.Array(dk.SAMPLE_TYPE, 2, "C"), dk.SAMPLES), cache=True, error_model="numpy")
def _read(t, ints, index, error, table, samples):
    """Copy the next recorded read into samples; 0, or an error code (closed, wrong rows, NaN t,
    an empty recording, a read the recorder dropped, a read the recorded device failed on)."""
    if ints[I_CLOSED] != 0:
        return dk.CLOSED
    fingers = ints[I_FINGERS]
    if samples.shape[0] != fingers:
        return dk.ROWS
    if t != t:
        return dk.TIME
    read = ints[I_READS]
    ints[I_READS] = read + 1
    records = ints[I_RECORDS]
    if records == 0:
        return EMPTY
    k = ints[I_NEXT]  # the first record not yet played
    if k < records:
        if index[k] != read:  # a later read is next: this one was dropped by the recorder
            return dk.error_code(DROPPED, read)
        ints[I_NEXT] = k + 1
    elif read < ints[I_RECORDED_READS]:  # dropped after the last record the file holds
        return dk.error_code(DROPPED, read)
    else:
        k = records - 1  # past the end: hold the last sample
    if error[k] != 0:
        return dk.error_code(FAILED, k)
    for f in range(fingers):
        samples[f] = table[k, f]
    return 0


@njit(types.int64(types.int64[::1], types.int64), cache=True, error_model="numpy")
def _send(ints, finger):
    """A replay renders nothing; only a finger it does not have is an error."""
    if finger < 0 or finger >= ints[I_FINGERS]:
        return dk.FINGER
    return 0


def _read_c(state, t, samples, n):
    """`_read` on the arrays whose [address, size] pairs `state` holds (device_kernel.READ)."""
    refused = dk.read_refused(state, samples, n, I_FINGERS)
    if refused:
        return refused
    block = dk.state_at(state)
    ints = dk.i64_at(block[0], block[1])
    table = dk.sample_table_at(block[6], ints[I_RECORDS], ints[I_FINGERS])
    return _read(t, ints, dk.i64_at(block[2], block[3]), dk.u8_at(block[4], block[5]), table,
                 dk.samples_at(samples, n))


def _send_c(state, finger, fx, fy, fz, tx, ty, tz):
    """`_send` on the arrays `state` points to (device_kernel.SEND)."""
    if state == 0:
        return dk.NULL
    block = dk.state_at(state)
    return _send(dk.i64_at(block[0], block[1]), finger)


@functools.cache
def _cfuncs():
    """The read and send cfuncs, built (or loaded from numba's cache) on first use."""
    return dk.build_cfuncs(_read_c, _send_c)


class ReplayDevice(KernelDevice):
    """A device playing back a softproxy recording (format in `softproxy.recording`)."""

    _read_kernel = staticmethod(_read)
    _cfuncs = staticmethod(_cfuncs)
    compiled_io = KernelDevice.compiled_io  # declared beside send and the limits it belongs with (servo._compiled_io)

    max_force = 1e6  # a replay renders nothing: the largest limit a device may declare (N, N·m),
    max_torque = 1e6  # so nothing the engine computes is clamped

    def __init__(self, path: str) -> None:
        self.path = path
        recording = load_recording(path)
        self.header = recording.header
        self.fingers = recording.fingers
        self.recovered = recording.recovered  # read records the file held
        self.dropped = recording.dropped  # reads the recorder did not keep
        self.truncated = recording.truncated  # a partial last record was dropped
        self.complete = recording.complete  # the recorder closed the file (end record present)
        # The records as one table of SAMPLE rows; the recording's arrays become views of it, so
        # the file's own buffer is freed and the records are held once.
        n, fingers = recording.recovered, self.fingers
        table = np.zeros((n, fingers), dtype=dk.SAMPLE)
        values = table.view(np.float64).reshape(n, fingers, 11)[:, :, :9]
        values[...] = recording.values
        table["buttons"] = recording.buttons
        table["valid"] = recording.valid != 0
        self._index = np.ascontiguousarray(recording.index, dtype=np.int64)  # which read each record holds
        self._failed = np.ascontiguousarray(recording.error, dtype=bool).view(np.uint8)  # the device raised
        self.recording = dataclasses.replace(recording, values=values, buttons=table["buttons"],
                                             valid=table["valid"].view(np.uint8), error=self._failed.view(bool),
                                             index=self._index)
        self._ints = np.zeros(6, dtype=np.int64)
        self._ints[I_RECORDS], self._ints[I_RECORDED_READS], self._ints[I_FINGERS] = n, recording.reads, fingers
        self._buffer = dk.SampleBuffer(fingers)
        self._arrays = (self._ints, self._index, self._failed, table, self._buffer.array)

    @property
    def reads(self) -> int:
        """Reads made so far (each one plays the recorded read of that number)."""
        return int(self._ints[I_READS])

    @classmethod
    def from_argument(cls, argument: str, scene=None) -> "ReplayDevice":
        """`--device replay:FILE`: the recording's path."""
        return cls(argument)

    @classmethod
    def from_config(cls, cfg: dict, *, source: str = "<config>") -> "ReplayDevice":
        """A scene's [device] table with `type = "replay"` and `path = "..."`."""
        path = cfg.get("path") if isinstance(cfg, dict) else None
        if not isinstance(path, str):
            raise ValueError(f"{source}: device.path must name the recording file, got {path!r}")
        return cls(path)

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        if _send(self._ints, finger):
            raise IndexError(self.read_error(dk.FINGER))

    def _raise(self, code: int) -> None:
        raise self._error_of(code)

    def _error_of(self, code: int) -> DeviceError:
        kind, argument = dk.split_code(code)
        if kind == EMPTY:
            return DeviceError(f"{self.path}: the recording holds no samples")
        if kind == DROPPED:
            return dropped_error(self.path, argument)
        if kind == FAILED and argument < len(self._index):
            return replay_error(int(self._index[argument]))
        return DeviceError(dk.common_error(code, NAME, self.fingers) or f"{NAME}: error code {code}")

    def read_error(self, code: int) -> str:
        """The one-line message for an error code of read or send."""
        return str(self._error_of(code))
