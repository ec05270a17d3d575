"""Recording device samples, and the file format a recording is kept in.

`RecordingDevice` wraps any device: every `read` is passed through and its samples copied
into preallocated arrays (no file I/O in the servo tick); `save` writes them once the run
is over. `devices.replay.ReplayDevice` plays a file back as a device, read for read, so a
lockstep run replayed from a recording reproduces the recorded run exactly.

File format, version 1 (text, UTF-8):
    line 1: a JSON object {"format": "softproxy-recording", "version": 1, "fingers": N,
            "reads": R, "scene": ..., "rate_hz": ...}
    then R × N lines, one per finger per device read, in read order, space-separated:
            read finger t x y z qw qx qy qz twist buttons valid error
    Floats are written with `repr` (exact round trip, `nan`/`inf` allowed: a NaN the device
    sent is replayed as sent); buttons an integer; valid 0/1; error 1 when the device
    raised on that read (the replay raises too).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from softproxy.device import Device, DeviceError, DeviceSample

FORMAT = "softproxy-recording"
VERSION = 1
_FLOATS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "twist")
FIELDS = ("read", "finger", *_FLOATS, "buttons", "valid", "error")


class RecordingError(ValueError):
    """A recording file that cannot be replayed; the message names the file and the first bad record."""


class RecordingDevice:
    """A device wrapper that records every sample it reads (Device protocol)."""

    def __init__(self, device: Device, capacity_reads: int) -> None:
        self.device = device
        self.fingers = device.fingers
        self.max_force = device.max_force
        self.max_torque = device.max_torque
        self.values = np.zeros((capacity_reads, device.fingers, len(_FLOATS)))
        self.flags = np.zeros((capacity_reads, device.fingers, 3), dtype=np.int64)  # buttons, valid, error
        self.reads = 0

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        i = self.reads
        if i >= len(self.values):  # past the planned length: grow (outside the usual run)
            self.values = np.concatenate([self.values, np.zeros_like(self.values)])
            self.flags = np.concatenate([self.flags, np.zeros_like(self.flags)])
        self.reads = i + 1
        try:
            self.device.read(t, samples)
        except Exception:
            self.flags[i, :, 2] = 1
            self.values[i, :, 0] = t
            raise
        values, flags = self.values[i], self.flags[i]
        for f, s in enumerate(samples):
            values[f] = (s.t, s.x, s.y, s.z, s.qw, s.qx, s.qy, s.qz, s.twist)
            flags[f] = (s.buttons, 1 if s.valid else 0, 0)

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        self.device.send(finger, fx, fy, fz, tx, ty, tz)

    def close(self) -> None:
        self.device.close()

    def save(self, path: str | Path, **meta) -> None:
        """Write the recording (format version 1) with extra header fields `meta`."""
        header = {"format": FORMAT, "version": VERSION, "fingers": self.fingers, "reads": self.reads, **meta}
        with open(path, "w", encoding="utf-8") as out:
            out.write(json.dumps(header) + "\n")
            for i in range(self.reads):
                for f in range(self.fingers):
                    floats = " ".join(repr(float(v)) for v in self.values[i, f])
                    b, valid, error = (int(v) for v in self.flags[i, f])
                    out.write(f"{i} {f} {floats} {b} {valid} {error}\n")


def load_recording(path: str | Path) -> tuple[dict, np.ndarray, np.ndarray]:
    """Read and validate a recording: (header, values[reads, fingers, 9], flags[reads, fingers, 3])."""
    path = Path(path)
    try:
        lines = path.read_text(encoding="utf-8").splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise RecordingError(f"{path}: cannot read the recording: {exc}") from None
    if not lines:
        raise RecordingError(f"{path}: empty file, expected a {FORMAT} header")
    try:
        header = json.loads(lines[0])
    except json.JSONDecodeError:
        raise RecordingError(f"{path}: line 1 is not a JSON header") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        raise RecordingError(f"{path}: not a {FORMAT} file (header format {header.get('format') if isinstance(header, dict) else header!r})")
    if header.get("version") != VERSION:
        raise RecordingError(f"{path}: format version {header.get('version')!r}; this softproxy reads version {VERSION}")
    fingers, reads = header.get("fingers"), header.get("reads")
    if not (isinstance(fingers, int) and fingers > 0 and isinstance(reads, int) and reads >= 0):
        raise RecordingError(f"{path}: header needs integer fingers > 0 and reads >= 0, got {fingers!r}, {reads!r}")
    values = np.zeros((reads, fingers, len(_FLOATS)))
    flags = np.zeros((reads, fingers, 3), dtype=np.int64)
    body = lines[1:]
    for k in range(reads * fingers):
        i, f = divmod(k, fingers)
        where = f"{path}: record {k} (read {i}, finger {f}, line {k + 2})"
        if k >= len(body):
            raise RecordingError(f"{where}: missing, the file is truncated ({len(body)} of {reads * fingers} records)")
        parts = body[k].split()
        if len(parts) != len(FIELDS):
            raise RecordingError(f"{where}: expected {len(FIELDS)} fields ({' '.join(FIELDS)}), got {len(parts)}")
        try:
            ri, rf = int(parts[0]), int(parts[1])
            floats = [float(v) for v in parts[2:11]]
            b, valid, error = int(parts[11]), int(parts[12]), int(parts[13])
        except ValueError:
            raise RecordingError(f"{where}: a field is not a number") from None
        if (ri, rf) != (i, f):
            raise RecordingError(f"{where}: says read {ri}, finger {rf}: records out of order")
        if valid not in (0, 1) or error not in (0, 1):
            raise RecordingError(f"{where}: valid and error must be 0 or 1")
        values[i, f] = floats
        flags[i, f] = (b, valid, error)
    if len(body) > reads * fingers and any(line.strip() for line in body[reads * fingers:]):
        raise RecordingError(f"{path}: record {reads * fingers} (line {reads * fingers + 2}): more records than the header's {reads} reads")
    return header, values, flags


def replay_error(read: int) -> DeviceError:
    return DeviceError(f"the recorded device failed on read {read}")
