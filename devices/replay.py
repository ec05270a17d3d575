"""Replay a recorded run (`softproxy run --record FILE`) as a device: `--device replay:FILE`.

Read for read, the samples come back exactly as recorded — NaN, invalid samples and device
failures included — so a lockstep run replayed from its recording gives the same result.
Forces sent to it go nowhere. Past the end of the recording it holds the last sample.
"""

from __future__ import annotations

from softproxy.device import DeviceError, DeviceSample
from softproxy.recording import load_recording, replay_error


class ReplayDevice:
    """A device playing back a softproxy recording (format in `softproxy.recording`)."""

    max_force = 1e9  # a replay renders nothing: do not clamp what the engine computed
    max_torque = 1e9

    def __init__(self, path: str) -> None:
        self.path = path
        self.header, self.values, self.flags = load_recording(path)
        self.fingers = int(self.header["fingers"])
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
        i = min(self.reads, len(self.values) - 1)
        self.reads += 1
        if i < 0:
            raise DeviceError(f"{self.path}: the recording holds no samples")
        if self.flags[i, 0, 2]:
            raise replay_error(i)
        for f in range(self.fingers):
            s = samples[f]
            (s.t, s.x, s.y, s.z, s.qw, s.qx, s.qy, s.qz, s.twist) = self.values[i, f].tolist()
            s.buttons = int(self.flags[i, f, 0])
            s.valid = bool(self.flags[i, f, 1])

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        pass

    def close(self) -> None:
        self.closed = True
