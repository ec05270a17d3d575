"""`DeviceGroup`: several devices as one, read and sent in one servo tick, each fault its own.

Two hands on two devices (bimanual work) run in one loop: the group is a `Device` whose
fingers are its members' fingers one after the other (member 0's first), so the loop's
sample rows and sends reach each member through `row(device, finger)`. A finger names its
device by `FingerParams.device` (the member's index, in the order the devices were given)
beside `device_finger` (the finger of that device).

Faults stay with the member that made them: a member whose read raises has its own samples
marked not valid for that tick (its fingers render zero force and their proxies hold, as
any invalid sample does), while the other members' fingers render as usual; the read fails
as a whole (`DeviceError`, the loop's `device_error`) only when every member failed. A
member's send that raises is that send's failure only. Each member's force and torque
limits are its own: a send is clamped to them here, after the loop's guard, which clamps to
the largest of them (`max_force`). The loop sends zero to every finger of every member on
every way out; `close()` closes every member, each whatever the others' closing raised.
Members' own safety (stall watchdogs, zero before closing) is theirs, as with one device.
When every member offers `compiled_io()` the servo loop runs the same rules as compiled
code (`softproxy.compiled.group`) instead of calling `read` and `send` here.
"""

from __future__ import annotations

from softproxy.device import DeviceError, DeviceSample, check_device
from softproxy.device_guard import as_limit
from softproxy.compiled.group import clamp_length
from softproxy.compiled.guard import MAX_LIMIT


def _clamped(limit, x: float, y: float, z: float) -> tuple[float, float, float]:
    """(x, y, z) scaled, direction kept, to length ≤ `limit` (`clamp_length`, as the compiled
    group does it); zero when the limit is no number in [0, MAX_LIMIT]."""
    return clamp_length(as_limit(limit), float(x), float(y), float(z))


class DeviceGroup:
    """Several devices driven by one servo loop as one `Device` (see the module docstring).

    `read_failures[k]`: reads of member k that failed; `last_errors[k]`: what it last said ("" none)."""

    def __init__(self, devices) -> None:
        devices = list(devices)
        if not devices:
            raise ValueError("a DeviceGroup needs at least one device")
        if len({id(d) for d in devices}) != len(devices):
            raise ValueError("a DeviceGroup was given the same device twice: each member drives its own fingers")
        for d in devices:
            check_device(d)
        self.devices = devices
        self.offsets = []
        n = 0
        for d in devices:
            self.offsets.append(n)
            n += int(d.fingers)
        self.fingers = n
        self._member = [(k, j) for k, d in enumerate(devices) for j in range(int(d.fingers))]
        self._spans = [(self.offsets[k], self.offsets[k] + int(d.fingers)) for k, d in enumerate(devices)]
        self.read_failures = [0] * len(devices)
        self.last_errors = [""] * len(devices)

    def row(self, device: int, finger: int) -> int:
        """The group's finger (the loop's sample row) of member `device`'s finger `finger`;
        ValueError when the group has no such member or the member no such finger."""
        if not 0 <= device < len(self.devices):
            raise ValueError(f"device {device}: the loop drives {len(self.devices)} device(s) (0 to "
                             f"{len(self.devices) - 1})")
        member = self.devices[device]
        if not 0 <= finger < member.fingers:
            raise ValueError(f"device {device} ({type(member).__name__}) drives {member.fingers} finger(s), "
                             f"not finger {finger}")
        return self.offsets[device] + finger

    def member_of(self, row: int) -> int:
        """Which member drives the group's finger `row`."""
        return self._member[row][0]

    @property
    def max_force(self) -> float:
        """The largest member's force limit (N): the loop's guard clamps to it, each send then to
        its own member's. A member whose limit is no number is left out (its sends are zero)."""
        return self._largest("max_force")

    @property
    def max_torque(self) -> float:
        """The largest member's torque limit (N·m), as `max_force`."""
        return self._largest("max_torque")

    def _largest(self, name: str) -> float:
        best = 0.0
        for d in self.devices:
            try:
                v = as_limit(getattr(d, name))
            except Exception:
                continue
            if 0.0 <= v <= MAX_LIMIT and v > best:
                best = v
        return best

    def read(self, t: float, samples: list) -> None:
        """Each member reads its own rows of `samples`; a member that raises has its rows marked
        not valid. DeviceError (every member's message) only when every member failed."""
        failed = 0
        for k, (d, (a, b)) in enumerate(zip(self.devices, self._spans)):
            # the member's rows as a list of its own, of the loop's DeviceSamples (in place)
            sub = [s if isinstance(s, DeviceSample) else DeviceSample() for s in samples[a:b]]
            sub += [DeviceSample() for _ in range(b - a - len(sub))]
            try:
                d.read(t, sub)
            except Exception as exc:  # this member's fingers hold; the others render
                failed += 1
                self.read_failures[k] += 1
                self.last_errors[k] = str(exc) or type(exc).__name__
                for s in sub:
                    if isinstance(s, DeviceSample):
                        s.valid = False
            for j in range(min(b, len(samples)) - a):  # what the member put in its rows, for the loop to check
                samples[a + j] = sub[j] if j < len(sub) else None
        if failed == len(self.devices):
            raise DeviceError("; ".join(f"device {k}: {e}" for k, e in enumerate(self.last_errors)))

    def send(self, finger: int, fx: float, fy: float, fz: float, tx: float, ty: float, tz: float) -> None:
        """Render on the member that drives `finger`, within that member's own limits."""
        k, j = self._member[finger]
        d = self.devices[k]
        fx, fy, fz = _clamped(d.max_force, fx, fy, fz)
        tx, ty, tz = _clamped(d.max_torque, tx, ty, tz)
        d.send(j, fx, fy, fz, tx, ty, tz)

    def close(self) -> None:
        """Close every member (each zeroes its force first), whatever the others raise; the
        first failure is raised once all are closed."""
        first = None
        for d in self.devices:
            try:
                d.close()
            except BaseException as exc:
                first = first or exc
        if first is not None:
            raise first

    def __repr__(self) -> str:
        return f"DeviceGroup({', '.join(type(d).__name__ for d in self.devices)}; fingers={self.fingers})"
