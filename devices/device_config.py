"""Checks of a device adapter's settings, shared by the adapters (sim, hid, forcedimension, openhaptics).

Two ways in: a scene's [device] table (`from_config`), where every error is one ValueError line
naming the source file (or `--device` argument) and the field, `"{source}: device.FIELD must be
..., got ..."`; and the `--device TYPE:...` argument (`from_argument`), whose `key=value` items
become such a table. Each shipped type's table is declared, with its fields' types, bounds and
units, in `softproxy.schema.DEVICE_TABLES` (the JSON Schema `softproxy schema` writes for
editors): `check_type` checks a table against it and `given` hands the checked fields to the
constructor; what depends on the device (a limit within its profile's or its SDK's) stays the
adapter's. The constructors' own checks of the workspace mapping live here too.
"""

from __future__ import annotations

import math

from softproxy import schema
from softproxy.input_error import must_be


def finite(v) -> bool:
    """A real, finite number (a bool is not one)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


# --- the constructors' checks ----------------------------------------------------------------

def check_workspace(workspace_scale, workspace_offset) -> tuple[float, tuple[float, float, float]]:
    """(scale, offset (m)) of a device's workspace mapping: position x scale + offset; a ValueError
    (without a source: the caller adds it) when the scale is no finite number > 0 or the offset
    no 3 finite numbers."""
    if not (finite(workspace_scale) and workspace_scale > 0):
        raise ValueError(f"workspace_scale must be a finite number > 0, got {workspace_scale!r}")
    offset = tuple(workspace_offset)
    if len(offset) != 3 or not all(finite(v) for v in offset):
        raise ValueError(f"workspace_offset must be 3 finite numbers (m), got {workspace_offset!r}")
    return float(workspace_scale), tuple(float(v) for v in offset)


# --- a scene's [device] table ------------------------------------------------------------------

def field_error(source: str, field: str, expected: str, got) -> ValueError:
    """The one-line error of a field: `{source}: {field} must be {expected}, got {got!r}` (an InputError)."""
    return must_be(field, expected, got, source=source)


def check_table(cfg, source: str) -> None:
    """The [device] entry must be a table."""
    if not isinstance(cfg, dict):
        raise field_error(source, "device", "a table", cfg)


def check_type(cfg: dict, source: str, type_name: str, what: str = ""):
    """device.type, when given, must be `type_name` (`what`: words after it in the message); then
    every field as `softproxy.schema.DEVICE_TABLES[type_name]` declares it (what depends on the
    device, a limit within its own, is the adapter's to check). The checked table (a pydantic
    model: fields absent from `cfg` at their declared defaults)."""
    if cfg.get("type", type_name) != type_name:
        raise field_error(source, "device.type",
                          f"\"{type_name}\"{what} (this scene's [device] is for another device type)", cfg.get("type"))
    return schema.validate(schema.DEVICE_TABLES[type_name], {**cfg, "type": type_name}, source=source, path="device")


def given(table, cfg: dict, arguments: dict) -> dict:
    """The checked values (from `check_type`'s table) of the fields `cfg` gives, as keyword
    arguments: `arguments` maps a field to its argument; a field left out keeps the adapter's
    own default."""
    return {arg: getattr(table, key) for key, arg in arguments.items() if key in cfg}


def construct(source: str, make, *args, **kwargs):
    """make(*args, **kwargs), a device built from checked fields; a ValueError from its own checks
    (a value beyond what this device can do) is the same one line with `source` in front."""
    try:
        return make(*args, **kwargs)
    except ValueError as exc:
        raise ValueError(f"{source}: {exc}") from None


# --- the --device argument ---------------------------------------------------------------------

def argument_table(argument: str, scene, type_name: str) -> tuple[dict, list[str]]:
    """The start of `--device TYPE:ARGUMENT`: the scene's own [device] when it is of this type
    (the argument overrides its fields; another type's is ignored), and the argument's items."""
    device_cfg = getattr(scene, "device", None)
    cfg = dict(device_cfg) if isinstance(device_cfg, dict) and device_cfg.get("type") == type_name else {}
    cfg["type"] = type_name
    return cfg, [p.strip() for p in str(argument).split(",") if p.strip()]


def argument_items(cfg: dict, items, source: str, *, usage: str, vectors=("workspace_offset",), strings=(),
                   integers=()) -> None:
    """`key=value` items into `cfg`: `vectors` as numbers separated by ':', `strings` as they are,
    `integers` as int, every other key as a float (from_config then checks each field); `usage`
    is the form the error names when an item is not key=value."""
    for item in items:
        key, eq, value = (s.strip() for s in item.partition("="))
        if not eq or not key:
            raise ValueError(f"{source}: expected {usage}, got {item!r}")
        if key in vectors:
            try:
                cfg[key] = [float(v) for v in value.split(":")]
            except ValueError:
                raise ValueError(f"{source}: {key} must be 3 numbers separated by ':', got {value!r}") from None
        elif key in integers:
            try:
                cfg[key] = int(value)
            except ValueError:
                raise ValueError(f"{source}: {key} must be an integer, got {value!r}") from None
        elif key in strings:
            cfg[key] = value
        else:
            try:
                cfg[key] = float(value)
            except ValueError:
                raise ValueError(f"{source}: {key} must be a number, got {value!r}") from None
