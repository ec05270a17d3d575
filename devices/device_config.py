"""Checks of a device adapter's settings, shared by the adapters (hid, forcedimension, openhaptics).

Two ways in: a scene's [device] table (`from_config`), where every error is one ValueError line
naming the source file (or `--device` argument) and the field, `"{source}: device.FIELD must be
..., got ..."`; and the `--device TYPE:...` argument (`from_argument`), whose `key=value` items
become such a table. The constructors' own checks of the workspace mapping live here too. What a
field means is each adapter's (its `from_config` docstring); only how it is checked is shared.
Each shipped type's table is declared, with its fields' bounds and units, in
`softproxy.schema.DEVICE_TABLES` (the JSON Schema `softproxy schema` writes for editors); the
errors are in that module's one-line format (`softproxy.input_error`).
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


def check_keys(cfg: dict, source: str, keys) -> None:
    """Every field must be one of `keys`: a misspelt one is an error, not silently ignored."""
    unknown = set(cfg) - set(keys)
    if unknown:
        raise ValueError(f"{source}: device has unknown field(s) {sorted(unknown)}; expected some of {sorted(keys)}")


def number(cfg: dict, source: str, key: str, expected: str, ok) -> float | None:
    """cfg[key] as a float, None when absent; the field's error when it is no finite number or
    `ok(value)` is false (`expected` says what it must be)."""
    if key not in cfg:
        return None
    v = cfg[key]
    if not (finite(v) and ok(v)):
        raise field_error(source, f"device.{key}", expected, v)
    return float(v)


def vector3(cfg: dict, source: str, key: str, *, positive: bool = False, kinds=(list, tuple)):
    """cfg[key] as 3 floats (m), None when absent; the field's error unless it is a `kinds`
    (a TOML array is a list) of 3 finite numbers, each > 0 when `positive`."""
    if key not in cfg:
        return None
    v = cfg[key]
    if not (isinstance(v, kinds) and len(v) == 3 and all(finite(c) and (c > 0 or not positive) for c in v)):
        raise field_error(source, f"device.{key}", f"3 finite numbers{' > 0' if positive else ''} [x, y, z] (m)", v)
    return tuple(float(c) for c in v)


def workspace_fields(cfg: dict, source: str, kwargs: dict, *, kinds=(list, tuple)) -> None:
    """workspace_scale (> 0) and workspace_offset (m) into `kwargs`, those of them given."""
    scale = number(cfg, source, "workspace_scale", "a finite number > 0", lambda v: v > 0)
    if scale is not None:
        kwargs["workspace_scale"] = scale
    offset = vector3(cfg, source, "workspace_offset", kinds=kinds)
    if offset is not None:
        kwargs["workspace_offset"] = offset


def limit_fields(cfg: dict, source: str, kwargs: dict, fields) -> None:
    """Force / torque limits into `kwargs`: `fields` pairs a config key (`max_force_N`) with its
    argument (`max_force`); each must be a finite number >= 0 (the device checks its own cap)."""
    for key, arg in fields:
        v = number(cfg, source, key, "a finite number >= 0", lambda v: v >= 0)
        if v is not None:
            kwargs[arg] = v


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
