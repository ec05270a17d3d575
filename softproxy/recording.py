"""Recording device samples as a run goes, and reading a recording back without trusting it.

`RecordingDevice` wraps any device. Each `read` is passed through and its samples packed
into a preallocated ring of fixed-size records (no file I/O, no allocation in the servo
tick); a daemon writer thread appends what the ring holds to the file and flushes it to
the operating system every `FLUSH_INTERVAL_S` (50 ms), so a run killed by any signal,
SIGKILL included, leaves a file that replays up to its last flush. The writer holds the GIL
only to slice the ring (microseconds every 50 ms); the writes themselves release it. The ring is bounded (about
`buffer_s` of reads, at most `MAX_BUFFER_BYTES`) whatever the run's length: if the writer
falls behind and the ring is full, the tick does not wait; it drops the read and counts it,
and the file shows the gap (below). `close()` (or `finish()`, or leaving a `with` block, or
the interpreter exiting) drains the ring, writes the end record and closes the file.

`load_recording` reads version 3 and the older versions 2 (binary, no checksums) and 1
(text): the header's `version` says which, so old recordings keep replaying; only version 3
can prove it is intact. It refuses anything that is not a regular file (a FIFO, /dev/zero, a
directory) before reading, refuses files over `MAX_FILE_BYTES` (2 GiB: about 3 hours of a
two-finger device at 1 kHz; the writer stops there and counts the rest as dropped) and
headers claiming more than `MAX_FINGERS` fingers, never sizes an array from a header's claim,
and names the file and the first bad record of a malformed body. The reads a recording
claims to span (its end record's count, or its last read index + 1) are checked against
the records the file holds, before anything replays them: at most `MAX_READS_PER_RECORD`
reads per record (a recorder whose writer fell so far behind that it kept under 1 read in
16 made a recording not worth replaying), and at most `MAX_CLAIMED_S` (24 h, the longest run
a scene or `--duration` asks for) of reads at the header's rate. So a forged end record
claiming 2^40 reads is one line, not decades of replay. `softproxy.devices.replay.ReplayDevice`
plays a recording back, read for read, so a lockstep run replayed from its recording
reproduces the recorded run exactly.

Checksums (version 3). The header line ends in `"crc32": "XXXXXXXX"}`: the CRC-32 (zlib) of
the line as it would read without that member (`{...}`); each record ends in 8 bytes, the
CRC-32 of the record's bytes before them (u32) and 4 zero bytes. Any flipped bit of a
version-3 file is found: in the header (one line naming the header) or in record k (one
line naming the record and its byte range), checked before the record's contents are
trusted. The writer thread computes the checksums as it drains the ring, so the servo
tick does no more work than before. Checking costs about 1 µs per record on load.

File format, version 3:
    line 1: a JSON object ending in "\\n" (at most 64 KiB): {"format": "softproxy-recording",
            "version": 3, "fingers": N, "record_bytes": 24 + 88 N, "byte_order": "little",
            "scene": ..., "rate_hz": ..., "crc32": "..."}. It does not say how many reads
            follow: the body does.
    then fixed-size little-endian records of 24 + 88 N bytes, one per device read:
            kind u32 (1 = a read, 2 = the end record), error u32 (1: the device raised on
            that read; the replay raises too), read i64 (the read's 0-based index), then per
            finger t x y z qw qx qy qz twist (9 float64, NaN as sent), buttons i64, valid u8,
            7 zero bytes; then crc32 u32 of the bytes before it, 4 zero bytes.
    Read indices increase; a gap is reads the recorder dropped (the writer fell behind or
    the file reached MAX_FILE_BYTES). The end record, written on close, has read = the
    number of reads the run made and dropped (i64) in the 8 bytes after its header; it is
    missing when the process was killed. A partial last record (killed mid-write) is
    dropped and reported (`Recording.truncated`).
File format, version 2 (still read): as version 3 without the header's crc32 and without
    the records' last 8 bytes (records of 16 + 88 N bytes).
File format, version 1 (text, written at the end of a run; still read):
    line 1: {"format": "softproxy-recording", "version": 1, "fingers": N, "reads": R, ...}
    then R × N lines "read finger t x y z qw qx qy qz twist buttons valid error" (floats
    as `repr`).
"""

from __future__ import annotations

import io
import json
import math
import os
import re
import stat
import struct
import threading
import weakref
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from softproxy.device import Device, DeviceError, DeviceSample

FORMAT = "softproxy-recording"
VERSION = 3
VERSIONS_READ = (1, 2, 3)
MAX_FINGERS = 16
MAX_FILE_BYTES = 2 << 30  # 2 GiB: what load_recording reads, and where the writer stops
MAX_HEADER_BYTES = 64 << 10
MAX_BUFFER_BYTES = 64 << 20  # the ring's ceiling, whatever the rate and finger count
FLUSH_INTERVAL_S = 0.05  # the writer drains and flushes at least this often (wall time)
FINISH_TIMEOUT_S = 5.0  # how long close() waits for a writer stuck in a write
MAX_READS_PER_RECORD = 16
"""The most reads a recording may claim to span per read record it holds (its gaps are reads
the recorder dropped; more than this and the claim, not the recording, is what would run)."""
MAX_CLAIMED_S = 86_400.0
"""The longest run (s) a recording may claim to span at its header's rate: 24 h, the longest
run a scene file or `softproxy run --duration` asks for (softproxy.schema.MAX_DURATION_S)."""
DEFAULT_RATE_HZ = 1000.0  # the rate assumed for a header without a usable rate_hz (Hz)

KIND_READ, KIND_END = 1, 2
_RECORD_HEAD = struct.Struct("<IIq")  # kind, error, read index
_FINGER = struct.Struct("<9dq?7x")  # t x y z qw qx qy qz twist, buttons, valid
_END_DROPPED = struct.Struct("<q")
_TRAILER = struct.Struct("<I4x")  # version 3: crc32 of the record's bytes before it, 4 zero bytes
_HEADER_CRC = re.compile(rb'^(.*), "crc32": "([0-9a-f]{8})"}$', re.DOTALL)  # the end of a version-3 header line
_FLOATS = ("t", "x", "y", "z", "qw", "qx", "qy", "qz", "twist")
FIELDS = ("read", "finger", *_FLOATS, "buttons", "valid", "error")  # a version-1 line
_MIN_V1_LINE_BYTES = 2 * len(FIELDS)  # one character per field and a separator after each
_RESERVED = ("format", "version", "fingers", "record_bytes", "byte_order", "reads", "crc32")


def record_bytes(fingers: int, version: int = VERSION) -> int:
    """Size of one binary record (bytes) for a device of `fingers` fingers (version 3, or 2)."""
    return _RECORD_HEAD.size + fingers * _FINGER.size + (_TRAILER.size if version >= 3 else 0)


def _record_dtype(fingers: int, version: int = VERSION) -> np.dtype:
    finger = np.dtype([("v", "<f8", (len(_FLOATS),)), ("buttons", "<i8"), ("valid", "u1"), ("pad", "V7")])
    fields = [("kind", "<u4"), ("error", "<u4"), ("read", "<i8"), ("f", finger, (fingers,))]
    if version >= 3:
        fields += [("crc", "<u4"), ("spare", "<u4")]
    dtype = np.dtype(fields)
    assert dtype.itemsize == record_bytes(fingers, version)
    return dtype


def header_line(header: dict) -> bytes:
    """A version-3 header line: the JSON object with its own CRC-32 as the last member, and "\\n"."""
    body = json.dumps(header)
    return f'{body[:-1]}, "crc32": "{zlib.crc32(body.encode("utf-8")):08x}"}}\n'.encode("utf-8")


def seal(buffer, start: int, count: int, size: int) -> None:
    """Write the checksum trailer of `count` version-3 records of `size` bytes from byte `start`."""
    view = memoryview(buffer)
    body = size - _TRAILER.size
    for base in range(start, start + count * size, size):
        _TRAILER.pack_into(buffer, base + body, zlib.crc32(view[base:base + body]))


def _checksums_bad(raw: np.ndarray, records: np.ndarray, size: int) -> np.ndarray:
    """A mask over version-3 records: the stored CRC-32 (or the zero bytes after it) is not the record's."""
    n = len(records)
    view = memoryview(raw)
    body = size - _TRAILER.size
    found = np.fromiter((zlib.crc32(view[k * size:k * size + body]) for k in range(n)), dtype=np.uint32, count=n)
    return (found != records["crc"]) | (records["spare"] != 0)


class RecordingError(ValueError):
    """A recording that cannot be written or replayed; the message names the file (and the first bad record)."""


# ---------------------------------------------------------------------------------------------
# writing


class _Writer:
    """The ring of records and the thread draining it to the file (knows nothing of the device,
    so a finaliser can finish the file without keeping the RecordingDevice alive)."""

    def __init__(self, path: str, file, fingers: int, capacity: int) -> None:
        self.path = path
        self.file = file
        self.record_bytes = record_bytes(fingers)
        self.capacity = capacity
        self.ring = bytearray(capacity * self.record_bytes)
        self.view = memoryview(self.ring)
        # [reads put in the ring (by the tick), reads taken out (by the writer), reads the tick
        # dropped because the ring was full]. One producer, one consumer: each index has one writer.
        self.counts = [0, 0, 0]
        self.discarded = 0  # reads taken out of the ring but not written (file full, or writing failed)
        self.written = 0  # read records in the file
        self.bytes = 0  # bytes in the file
        self.error = ""  # why writing stopped, if it did
        self.finished = False
        self._close_in_thread = False  # finish() was called from the writer thread itself
        self._stop = threading.Event()
        self.thread = threading.Thread(target=self._run, name=f"softproxy recorder {path}", daemon=True)

    def _run(self) -> None:
        while not self._stop.wait(FLUSH_INTERVAL_S):
            self.drain()
        if self._close_in_thread:
            self._close()

    def drain(self) -> None:
        """Write what the ring holds to the file and flush it to the OS (writer thread, or close)."""
        counts = self.counts
        head, tail = counts[0], counts[1]
        n = head - tail
        if n <= 0:
            return
        size = self.record_bytes
        keep = n
        if self.error:
            keep = 0
        elif self.bytes + (n + 1) * size > MAX_FILE_BYTES:  # +1: room for the end record
            keep = max(0, (MAX_FILE_BYTES - self.bytes) // size - 1)
        try:
            start = tail % self.capacity
            first = min(keep, self.capacity - start)
            seal(self.ring, start * size, first, size)  # here, not in the tick: the tick only packs
            seal(self.ring, 0, keep - first, size)
            if first:
                self.file.write(self.view[start * size:(start + first) * size])
            if keep > first:
                self.file.write(self.view[:(keep - first) * size])
            if keep:
                self.file.flush()
        except (OSError, ValueError) as exc:
            reason = getattr(exc, "strerror", None) or exc
            self.error = f"writing the recording failed after {self.written} reads: {reason}"
            keep = 0
        self.written += keep
        self.bytes += keep * size
        self.discarded += n - keep
        counts[1] = head  # the slots are free for the tick again

    def start(self, header: bytes) -> None:
        self.file.write(header)
        self.file.flush()
        self.bytes = len(header)
        self.thread.start()

    def finish(self) -> None:
        """Stop the thread, drain the ring, write the end record and close the file (idempotent, never raises)."""
        if self.finished:
            return
        self.finished = True
        if threading.current_thread() is self.thread:  # the collector ran the finaliser here, maybe mid-drain
            self._close_in_thread = True
            self._stop.set()
            return
        self._stop.set()
        if self.thread.is_alive():
            self.thread.join(FINISH_TIMEOUT_S)
            if self.thread.is_alive():  # stuck in a write (a hung disk): leave the file to it
                self.error = self.error or f"the writer did not finish within {FINISH_TIMEOUT_S:g} s"
                return
        self._close()

    def _close(self) -> None:
        """The last drain, the end record, and the file closed (by whichever thread finishes)."""
        self.drain()
        reads = self.counts[0] + self.counts[2]
        dropped = self.counts[2] + self.discarded
        try:
            if not self.error:
                end = bytearray(self.record_bytes)
                _RECORD_HEAD.pack_into(end, 0, KIND_END, 0, reads)
                _END_DROPPED.pack_into(end, _RECORD_HEAD.size, dropped)
                seal(end, 0, 1, self.record_bytes)
                self.file.write(end)
                self.bytes += len(end)
            self.file.close()
        except (OSError, ValueError) as exc:
            self.error = self.error or f"closing the recording failed: {getattr(exc, 'strerror', None) or exc}"


def _open_for_writing(path: str):
    """A buffered binary file at `path`, created or truncated; RecordingError if it cannot be
    (no directory, no permission, not a regular file: a FIFO would block the run)."""
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | os.O_NONBLOCK | os.O_NOCTTY, 0o644)
    except OSError as exc:
        raise RecordingError(f"{path}: cannot write the recording: {exc.strerror or exc}") from None
    if not stat.S_ISREG(os.fstat(fd).st_mode):
        os.close(fd)
        raise RecordingError(f"{path}: not a regular file; record to a file path")
    return os.fdopen(fd, "wb")


class RecordingDevice:
    """A device wrapper (Device protocol) streaming every sample it reads to a recording file.

    `RecordingDevice(device, path, scene=..., rate_hz=...)`: the keyword arguments go into
    the file's header (`rate_hz`, Hz, also sizes the ring to `buffer_s` seconds of reads).
    The file is created at once (RecordingError naming it if it cannot be). `close()`
    finishes the file and closes the wrapped device; `finish()` finishes the file only.
    After a run: `reads` made, `written` to the file, `dropped` (the writer fell behind),
    `error` (why writing stopped, "" if it did not).
    """

    __slots__ = ("device", "fingers", "max_force", "max_torque", "path", "reads", "_writer", "_ring",
                 "_counts", "_capacity", "_size", "_open", "_finaliser", "__weakref__")

    def __init__(self, device: Device, path: str | Path, *, buffer_s: float = 2.0, **meta) -> None:
        fingers = device.fingers
        path = str(path)
        if isinstance(fingers, bool) or not isinstance(fingers, int) or not 1 <= fingers <= MAX_FINGERS:
            raise RecordingError(f"{path}: cannot record a device of {fingers!r} fingers (1 to {MAX_FINGERS})")
        taken = [k for k in meta if k in _RESERVED]
        if taken:
            raise ValueError(f"recording header fields {taken} are the format's own")
        header = {"format": FORMAT, "version": VERSION, "fingers": fingers, "record_bytes": record_bytes(fingers),
                  "byte_order": "little", **meta}
        try:
            line = header_line(header)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"recording header: {exc}") from None
        rate = meta.get("rate_hz", 1000.0)
        rate = float(rate) if isinstance(rate, (int, float)) and math.isfinite(rate) and rate > 0 else 1000.0
        capacity = max(256, math.ceil(buffer_s * rate))
        capacity = min(capacity, max(16, MAX_BUFFER_BYTES // record_bytes(fingers)))
        self.device = device
        self.fingers = fingers
        self.max_force = device.max_force
        self.max_torque = device.max_torque
        self.path = path
        self.reads = 0
        writer = _Writer(path, _open_for_writing(path), fingers, capacity)
        try:
            writer.start(line)
        except OSError as exc:
            writer.file.close()
            raise RecordingError(f"{path}: cannot write the recording: {exc.strerror or exc}") from None
        self._writer = writer
        self._ring = writer.ring
        self._counts = writer.counts
        self._capacity = capacity
        self._size = writer.record_bytes
        self._open = True
        # Dropped without close(), or still open when the interpreter exits: finish the file then.
        self._finaliser = weakref.finalize(self, writer.finish)

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        i = self.reads
        self.reads = i + 1
        try:
            self.device.read(t, samples)
        except Exception:
            self._put(i, 1, samples)
            raise
        self._put(i, 0, samples)

    def _put(self, read: int, error: int, samples: list[DeviceSample]) -> None:
        """Pack one read into the ring's next free record; if none is free, count it dropped."""
        counts = self._counts
        head = counts[0]
        if head - counts[1] >= self._capacity or not self._open:
            if self._open:
                counts[2] += 1
            return
        if len(samples) != self.fingers:  # not what the protocol hands over: one sample per finger, no more
            samples = [*samples[:self.fingers], *(DeviceSample() for _ in range(self.fingers - len(samples)))]
        ring = self._ring
        base = (head % self._capacity) * self._size
        _RECORD_HEAD.pack_into(ring, base, KIND_READ, error, read)
        offset = base + _RECORD_HEAD.size
        try:
            for s in samples:
                _FINGER.pack_into(ring, offset, s.t, s.x, s.y, s.z, s.qw, s.qx, s.qy, s.qz, s.twist, s.buttons, s.valid)
                offset += _FINGER.size
        except (struct.error, TypeError, ValueError, OverflowError):  # a device filling samples with odd types
            offset = base + _RECORD_HEAD.size
            for s in samples:
                _FINGER.pack_into(ring, offset, *_coerced(s))
                offset += _FINGER.size
        counts[0] = head + 1  # published after the record is complete

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        self.device.send(finger, fx, fy, fz, tx, ty, tz)

    @property
    def written(self) -> int:
        """Reads in the file so far (after `finish`, all it will hold)."""
        return self._writer.written

    @property
    def dropped(self) -> int:
        """Reads not recorded: the ring was full (the writer fell behind) or the file reached its bound."""
        return self._counts[2] + self._writer.discarded

    @property
    def error(self) -> str:
        """Why writing stopped ("" if it did not): a full disk, a failed write, a writer that hung."""
        return self._writer.error

    def finish(self) -> None:
        """Drain the ring, write the end record and close the file; later reads are not recorded."""
        self._open = False
        self._finaliser()

    def close(self) -> None:
        """Finish the file, then close the wrapped device."""
        try:
            self.finish()
        finally:
            self.device.close()

    def __enter__(self) -> "RecordingDevice":
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _coerced(s: DeviceSample) -> tuple:
    """A sample's fields as the record's types: a float that is not one is NaN, buttons outside int64 are 0."""
    floats = []
    for name in _FLOATS:
        try:
            floats.append(float(getattr(s, name)))
        except (TypeError, ValueError, OverflowError):
            floats.append(math.nan)
    try:
        buttons = int(s.buttons)
        if not -(1 << 63) <= buttons < (1 << 63):
            buttons = 0
    except (TypeError, ValueError, OverflowError):
        buttons = 0
    try:
        valid = bool(s.valid)
    except Exception:
        valid = False
    return (*floats, buttons, valid)


# ---------------------------------------------------------------------------------------------
# reading


@dataclass
class Recording:
    """A recording as read: one row per read record, in read order.

    `values[k, f]` t x y z qw qx qy qz twist; `buttons[k, f]`; `valid[k, f]` (0/1);
    `error[k]` the device raised on that read; `index[k]` which read of the run row k is.
    `reads`: reads the recorded run made (from the end record; without it, the last index
    + 1); `dropped`: reads in that span with no record; `complete`: the end record is there
    (the recorder was closed); `truncated`: a partial last record was dropped.
    """

    path: str
    header: dict
    values: np.ndarray
    buttons: np.ndarray
    valid: np.ndarray
    error: np.ndarray
    index: np.ndarray
    reads: int
    dropped: int
    complete: bool
    truncated: bool

    @property
    def fingers(self) -> int:
        return int(self.header["fingers"])

    @property
    def recovered(self) -> int:
        """Read records recovered from the file."""
        return len(self.index)


def _open_recording(path: str) -> tuple[int, os.stat_result]:
    """A recording file's descriptor, opened for reading, and its stat; RecordingError naming
    the file (the descriptor closed) when it cannot be opened or is no regular file. Opened
    non-blocking (opening a FIFO must not wait for a writer) and checked before anything is
    read from it."""
    try:
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK | os.O_NOCTTY)
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None
    try:
        info = os.fstat(fd)
        if stat.S_ISDIR(info.st_mode):
            raise RecordingError(f"{path}: is a directory, not a recording file")
        if not stat.S_ISREG(info.st_mode):
            raise RecordingError(f"{path}: not a regular file (a FIFO, socket or device); replay a recording file")
    except OSError as exc:
        os.close(fd)
        raise RecordingError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None
    except BaseException:
        os.close(fd)
        raise
    return fd, info


def load_recording(path: str | Path, max_bytes: int = MAX_FILE_BYTES) -> Recording:
    """Read and validate a recording (format versions 1 and 2); RecordingError naming the file
    (and the first bad record) for anything else. Reads at most `max_bytes`."""
    path = str(path)
    fd, info = _open_recording(path)
    try:
        size = info.st_size
        if size > max_bytes:
            raise RecordingError(f"{path}: {size} bytes, over the {max_bytes}-byte limit for a recording")
        file = os.fdopen(fd, "rb", buffering=0)
    except BaseException:
        os.close(fd)
        raise
    with file:
        try:
            start = _read_exactly(file, min(size, MAX_HEADER_BYTES))
        except OSError as exc:
            raise RecordingError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None
        if not start:
            raise RecordingError(f"{path}: empty file, expected a {FORMAT} header")
        header, header_bytes = _parse_header(path, start)
        try:
            if header["version"] == 1:
                return _read_v1(path, header, file, header_bytes, size)
            return _read_v2(path, header, file, header_bytes, size)
        except OSError as exc:
            raise RecordingError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None


def read_header(path: str | Path) -> dict:
    """A recording's header line, checked (format, version, fingers) without reading its body;
    RecordingError naming the file otherwise."""
    path = str(path)
    fd, _ = _open_recording(path)
    try:
        start = os.read(fd, MAX_HEADER_BYTES)
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read the recording: {exc.strerror or exc}") from None
    finally:
        os.close(fd)
    if not start:
        raise RecordingError(f"{path}: empty file, not a recording")
    return _parse_header(path, start)[0]


def _read_exactly(file, n: int) -> bytes:
    """Up to `n` bytes (fewer only at the end of the file)."""
    parts, got = [], 0
    while got < n:
        part = file.read(n - got)
        if not part:
            break
        parts.append(part)
        got += len(part)
    return b"".join(parts)


def _parse_header(path: str, start: bytes) -> tuple[dict, int]:
    """The header dict (format, version, fingers checked) and the header line's length in bytes."""
    end = start.find(b"\n")
    if end < 0:
        raise RecordingError(f"{path}: line 1 is not a JSON header (no end of line in its first {len(start)} bytes)")
    try:
        header = json.loads(start[:end].decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError):
        raise RecordingError(f"{path}: line 1 is not a JSON header") from None
    if not isinstance(header, dict) or header.get("format") != FORMAT:
        got = header.get("format") if isinstance(header, dict) else header
        raise RecordingError(f"{path}: not a {FORMAT} file (header format {str(got)[:40]!r})")
    version = header.get("version")
    if isinstance(version, bool) or version not in VERSIONS_READ:
        raise RecordingError(f"{path}: header format version {str(version)[:40]}; this softproxy reads versions "
                             f"{', '.join(map(str, VERSIONS_READ))}")
    if version >= 3:
        sealed = _HEADER_CRC.match(start[:end])
        if sealed is None or int(sealed[2], 16) != zlib.crc32(sealed[1] + b"}"):
            raise RecordingError(f"{path}: line 1 (the header, bytes 0-{end}): checksum mismatch, the header is "
                                 f"corrupt")
    fingers = header.get("fingers")
    if isinstance(fingers, bool) or not isinstance(fingers, int) or not 1 <= fingers <= MAX_FINGERS:
        raise RecordingError(f"{path}: header fingers must be an integer from 1 to {MAX_FINGERS}, "
                             f"got {str(fingers)[:40]}")
    return header, end + 1


def _read_v2(path: str, header: dict, file, header_bytes: int, size: int) -> Recording:
    """Versions 2 and 3: fixed-size binary records (version 3 with a checksum each)."""
    fingers, version = header["fingers"], header["version"]
    size_one = record_bytes(fingers, version)
    if header.get("record_bytes") != size_one or header.get("byte_order") != "little":
        raise RecordingError(f"{path}: header record_bytes {str(header.get('record_bytes'))[:20]} and byte_order "
                             f"{str(header.get('byte_order'))[:20]} do not match {fingers} fingers' layout "
                             f"in version {version} ({size_one}, little)")
    whole = (size - header_bytes) // size_one  # sized from the file, never from a claim
    raw = np.empty(whole * size_one, dtype=np.uint8)
    file.seek(header_bytes)
    view, got = memoryview(raw), 0
    while got < len(raw):
        chunk = file.readinto(view[got:])
        if not chunk:
            break  # the file shrank since fstat
        got += chunk
    truncated = (size - header_bytes) % size_one != 0 or got < len(raw)
    records = raw[:got - got % size_one].view(_record_dtype(fingers, version))
    corrupt = _checksums_bad(raw, records, size_one) if version >= 3 else np.zeros(len(records), dtype=bool)
    kind, index = records["kind"], records["read"]
    complete = len(records) > 0 and kind[-1] == KIND_END
    body = records[:-1] if complete else records
    n = len(body)
    hits = np.flatnonzero(corrupt)
    if hits.size:  # before anything the record says is believed: a flipped bit could make it say anything
        k = int(hits[0])
        raise RecordingError(f"{path}: record {k} (bytes {header_bytes + k * size_one}-"
                             f"{header_bytes + (k + 1) * size_one - 1}): checksum mismatch, the record is corrupt")
    if complete and truncated:
        raise RecordingError(f"{path}: {size - header_bytes - n * size_one - size_one} bytes after the end record")
    ordered = np.empty(n, dtype=bool)
    ordered[:1] = True
    ordered[1:] = index[1:n] > index[:n - 1]
    checks = (  # each a mask over the read records; the first record any of them flags is named
        (kind[:n] != KIND_READ, "kind must be 1 (a read) or 2 (the end record, last)"),
        (body["error"] > 1, "error must be 0 or 1"),
        (body["f"]["valid"].max(axis=1, initial=0) > 1, "valid must be 0 or 1"),
        (index[:n] < 0, "read index is negative"),
        (~ordered, "read index does not increase: records out of order"),
    )
    first_bad, reason = n, ""
    for bad, why in checks:
        hits = np.flatnonzero(bad)
        if hits.size and hits[0] < first_bad:
            first_bad, reason = int(hits[0]), why
    if first_bad < n:
        k = first_bad
        raise RecordingError(f"{path}: record {k} (bytes {header_bytes + k * size_one}-"
                             f"{header_bytes + (k + 1) * size_one - 1}): {reason}")
    last = int(index[n - 1]) + 1 if n else 0  # the reads the records span
    reads, dropped = last, last - n
    if complete:
        reads = int(index[n])
        dropped = _END_DROPPED.unpack_from(raw, n * size_one + _RECORD_HEAD.size)[0]
        if reads < last or dropped != reads - n:
            raise RecordingError(f"{path}: record {n} (the end record): says {reads} reads and {dropped} dropped, "
                                 f"but the file holds {n} reads up to read {last - 1}")
    _check_claim(path, header, reads, n, f"record {n} (the end record)" if complete else f"record {n - 1}")
    fields = body["f"]
    return Recording(path=path, header=header, values=fields["v"], buttons=fields["buttons"], valid=fields["valid"],
                     error=body["error"] != 0, index=body["read"], reads=reads, dropped=dropped, complete=complete,
                     truncated=truncated)


def _check_claim(path: str, header: dict, reads: int, held: int, where: str) -> None:
    """RecordingError unless the `reads` a recording claims to span are bounded by the `held`
    read records the file holds (MAX_READS_PER_RECORD each) and by MAX_CLAIMED_S at its rate:
    a replay runs one tick per claimed read, so the claim is what a replay would cost."""
    if reads > MAX_READS_PER_RECORD * max(held, 1):
        raise RecordingError(f"{path}: {where}: claims {reads} reads, but the file holds {held} read records "
                             f"(at most {MAX_READS_PER_RECORD} reads per record); the file is damaged or forged")
    rate = header.get("rate_hz")
    if isinstance(rate, bool) or not isinstance(rate, (int, float)) or not (math.isfinite(rate) and rate > 0):
        rate = DEFAULT_RATE_HZ
    if reads > MAX_CLAIMED_S * rate + 1:
        raise RecordingError(f"{path}: {where}: claims {reads} reads, {reads / rate:.4g} s at {rate:g} Hz, over the "
                             f"{MAX_CLAIMED_S:g} s a recording may span")


def _read_v1(path: str, header: dict, file, header_bytes: int, size: int) -> Recording:
    """Version 1: text lines, the count of reads in the header (checked against the body, never
    used to allocate more than the body can hold)."""
    fingers, reads = header["fingers"], header.get("reads")
    if isinstance(reads, bool) or not isinstance(reads, int) or reads < 0:
        raise RecordingError(f"{path}: header needs integer reads >= 0, got {str(reads)[:40]}")
    expected = reads * fingers
    room = min(expected, (size - header_bytes) // _MIN_V1_LINE_BYTES + 1)  # lines the body can hold
    values = np.zeros((room, len(_FLOATS)))
    ints = np.zeros((room, 3), dtype=np.int64)  # buttons, valid, error
    file.seek(header_bytes)
    lines = io.TextIOWrapper(io.BufferedReader(file), encoding="utf-8")
    k = 0
    try:
        for line in lines:
            if k >= expected:
                if line.strip():
                    raise RecordingError(f"{path}: record {expected} (line {expected + 2}): more records than the "
                                         f"header's {reads} reads")
                continue
            i, f = divmod(k, fingers)
            where = f"{path}: record {k} (read {i}, finger {f}, line {k + 2})"
            parts = line.split()
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
            if not -(1 << 63) <= b < (1 << 63):
                raise RecordingError(f"{where}: buttons out of range")
            values[k] = floats
            ints[k] = (b, valid, error)
            k += 1
    except UnicodeDecodeError:
        raise RecordingError(f"{path}: record {k} (line {k + 2}): not UTF-8 text") from None
    finally:
        lines.detach()
    if k < expected:
        i, f = divmod(k, fingers)
        raise RecordingError(f"{path}: record {k} (read {i}, finger {f}, line {k + 2}): missing, the file is "
                             f"truncated ({k} of {expected} records)")
    ints = ints.reshape(reads, fingers, 3)
    return Recording(path=path, header=header, values=values.reshape(reads, fingers, len(_FLOATS)),
                     buttons=ints[:, :, 0], valid=ints[:, :, 1], error=ints[:, 0, 2] != 0,
                     index=np.arange(reads, dtype=np.int64), reads=reads, dropped=0, complete=True, truncated=False)


def replay_error(read: int) -> DeviceError:
    """What a replay raises on a read the recorded device failed on."""
    return DeviceError(f"the recorded device failed on read {read}")


def dropped_error(path: str, read: int) -> DeviceError:
    """What a replay raises on a read the recorder dropped (its writer fell behind)."""
    return DeviceError(f"{path}: read {read} was not recorded (the recorder dropped it); zero force")
