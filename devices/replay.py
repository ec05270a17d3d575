"""Replay a recorded run (`softproxy run --record FILE`) as a device: `--device replay:FILE`.

Read for read, the samples come back exactly as recorded — NaN, invalid samples and device
failures included — so a lockstep run replayed from its recording gives the same result.
Forces sent to it go nowhere. Past the end of the recording it holds the last sample.

An incomplete recording still replays: a read the recorder dropped (its writer fell
behind) raises DeviceError on that read, so the run renders zero force that tick and
counts a device error naming the read; a recording cut short by a kill replays up to its
last whole record (`truncated` says a partial one was dropped, `complete` that the end
record is missing).
"""

from __future__ import annotations

from softproxy.device import DeviceError, DeviceSample
from softproxy.recording import dropped_error, load_recording, replay_error


class ReplayDevice:
    """A device playing back a softproxy recording (format in `softproxy.recording`)."""

    max_force = 1e6  # a replay renders nothing: the largest limit a device may declare (N, N·m),
    max_torque = 1e6  # so nothing the engine computes is clamped

    def __init__(self, path: str) -> None:
        self.path = path
        self.recording = load_recording(path)
        self.header = self.recording.header
        self.fingers = self.recording.fingers
        self.recovered = self.recording.recovered  # read records the file held
        self.dropped = self.recording.dropped  # reads the recorder did not keep
        self.truncated = self.recording.truncated  # a partial last record was dropped
        self.complete = self.recording.complete  # the recorder closed the file (end record present)
        self._index = self.recording.index.tolist()  # which read each record holds, ascending
        self._next = 0  # the first record not yet played
        self.reads = 0
        self.closed = False

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

    def read(self, t: float, samples: list[DeviceSample]) -> None:
        if self.closed:
            raise DeviceError("replay device is closed")
        read = self.reads
        self.reads = read + 1
        index = self._index
        if not index:
            raise DeviceError(f"{self.path}: the recording holds no samples")
        k = self._next
        if k < len(index):
            if index[k] != read:  # a later read is next: this one was dropped by the recorder
                raise dropped_error(self.path, read)
            self._next = k + 1
        elif read < self.recording.reads:  # dropped after the last record the file holds
            raise dropped_error(self.path, read)
        else:
            k = len(index) - 1  # past the end: hold the last sample
        rec = self.recording
        if rec.error[k]:
            raise replay_error(int(index[k]))
        values, buttons, valid = rec.values[k].tolist(), rec.buttons[k].tolist(), rec.valid[k].tolist()
        for f in range(self.fingers):
            s = samples[f]
            (s.t, s.x, s.y, s.z, s.qw, s.qx, s.qy, s.qz, s.twist) = values[f]
            s.buttons = buttons[f]
            s.valid = bool(valid[f])

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        pass

    def close(self) -> None:
        self.closed = True
