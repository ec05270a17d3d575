"""Device-aware coupling: a finger asked for a stiffer spring (or a stronger damper) than its
device renders stably gets its device's figure instead, and one line saying so.

A device reports what it renders stably as `max_stiffness` (N/m) and `max_damping` (N·s/m),
optional members of the `Device` protocol (absent or None: no limit known, nothing capped):
the vendor's figures, which the adapters take from CHAI3D's device tables (docs/devices.md).
A coupling spring above the device's figure makes a sampled wall buzz or kick on that device
(the passivity controller then dissipates, but the hand feels it first). `allow_stiffer`
keeps the finger's own figures, for research on the edge of stability, and says so.

The hand feels a finger's spring through the device-to-world scale: a device motion of 1 m
is `scale` m in the world (times the adapter's own `workspace_scale`, if it has one), so it
feels k·scale N/m; the cap on k is the device's figure divided by that scale (damping alike).
"""

from __future__ import annotations

import math
from dataclasses import replace

from softproxy.schema import FingerParams

CAPPED = (("stiffness", "max_stiffness", "N/m"), ("damping", "max_damping", "N·s/m"))
"""(FingerParams field, the device's member, unit) of each figure capped."""


def device_figure(device, member: str) -> float | None:
    """The device's `member` (max_stiffness, max_damping) as a float, None when it gives none
    (absent, None, or anything but a finite number ≥ 0)."""
    value = getattr(device, member, None)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    value = float(value)
    return value if math.isfinite(value) and value >= 0.0 else None


def device_label(device, index: int, count: int) -> str:
    """How a note names a device: its label (or class), with its index when there are several."""
    name = getattr(device, "label", None)
    name = name if isinstance(name, str) and name else type(device).__name__
    return f"device {index} ({name})" if count > 1 else f"the device ({name})"


def cap_fingers(fingers: list[FingerParams], devices: list, allow_stiffer: bool = False
                ) -> tuple[list[FingerParams], list[str]]:
    """(the fingers' params, each capped to its device's figures unless `allow_stiffer`; one
    line per finger asked for more than its device renders stably). A finger's device is
    `devices[params.device]` (one device: every finger's). ValueError (one line) when a cap
    falls below the lowest figure a finger takes (`FingerParams.LIMITS`; a large `scale`)."""
    capped, notes = [], []
    for p in fingers:
        k = p.device if p.device < len(devices) else 0
        device = devices[k]
        over = []
        changes = {}
        ws = getattr(device, "workspace_scale", 1.0)  # an adapter's own device-to-engine scale
        if isinstance(ws, bool) or not isinstance(ws, (int, float)) or not (math.isfinite(ws) and ws > 0.0):
            ws = 1.0
        for field, member, unit in CAPPED:
            limit = device_figure(device, member)
            if limit is not None:
                limit /= p.scale * ws  # the figure at the hand, as a figure in the world
            asked = getattr(p, field)
            if limit is not None and asked > limit:
                over.append((field, asked, limit, unit))
                changes[field] = limit
        if over:
            said = ", ".join(f"{field} {asked:g} {unit}" + ("" if allow_stiffer else f" capped to {limit:g} {unit}")
                             for field, asked, limit, unit in over)
            figures = ", ".join(f"{limit:g} {unit}" for _, _, limit, unit in over)
            who = device_label(device, k, len(devices))
            low = {f: FingerParams.LIMITS[f][0] for f, _, _ in CAPPED}
            for field, _, limit, unit in over:
                if not allow_stiffer and limit < low[field]:
                    raise ValueError(f"finger {p.name!r}: {device_label(device, k, len(devices))} renders at most "
                                     f"{limit * p.scale * ws:g} {unit} at the hand, {limit:g} {unit} in the world at "
                                     f"scale {p.scale * ws:g}, below the lowest {field} a finger takes ({low[field]:g} "
                                     f"{unit}): map the device with a smaller scale, or run with --allow-stiffer")
            if allow_stiffer:
                notes.append(f"finger {p.name!r}: {said}: above the {figures} {who} renders stably, kept "
                             f"(--allow-stiffer)")
            else:
                notes.append(f"finger {p.name!r}: {said}, the most {who} renders stably "
                             f"(--allow-stiffer keeps the scene's)")
                p = replace(p, **changes)
        capped.append(p)
    return capped, notes
