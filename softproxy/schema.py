"""The declared schema of every input: each field once, with its type, bounds and SI unit.

Declared here: `FingerParams` (a finger's settings), `TactileSpec` / `SensingSpec` (a finger's
fingertip-sensor channels), the scene TOML's tables (`SceneFile`), a HID profile's file
(`HidProfileFile`) and the [device] tables of the device types (`DeviceTable`). A field's
bounds and unit are declared once, in its `Field` (`quantity`, `count`); the validation, the
one-line errors and the JSON Schema an editor reads (`softproxy schema`) all come from them.

Errors: every mistake is one `InputError` line (a ValueError), in the one format of
`softproxy.input_error`: `[FILE: ]PATH must be REQUIREMENT, got VALUE[ (HINT)]`, e.g.
`scene.toml: finger[0].stiffness must be between 10 and 1e+08 N/m, got 2.0 (stiffness is in
N/m: 2 N/mm is 2000 N/m)`. `validate(model, data, source=..., path=...)` turns pydantic's ValidationError
(several lines) into that line, naming the first mistake.

Decision: `FingerParams`, `TactileSpec` and `SensingSpec` stay stdlib dataclasses (their
fields are plain floats, ints and tuples that `softproxy.finger` copies into the compiled
core's records, `dataclasses.replace` and `fields` work on them), their fields declared with
pydantic's `Annotated[..., Field(...)]`; `__post_init__` validates the instance through a
pydantic model built once from those same annotations (`_check_dataclass`). A pydantic
dataclass was not used: it raises a multi-line ValidationError from `__init__`, which the
one-line error format (and every caller catching ValueError) would have to unwrap.

Layering: this module imports the constants it bounds fields with from the modules that own
them (`fingertip`, `tactile`, `geometry`, `compiled.godobject`), none of which imports it; the
servo loop's rate range is declared here (`SERVO_RATE_HZ`) and `softproxy.servo` takes it.
"""

import dataclasses
import json
import math
import operator
import typing
from pathlib import Path
from typing import Annotated, Any, Literal, Optional, Union

from pydantic import (AfterValidator, BaseModel, BeforeValidator, ConfigDict, Discriminator, Field, Tag, TypeAdapter,
                      ValidationError, create_model, model_validator)
from pydantic_core import PydanticCustomError

from softproxy.compiled.godobject import RESTICK_TIME, WORKSPACE_LIMIT
from softproxy.fingertip import MODELS
from softproxy.geometry import GEOM_GROUPS, MESH_SURFACES
from softproxy.input_error import InputError, must_be
from softproxy.tactile import PAPER_CELLS, PAPER_YOUNGS_MODULUS

SERVO_RATE_HZ = (10.0, 100_000.0)
"""Servo rates a scene may ask for, Hz: what `softproxy.servo.ServoLoop` runs (its MIN_RATE_HZ, MAX_RATE_HZ, taken from here)."""
MAX_DURATION_S = 86_400.0
"""Longest run a scene (duration_s) or `softproxy run --duration` may ask for, s (24 h); more is
taken for a mistake (a run's recording and video grow with its length)."""

# ---------------------------------------------------------------------------------------------
# Declaring a field once: a number with its unit and bounds, an integer count, a 3-vector.


def _range_text(low, high, unit: str, open_low: bool) -> str:
    """' in [0, 0.1] m', ' >= 0 N', ' > 0' or ' (m)': what a number field admits, for its errors."""
    u = f" {unit}" if unit else ""
    if low is not None and high is not None:
        return f" in {'(' if open_low else '['}{low:g}, {high:g}]{u}"
    if low is not None:
        return f" {'>' if open_low else '>='} {low:g}{u}"
    if high is not None:
        return f" <= {high:g}{u}"
    return f" ({unit})" if unit else ""


def _number_check(requirement: str):
    """A before-validator: a real number (not a bool or a string), finite, as a float; the error
    says `requirement` ("a finite number in [0, 0.1] m")."""
    def number(value):
        if isinstance(value, (bool, str, bytes)):
            raise PydanticCustomError("input", requirement)
        try:
            number = float(value)
        except (TypeError, ValueError, OverflowError):  # OverflowError: a TOML integer past a float's range
            raise PydanticCustomError("input", requirement) from None
        if not math.isfinite(number):
            raise PydanticCustomError("input", requirement)
        return number

    return number



def _integer(value):
    """Before the int check: an integer (not a bool, not 2.0)."""
    if isinstance(value, bool):
        raise PydanticCustomError("input", "an integer")
    try:
        return operator.index(value)  # int and numpy's integers, never a float
    except TypeError:
        raise PydanticCustomError("input", "an integer") from None


def _bound_check(low, high, unit: str, open_low: bool, hint_low: str, hint_high: str, nonzero: bool = False,
                 says: str = ""):
    """An after-validator: `low <= v <= high` (`low < v` when open_low; v != 0 when nonzero); the
    error words the bound with its unit (or says `says`)."""
    u = f" {unit}" if unit else ""
    # a signed range (an offset): say both ends
    both = f"at least {low:g}{u} and at most {high:g}{u}" if low is not None and high is not None and low < 0.0 else ""

    def check(v):
        if says and not ((low is None or (v > low if open_low else v >= low)) and (high is None or v <= high)):
            raise PydanticCustomError("bound", says)
        if nonzero and v == 0:
            raise PydanticCustomError("bound", "non-zero")
        if low is not None and (v <= low if open_low else v < low):
            if both:
                text = both
            elif high is not None and low > 0.0:
                text = f"between {low:g} and {high:g}{u}"
            else:
                text = f"a finite number {'>' if open_low else '>='} {low:g}{u}"
            # a unit slip gives a positive number too small: a negative one is another mistake
            raise PydanticCustomError("bound", text, {"hint": hint_low if v > 0 else ""})
        if high is not None and v > high:
            text = both or f"at most {high:g}{u}"
            raise PydanticCustomError("bound", text, {"hint": hint_high})
        return v

    return check


def quantity(unit: str, description: str, *, low: float | None = None, high: float | None = None,
             open_low: bool = False, hint_low: str = "", hint_high: str = "", optional: bool = False,
             nonzero: bool = False, says: str = ""):
    """A finite number in `unit` (SI; "" for a ratio) within [low, high] ((low, high] when open_low).

    `hint_low` / `hint_high`: the likely mistake when the value is past that bound (a unit slip),
    appended to the error. `optional`: None is allowed too (a default chosen elsewhere).
    `nonzero`: 0 is refused (a scale). `says`: what every error of the field says it must be
    (e.g. "a probability per read in [0, 1]"), in place of the type and bound.
    """
    extra: dict[str, Any] = {"unit": unit} if unit else {}
    if low is not None:
        extra["exclusiveMinimum" if open_low else "minimum"] = low
    if high is not None:
        extra["maximum"] = high
    if nonzero:
        extra["not"] = {"const": 0}
    requirement = says or f"a finite number{_range_text(low, high, unit, open_low)}"
    bound = _bound_check(low, high, unit, open_low, hint_low, hint_high, nonzero, says)
    number = Annotated[float, BeforeValidator(_number_check(requirement)), AfterValidator(bound)]
    kind = Optional[number] if optional else number
    return Annotated[kind, Field(description=f"{description} ({unit})" if unit else description,
                                 json_schema_extra=extra)]


def count(description: str, *, low: int | None = None, high: int | None = None, unit: str = "", hint: str = ""):
    """An integer within [low, high] (a count of cells, frames, a seed, a finger index, an id);
    `hint` is appended to the error past either bound."""
    extra: dict[str, Any] = {}
    if low is not None:
        extra["minimum"] = low
    if high is not None:
        extra["maximum"] = high
    return Annotated[int, BeforeValidator(_integer),
                     AfterValidator(_bound_check(low, high, unit, False, hint, hint)),
                     Field(description=description, json_schema_extra=extra)]


def _vector3(value):
    """Before the tuple check: a list or tuple of exactly 3 items."""
    if isinstance(value, (str, bytes, dict)):
        raise PydanticCustomError("input", "3 finite numbers [x, y, z]")
    try:
        items = tuple(value)
    except TypeError:
        raise PydanticCustomError("input", "3 finite numbers [x, y, z]") from None
    if len(items) != 3:
        raise PydanticCustomError("input", "3 finite numbers [x, y, z]")
    return items


def vector3(description: str, unit: str = "", *, low: float | None = None, high: float | None = None,
            open_low: bool = False, direction: bool = False, optional: bool = False):
    """[x, y, z]: 3 finite numbers (each within [low, high], (low, high] when open_low); `direction`:
    non-zero, made a unit vector."""
    item_schema = {k: v for k, v in (("exclusiveMinimum" if open_low else "minimum", low), ("maximum", high))
                   if v is not None}
    item = Annotated[float, BeforeValidator(_number_check(f"a finite number{_range_text(low, high, unit, open_low)}")),
                     AfterValidator(_bound_check(low, high, unit, open_low, "", "")),
                     Field(json_schema_extra=item_schema)]
    checks: list = [BeforeValidator(_vector3)]
    if direction:
        checks.append(AfterValidator(_unit_vector))
    kind = Annotated[tuple[item, item, item], *checks]
    kind = Optional[kind] if optional else kind
    extra: dict[str, Any] = {"unit": unit} if unit else {}
    if low is not None and high is not None:
        extra["x-component-range"] = [low, high]  # for `limits`; each item carries its own bounds
    return Annotated[kind, Field(description=f"{description} ({unit})" if unit else description,
                                 json_schema_extra=extra)]


def _unit_vector(v):
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    if not (math.isfinite(n) and n > 0.0):
        raise PydanticCustomError("input", "a finite non-zero vector")
    return (v[0] / n, v[1] / n, v[2] / n)


def choice(options, description: str):
    """One of `options` (strings)."""
    return Annotated[Literal[tuple(options)], Field(description=description)]


def text(requirement: str, *, description: str = ""):
    """A non-empty string; the error says `requirement` (what the string names)."""
    def check(value):
        if not (isinstance(value, str) and value.strip()):
            raise PydanticCustomError("input", requirement)
        return value

    return Annotated[str, BeforeValidator(check), Field(description=description or requirement,
                                                        json_schema_extra={"pattern": r"\S"})]


Flag = Annotated[bool, Field(strict=True)]
"""true or false (never 1 or "yes")."""
Text = Annotated[str, Field(strict=True)]
Name = Annotated[str, Field(strict=True, min_length=1, pattern=r"\S")]

# ---------------------------------------------------------------------------------------------
# The one error format: pydantic's ValidationError -> one InputError line.

_KIND = {
    "model_type": "a table", "model_attributes_type": "a table", "dict_type": "a table", "dataclass_type": "a table",
    "list_type": "a list", "tuple_type": "3 finite numbers [x, y, z]", "bool_type": "true or false",
    "string_type": "a string",
    "int_type": "an integer", "float_type": "a number", "string_too_short": "a non-empty string",
    "too_short": "a non-empty list", "string_pattern_mismatch": "a non-empty string",
}


def _path(prefix: str, loc) -> str:
    """`finger[0].tactile.cells` from a pydantic location (a union member's tag dropped)."""
    text = prefix
    for part in loc:
        if isinstance(part, int):
            text += f"[{part}]"
        elif isinstance(part, str) and (part.startswith(("function-", "tagged-union[")) or part in _UNION_TAGS
                                        or part == "[key]"):  # a table's key (its error names the key itself)
            continue
        else:
            text += f".{part}" if text else str(part)
    return text


_UNION_TAGS = {"flag", "table", "choice", "sim", "hid", "forcedimension", "openhaptics", "haply", "replay"}
"""Tags pydantic puts in an error's location inside a union (a channel's, a [device] table's type)."""


_REQUIRED = {
    "finger": "at least one [[finger]] table is required",
    "scene": "a [scene] table is required, with mjcf: the MJCF file name, relative to the scene file",
    "scene.mjcf": "scene.mjcf is required: the MJCF file name, relative to the scene file",
    "device.finger": "device.finger is required: a list of [[device.finger]] tables with keyframes",
}
"""What a missing (or empty) key means, by path (others: `PATH is required: its description`)."""


def _rank(error: dict) -> int:
    """Which of a union's errors to report: a table's own complaint beats 'must be true or false'."""
    return 1 if error["type"] in ("bool_type",) else 0


def one_line(exc: ValidationError, *, source: str = "", path: str = "") -> InputError:
    """The first mistake of a ValidationError as one InputError line (`source`: the file; `path`:
    where the validated data sits in it, e.g. "finger[0]")."""
    errors = sorted(exc.errors(include_url=False), key=_rank)
    e = errors[0]
    loc = e["loc"]
    where = _path(path, loc)
    kind, ctx = e["type"], e.get("ctx") or {}
    if kind == "unknown_fields":
        lead = f"{source}: " if source else ""
        if not where:  # the file's own keys
            return InputError(f"{lead}unknown {ctx['what']} {ctx['unknown']}; expected some of {ctx['allowed']}")
        return InputError(f"{lead}{where} has unknown field(s) {ctx['unknown']}; expected some of {ctx['allowed']}")
    if kind == "missing_field":
        where = f"{where}.{ctx['field']}" if where else ctx["field"]
        kind, ctx = "missing", {"hint": ctx.get("hint") or ""}
    if kind == "missing" or (kind == "too_short" and where in _REQUIRED):
        lead = f"{source}: " if source else ""
        hint = f": {ctx['hint']}" if ctx.get("hint") else ""
        return InputError(f"{lead}{_REQUIRED.get(where, f'{where} is required{hint}')}")
    if kind in ("input", "bound"):
        requirement = e["msg"]
    elif kind == "literal_error":
        requirement = f"one of {ctx['expected'].replace(' or ', ', ')}"
    elif kind == "extra_forbidden":
        lead = f"{source}: " if source else ""
        return InputError(f"{lead}{where} is not a field of this table")
    else:
        requirement = _KIND.get(kind, e["msg"].lower())
    return must_be(where, requirement, e.get("input"), source=source, hint=ctx.get("hint", ""))


def build(cls, data: dict, *, source: str = "", path: str = ""):
    """`cls(**data)` for a validated dataclass; its InputError with `source: path.` in front."""
    try:
        return cls(**data)
    except InputError as exc:
        raise InputError(f"{source}: {path}.{exc}" if source else f"{path}.{exc}") from None


def validate(model, data, *, source: str = "", path: str = ""):
    """`model.model_validate(data)`; InputError (one line naming `source` and the field) otherwise."""
    try:
        return model.model_validate(data)
    except ValidationError as exc:
        raise one_line(exc, source=source, path=path) from None


class Table(BaseModel):
    """A TOML table: every key declared (a misspelt one is named, with the keys it may be)."""

    model_config = ConfigDict(extra="forbid", populate_by_name=True)
    keys_are: typing.ClassVar[str] = "field(s)"
    """What the table's keys are called in an error: a scene file's are tables."""

    @model_validator(mode="before")
    @classmethod
    def _known_keys(cls, data):
        if isinstance(data, dict):
            allowed = {f.alias or name for name, f in cls.model_fields.items()}
            unknown = sorted(str(k) for k in set(data) - allowed)
            if unknown:
                raise PydanticCustomError("unknown_fields", "unknown field(s)",
                                          {"unknown": unknown, "allowed": sorted(allowed), "what": cls.keys_are})
            for name, f in cls.model_fields.items():
                if f.is_required() and name not in data:  # named with what it is
                    raise PydanticCustomError("missing_field", "required", {"field": name, "hint": f.description})
        return data


# ---------------------------------------------------------------------------------------------
# Dataclasses validated on construction (FingerParams, TactileSpec, SensingSpec).

_MODELS: dict[type, type[BaseModel]] = {}


def _fields_model(cls) -> type[BaseModel]:
    """A pydantic model of a dataclass's fields, from their annotations (built once per class)."""
    model = _MODELS.get(cls)
    if model is None:
        hints = typing.get_type_hints(cls, include_extras=True)
        model = create_model(f"{cls.__name__}Fields", __base__=Table,
                             **{f.name: (hints[f.name], f.default) for f in dataclasses.fields(cls)})
        _MODELS[cls] = model
    return model


def _check_dataclass(obj) -> None:
    """Validate a dataclass instance's fields against their declarations; store the checked values
    (a list offset becomes a tuple of floats). InputError naming the field otherwise."""
    cls = type(obj)
    names = [f.name for f in dataclasses.fields(cls)]
    checked = validate(_fields_model(cls), {n: getattr(obj, n) for n in names})
    for n in names:
        object.__setattr__(obj, n, getattr(checked, n))


def fields_of(cls) -> dict[str, Any]:
    """The declared fields of a validated dataclass: name -> (annotation, default), to build tables from."""
    hints = typing.get_type_hints(cls, include_extras=True)
    return {f.name: (hints[f.name], f.default) for f in dataclasses.fields(cls)}


def limits(cls) -> dict[str, tuple[float, float, str]]:
    """(lowest, highest, unit) of every bounded numeric field of a validated dataclass."""
    out = {}
    for name, info in _fields_model(cls).model_fields.items():
        schema = info.json_schema_extra or {}
        if "maximum" in schema:
            out[name] = (schema.get("minimum", schema.get("exclusiveMinimum", 0.0)), schema["maximum"],
                         schema.get("unit", ""))
        elif "x-component-range" in schema:  # a vector: each component's range
            out[name] = (*schema["x-component-range"], schema.get("unit", ""))
    return out


# ---------------------------------------------------------------------------------------------
# A finger


@dataclasses.dataclass
class FingerParams:
    """Per-finger settings of a scene (SI units). Validated on construction: every number finite
    and within its declared bounds (`LIMITS`), so no setting can drive a force to overflow (Inf,
    then NaN at the clamp); InputError (a ValueError) naming the field, its range and its unit.

    Why the highest bounds: a device position is believed within ±WORKSPACE_LIMIT (1 km) and a
    tick is at least 10 µs (100 kHz), so the spring stretch is < ~2e6 m (with `scale`) and its
    rate < ~2e11 m/s; at these bounds k·stretch + b·rate stays below ~1e17 N, far from float
    overflow (a damping of 1e308 made b·rate Inf and the clamp Inf·0 = NaN). Each bound is also
    orders of magnitude past any real setting, so it only catches mistakes (mm typed as m, an
    exponent slip) and admits the extremes the tests and benchmarks drive (k = 1e7 N/m, b = 1e3
    N·s/m, k_τ = 1e6 N·m/rad, a 1e4 N clamp).
    """

    name: Annotated[Name, Field(description="the finger's name (recordings, messages)")] = "finger"
    radius: quantity("m", "proxy sphere radius: a fingertip or a tool tip (shipped: 5-50 mm)", low=0.0, high=0.1,
                     hint_high="radius is in m: 8 mm is 0.008") = 0.008
    stiffness: quantity("N/m", "coupling stiffness k. Lowest 10 N/m: a softer spring renders nothing a hand "
                        "feels, and a stiffness typed in N/mm (2 for 2000 N/m) falls below it; devices render "
                        "<= ~1e4 N/m, tests 1e7", low=10.0, high=1e8,
                        hint_low="stiffness is in N/m: 2 N/mm is 2000 N/m") = 2000.0
    damping: quantity("N·s/m", "coupling damping b (devices render <= ~1e2 N·s/m; tests 1e3)",
                      low=0.0, high=1e5) = 5.0
    torsion_stiffness: quantity("N·m/rad", "torsional stiffness k_τ (shipped 0.5-2; tests 1e6)",
                                low=0.0, high=1e7, open_low=True) = 2.0
    torsion_damping: quantity("N·m·s/rad", "torsional damping b_τ (shipped <= 0.01)", low=0.0, high=1e4) = 0.002
    model: choice(MODELS, "fingertip model: the torsion law (softproxy.fingertip)") = "CH"
    mu_s: quantity("", "translational static friction (a cone of 84° at 10; skin is ~0.5-3)",
                   low=0.0, high=10.0) = 1.0
    mu_d: quantity("", "translational dynamic friction, <= mu_s", low=0.0, high=10.0) = 0.8
    torsion_mu_s: quantity("N·m/N^γ", "static torsional coefficient μ' (default: Table 1's; ~100 × Table 1 "
                           "at most)", low=0.0, high=1.0, optional=True) = None
    torsion_mu_d: quantity("N·m/N^γ", "dynamic torsional coefficient (default: 0.8 × static), <= torsion_mu_s",
                           low=0.0, high=1.0, optional=True) = None
    saturate: Annotated[Flag, Field(description="torsion limit follows eq 26 (linear above P*), the default: closer "
                                    "to the measured fingertip (docs/peer.md); false: μ'|P|^γ at every P")] = True
    restick_time: quantity("s", "a slipping contact (cone, torsion) stopped this long re-sticks; 0: static limits "
                           "re-tested every tick (Simulating human fingers, eq 39 as printed); a minute is already never",
                           low=0.0, high=60.0) = RESTICK_TIME
    max_force: quantity("N", "clamp on |F| (devices render <= ~1e2 N; the wall benchmark 200 N, tests 1e4)",
                        low=0.0, high=1e5, open_low=True) = 40.0
    max_torque: quantity("N·m", "clamp on |M| (devices render <= ~1 N·m)", low=0.0, high=1e3, open_low=True) = 1.0
    max_speed: quantity("m/s", "a device sample farther than max_speed·dt from the last is a spike (a hand "
                        "moves at <= ~5 m/s)", low=0.0, high=1e4, open_low=True) = 20.0
    soft_start: quantity("s", "after placement the force clamp ramps from 0 to max_force over this (a minute "
                         "is already no force at all to a user)", low=0.0, high=60.0) = 0.1
    device: count("which device drives this one: its index among the scene's [[device]] tables (or the "
                  "--device flags), in order; 0 with one device", low=0) = 0
    device_finger: count("which finger of its device drives this one", low=0) = 0
    offset: vector3("device-to-world offset, each component inside the workspace", "m",
                    low=-WORKSPACE_LIMIT, high=WORKSPACE_LIMIT) = (0.0, 0.0, 0.0)
    scale: quantity("", "device-to-world workspace scale (1e3 maps 1 mm to 1 m)", low=0.0, high=1e3,
                    open_low=True) = 1.0

    LIMITS: typing.ClassVar[dict[str, tuple[float, float, str]]] = {}
    """Allowed range of every numeric field, (lowest, highest, unit), from the declarations above."""

    def __post_init__(self) -> None:
        _check_dataclass(self)
        if self.mu_d > self.mu_s:
            raise must_be("mu_d", f"<= mu_s ({self.mu_s!r})", self.mu_d)
        if (self.torsion_mu_s is not None and self.torsion_mu_d is not None
                and self.torsion_mu_d > self.torsion_mu_s):
            raise must_be("torsion_mu_d", f"<= torsion_mu_s ({self.torsion_mu_s!r})", self.torsion_mu_d)


FingerParams.LIMITS = limits(FingerParams)

# ---------------------------------------------------------------------------------------------
# A material (softproxy.material): what a finger feels on the geoms it is given to


@dataclasses.dataclass(frozen=True)
class Material:
    """What a finger feels on a surface beyond its own coupling (SI units; docs/materials.md).
    Every field is optional: a field left out is the finger's own, or no effect. The spring
    and damper render the softer of the surface's and the finger's; friction given here is the
    pair's (the finger's is not combined with it); the effects are CHAI3D's `cMaterial`'s."""

    stiffness: quantity("N/m", "the surface's stiffness: the softer of it and the finger's coupling renders",
                        low=10.0, high=1e8, optional=True,
                        hint_low="stiffness is in N/m: 2 N/mm is 2000 N/m") = None
    damping: quantity("N·s/m", "the surface's damping: the lesser of it and the finger's renders",
                      low=0.0, high=1e5, optional=True) = None
    mu_s: quantity("", "static friction of the finger on this surface (the pair's)", low=0.0, high=10.0,
                   optional=True) = None
    mu_d: quantity("", "dynamic friction of the pair, <= mu_s (default 0.8 × mu_s)", low=0.0, high=10.0,
                   optional=True) = None
    torsion: quantity("", "factor on the torsional limit, over its scaling with the sliding friction",
                      low=0.0, high=100.0) = 1.0
    viscosity: quantity("N·s/m", "a damper on the finger's motion relative to the surface while in contact",
                        low=0.0, high=1e3) = 0.0
    vibration_hz: quantity("Hz", "frequency of a vibration along the contact normal", low=0.0, high=1e4) = 0.0
    vibration_amplitude: quantity("N", "its amplitude (0: none; a contact never pulls, so at most the grip "
                                  "of the negative half)", low=0.0, high=100.0) = 0.0
    magnet_force: quantity("N", "a magnet's pull on a finger about to touch (out of contact; touching, the surface "
                           "bears it) (0: none)",
                           low=0.0, high=100.0) = 0.0
    magnet_reach: quantity("m", "how far from the surface the pull reaches, falling linearly to zero",
                           low=0.0, high=0.1, hint_high="magnet_reach is in m: 1 cm is 0.01") = 0.0
    stick_slip_force: quantity("N", "stick-slip: the anchor spring's break force (0: none)",
                               low=0.0, high=100.0) = 0.0
    stick_slip_stiffness: quantity("N/m", "stick-slip: the anchor spring's stiffness", low=0.0, high=1e6) = 0.0
    texture_period: quantity("m", "a height grating's spatial period (0: none)", low=0.0, high=1.0,
                             hint_high="texture_period is in m: 2 mm is 0.002") = 0.0
    texture_height: quantity("m", "the grating's height amplitude", low=0.0, high=0.01,
                             hint_high="texture_height is in m: 0.1 mm is 0.0001") = 0.0
    texture_friction: quantity("", "the grating's friction modulation: μ × (1 + m sin(2π u / period))",
                               low=-1.0, high=1.0) = 0.0
    texture_axis: vector3("the grating's axis in the geom's frame", direction=True) = (1.0, 0.0, 0.0)
    popthrough_force: quantity("N", "a finger pressing harder than this passes through the surface, which it "
                               "feels again once out of it (0: never)", low=0.0, high=1e3) = 0.0

    def __post_init__(self) -> None:
        _check_dataclass(self)
        if self.mu_d is not None:
            if self.mu_s is None:
                raise must_be("mu_d", "given with mu_s (the pair's static friction)", self.mu_d)
            if self.mu_d > self.mu_s:
                raise must_be("mu_d", f"<= mu_s ({self.mu_s!r})", self.mu_d)
        self._both("magnet_force", "magnet_reach", self.magnet_reach > 0.0,
                   "a magnet needs both its force and its reach")
        self._both("stick_slip_force", "stick_slip_stiffness", self.stick_slip_stiffness > 0.0,
                   "stick-slip needs both its break force and its stiffness")
        self._both("texture_period", "texture_height", self.texture_height > 0.0 or self.texture_friction != 0.0,
                   "a grating needs its period and a height or a friction modulation")

    def _both(self, first: str, second: str, second_given: bool, why: str) -> None:
        """An effect of two fields, `first` (> 0 when given) and `second`: neither or both; the
        one left out named otherwise."""
        if (getattr(self, first) > 0.0) != second_given:
            missing = second if getattr(self, first) > 0.0 else first
            raise must_be(missing, f"given with the other: {why}", getattr(self, missing))


MaterialTable = create_model("MaterialTable", __base__=Table, __doc__="[materials.NAME]: Material's fields.",
                             **fields_of(Material))

# ---------------------------------------------------------------------------------------------
# A finger's fingertip-sensor channels (softproxy.fingertip_sensors)

CHANNEL_RATE_HZ = (0.01, 100_000.0)
"""A channel's frame rate, Hz: at most the servo's highest rate (a frame at most every tick), at
least a frame every 100 s (below it the decimation count overflows)."""
MAX_HISTORY = 10_000
"""Most frames a channel keeps for the run result (each tactile frame holds its image)."""
MAX_CELLS = 64
"""Most tactile cells per side (the paper's sensor has 10)."""
MAX_SUPERSAMPLE = 8
"""Most sample points per cell and side."""
MAX_POINTS_PER_SIDE = 256
"""Most sample points per side, cells × supersample: the spring fields are (side points)²
arrays, ~10 MB here; 100000 cells asked for ~300 GB before this bound."""
MAX_SUBSTEPS = 1000
"""Most history sub-steps per tactile frame (a frame's cost is linear in them)."""
MAX_FINGERTIP_M = 0.1
"""Largest tactile fingertip radius and sensor side, m (a fingertip; mm typed as m is caught)."""
YOUNGS_MODULUS_PA = (1.0, 1e12)
"""Range of the tactile skin's Young's modulus E, Pa (the paper's 0.36 MPa; steel is 2e11)."""
NOISE = ("none", "gauss", "quantise")
"""Sensor noise models of the sensing channel (seed 003 §2.1 Nano17 resolution)."""
INDENTATION = ("force", "depth")
"""Where the tactile indentation comes from: the normal force or the device penetration."""
DEFAULT_RATE_HZ = 100.0
"""Frames per second of either channel unless the scene says otherwise, Hz."""
DEFAULT_HISTORY = 20
"""Frames kept for the run result."""


@dataclasses.dataclass(frozen=True)
class _ChannelSpec:
    """What every channel has: frame rate (Hz), pad frame, frames of history kept."""

    rate_hz: quantity("Hz", "frames per second", low=CHANNEL_RATE_HZ[0], high=CHANNEL_RATE_HZ[1]) = DEFAULT_RATE_HZ
    pad: vector3("world direction the pad faces (default: latched at each contact as -n)",
                 direction=True, optional=True) = None
    distal: vector3("world direction toward the fingertip's end (default: world +z made ⟂ pad)",
                    direction=True, optional=True) = None
    history: count("frames kept for the run result", low=1, high=MAX_HISTORY, unit="frames") = DEFAULT_HISTORY

    def __post_init__(self) -> None:
        _check_dataclass(self)
        if self.distal is not None and self.pad is None:
            raise InputError("distal needs pad (a latched pad takes the default distal)")
        if self.pad is not None and self.distal is not None:
            if abs(sum(p * d for p, d in zip(self.pad, self.distal))) > 0.99:
                raise InputError(f"distal {list(self.distal)} must not be parallel to pad {list(self.pad)}")


@dataclasses.dataclass(frozen=True)
class TactileSpec(_ChannelSpec):
    """A finger's tactile channel (SI): frame rate (Hz), fingertip and sensor, pad frame."""

    radius: quantity("m", "Inoue-Hirai fingertip radius r (default: the proxy radius)", low=0.0,
                     high=MAX_FINGERTIP_M, open_low=True, optional=True,
                     hint_high="radius is in m: 8 mm is 0.008") = None
    side: quantity("m", "sensor side (default: 2 r)", low=0.0, high=MAX_FINGERTIP_M, open_low=True, optional=True,
                   hint_high="side is in m: 12 mm is 0.012") = None
    cells: count("tactile cells per side", low=1, high=MAX_CELLS) = PAPER_CELLS
    supersample: count("sample points per cell and side", low=1, high=MAX_SUPERSAMPLE) = 2
    youngs_modulus: quantity("Pa", "skin Young's modulus E (the paper's 0.36 MPa)", low=YOUNGS_MODULUS_PA[0],
                             high=YOUNGS_MODULUS_PA[1], hint_low="E is in Pa: 0.36 MPa is 3.6e5") = PAPER_YOUNGS_MODULUS
    indentation: choice(INDENTATION, "indentation from the normal force or the device penetration") = "force"
    max_substeps: count("history sub-steps per frame at most", low=1, high=MAX_SUBSTEPS) = 10

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.cells * self.supersample > MAX_POINTS_PER_SIDE:
            raise InputError(f"cells × supersample must be at most {MAX_POINTS_PER_SIDE} sample points per side, "
                             f"got {self.cells} × {self.supersample}")


@dataclasses.dataclass(frozen=True)
class SensingSpec(_ChannelSpec):
    """A finger's contact-sensing channel: frame rate (Hz), Nano17 noise model and seed, pad frame."""

    noise: choice(NOISE, "sensor noise model (the contact-sensing paper's §2.1: the Nano17's resolution)") = "none"
    seed: count("seed of the noise's random generator") = 0


# ---------------------------------------------------------------------------------------------
# The scene TOML (softproxy.scene)

def _channel_table(spec) -> type[Table]:
    return create_model(f"{spec.__name__}Table", __base__=Table, __doc__=f"The fields of {spec.__name__}.",
                        **fields_of(spec))


def _flag_or_table(value) -> str | None:
    return "flag" if isinstance(value, bool) else "table" if isinstance(value, dict) else None


def channel(table: type[Table], description: str):
    """A finger's `tactile` / `sensing` entry: true, false, or a table of the channel's fields."""
    either = Annotated[Union[Annotated[bool, Tag("flag")], Annotated[table, Tag("table")]],
                       Discriminator(_flag_or_table, custom_error_type="input",
                                     custom_error_message="true, false or a table")]
    return Annotated[Optional[either], Field(None, description=description)]


TactileTable = _channel_table(TactileSpec)
SensingTable = _channel_table(SensingSpec)


def _finger_table(name: str, doc: str) -> type[Table]:
    fields = fields_of(FingerParams)  # each optional: the defaults are FingerParams' (or [finger_defaults]')
    fields["tactile"] = (channel(TactileTable, "the tactile channel (softproxy.fingertip_sensors): true, or a "
                                "table over [finger_defaults]'s; false turns it off"), None)
    fields["sensing"] = (channel(SensingTable, "the contact-sensing channel: true, or a table over "
                                "[finger_defaults]'s; false turns it off"), None)
    return create_model(name, __base__=Table, __doc__=doc, **fields)


FingerTable = _finger_table("FingerTable", "One [[finger]]: FingerParams fields (over [finger_defaults]) and channels.")
FingerDefaults = _finger_table("FingerDefaults", "[finger_defaults]: fields every [[finger]] starts from.")


SETTLE_MAX_S = 60.0
"""The longest [scene] settle_s (s): a model that has not come to rest in a minute will not."""


class SceneTable(Table):
    """[scene]: the MJCF and the run's rate and length."""

    mjcf: Annotated[Name, Field(description="the MJCF file, relative to the scene file")]
    description: Text = ""
    rate_hz: quantity("Hz", "servo rate", low=SERVO_RATE_HZ[0], high=SERVO_RATE_HZ[1],
                      hint_low="rate_hz is in Hz: 1 kHz is 1000") = 1000.0
    duration_s: quantity("s", "length of the run (24 h at most)", low=0.0, high=MAX_DURATION_S, open_low=True,
                         hint_high="duration_s is in s") = 5.0
    physics_rate_hz: Optional[Union[Literal["auto"], quantity(
        "Hz", "MuJoCo's rate with two rates: it steps once every rate_hz / physics_rate_hz haptic ticks, which "
        "render against the shapes carried forward; \"auto\": as fast as the world's step cost lets it (default: "
        "one rate, a MuJoCo step every tick)", low=0.0, high=SERVO_RATE_HZ[1], open_low=True,
        hint_high="physics_rate_hz is in Hz")]] = None
    audit: Annotated[Flag, Field(description="track proxy penetration every tick")] = True
    keyframe: Annotated[Optional[Name], Field(description="a <key> of the MJCF, by name: the world starts "
                                              "from its state (default: the model's qpos0)")] = None
    settle_s: quantity("s", "how long the world runs on its own, no finger in it, before the device takes "
                       "over (a model that sags or drops from its start state comes to rest first)",
                       low=0.0, high=SETTLE_MAX_S, hint_high="settle_s is in s") = 0.0
    force_shading: Annotated[Flag, Field(description="mesh contacts report the normal interpolated from the "
                                          "vertex normals (false: the faceted normal)")] = False


class MeasureTable(Table):
    """[measure]: the run reports how far `object` turned about `axis` from `start_s` to the end."""

    object: Annotated[Name, Field(description="a body of the MJCF")]
    axis: vector3("world axis", direction=True) = (1.0, 0.0, 0.0)
    start_s: quantity("s", "from when", low=0.0, high=MAX_DURATION_S) = 0.0


GeomGroup = count("a geom group", low=0, high=GEOM_GROUPS - 1, hint=f"a geom group is 0 to {GEOM_GROUPS - 1}")


class HapticsTable(Table):
    """[haptics]: what the fingers touch (docs/models.md)."""

    exclude: Annotated[list[Name], Field(description="geom or flex names kept out of haptic contact, "
                                         "still in MuJoCo's physics, e.g. [\"ring\"]")] = []
    exclude_groups: Annotated[list[GeomGroup], Field(description="geom groups kept out of haptic contact")] = []
    mesh_surface: choice(MESH_SURFACES, "\"true\": a mesh's own triangles; \"hull\": the convex hull MuJoCo "
                         "collides it with") = "true"


class DeviceTableAny(BaseModel):
    """[device]: handed as is to the device its `type` names (each device type checks its fields)."""

    model_config = ConfigDict(extra="allow")
    type: Annotated[Name, Field(description="the device type, e.g. \"sim\", \"hid\"")] = "sim"


MAX_DEVICES = 16
"""Most devices one servo loop drives (two hands need two; more is a mistake in a scene)."""


class SceneFile(Table):
    """A scene TOML file: the MJCF beside it and what the haptic side needs (softproxy.scene)."""

    keys_are: typing.ClassVar[str] = "table(s)"

    scene: SceneTable
    measure: Optional[MeasureTable] = None
    finger_defaults: FingerDefaults = Field(default_factory=FingerDefaults)
    finger: Annotated[list[FingerTable], Field(min_length=1, description="one [[finger]] table per finger")]
    device: Union[DeviceTableAny, Annotated[list[DeviceTableAny], Field(min_length=1, max_length=MAX_DEVICES)]] = Field(
        default_factory=DeviceTableAny, description="[device]: the device; or [[device]], one table per device, "
        "each finger naming its own by `device` (an index)")
    haptics: HapticsTable = Field(default_factory=HapticsTable)
    materials: Annotated[dict[Name, MaterialTable], Field(description="[materials.NAME]: a material for the geom, "
                                                          "body or MJCF default class NAME (a geom's own name first, "
                                                          "then its body's, then its class's)")] = {}


# ---------------------------------------------------------------------------------------------
# A HID profile (softproxy.devices.hid_profile; the format in devices/profiles/README.md).
# Declared here: each field's type and bounds. Checked there: what depends on other fields
# (a field ends within its report, the axes name scaled fields, output spans do not overlap).

HID_FIELD_TYPES = ("int8", "uint8", "int16", "uint16", "int32", "uint32", "float32")
"""Types a report field may have (softproxy.devices.hid_profile.TYPES packs them)."""
HID_MODES = ("position", "rate")
HID_REPORTING = ("periodic", "on_change")
MAX_FORCE_N = 100.0
"""Largest `max_force` a profile may declare (N): several times a firm grip, far above a finger-sized device."""
MAX_TORQUE_NM = 10.0
"""Largest `max_torque` a profile may declare (N·m)."""
MAX_INPUT_SCALE = 1e3
"""Largest |scale| / |rate_scale| of an input field (m, rad, m/s or rad/s per count)."""
MAX_OUTPUT_SCALE = 1e9
"""Largest `scale` of an output field (counts per N or per N·m: 1e9 is a count per nN)."""

UsbId = count("a USB id", low=0, high=0xFFFF, hint="a USB id is 16 bits: 0..0xFFFF")
ReportId = count("a report id; 0: the device does not number its reports", low=0, high=255,
                 hint="a report id is 0..255")
Mask = count("a bit mask of the status field", low=0, high=0xFFFFFFFF, hint="a mask of 32 bits: 0..0xFFFFFFFF")


def _signed_axis(value):
    """Before the str check: "x", "y" or "z", optionally with a '-' (or '+')."""
    if not (isinstance(value, str) and value.strip().lstrip("+-").strip() in ("x", "y", "z")):
        raise PydanticCustomError("input", "\"x\", \"y\" or \"z\", optionally with a '-'")
    return value


SignedAxis = Annotated[str, BeforeValidator(_signed_axis),
                       Field(description="an axis of the sample frame, \"x\", \"y\" or \"z\", optionally with a '-'",
                             json_schema_extra={"pattern": r"^\s*[+-]?\s*[xyz]\s*$"})]
FieldName = Annotated[str, Field(strict=True, description="\"field\" or \"-field\": a field of the input reports")]


class HidMatch(Table):
    """[[match]]: the USB ids a profile claims; usage_page / usage / interface narrow a multi-interface device."""

    vendor_id: UsbId
    product_id: UsbId
    model: Text = ""
    usage_page: Optional[UsbId] = None
    usage: Optional[UsbId] = None
    interface: Optional[count("the USB interface number (-1: any)", low=-1)] = None


class HidReportField(Table):
    """Where a number sits in a report: payload byte offset, type, byte order."""

    offset: count("payload byte offset (after the report id of a numbered report)", low=0, unit="bytes")
    type: choice(HID_FIELD_TYPES, "the number's type")
    endian: choice(("little", "big"), "byte order") = "little"


class HidInputField(HidReportField):
    """An input field: `sequence`, `status` and `buttons` are read raw; every other is scaled to SI."""

    scale: quantity("", "SI units per count in position mode (m or rad per count)", low=-MAX_INPUT_SCALE,
                    high=MAX_INPUT_SCALE, nonzero=True) = 1.0
    rate_scale: quantity("", "SI units per second per count in rate mode (m/s or rad/s per count)",
                         low=-MAX_INPUT_SCALE, high=MAX_INPUT_SCALE, nonzero=True, optional=True) = None
    deadband: quantity("counts", "|counts| <= deadband read as 0", low=0.0) = 0.0


class HidInputReport(Table):
    """[[input.report]]: one input report layout (several may share an id with different sizes)."""

    id: ReportId
    size: count("payload bytes", low=1, unit="bytes")
    fields: Annotated[dict[str, HidInputField], Field(min_length=1, description="name = {offset, type, ...}")]


class HidInput(Table):
    """[input]: how the device reports."""

    max_bytes: count("longest input report accepted, report id included", low=1, high=4096, unit="bytes") = 64
    reporting: choice(HID_REPORTING, "\"periodic\": a report every period; \"on_change\": only on motion") = "periodic"
    stale_ms: quantity("ms", "periodic: the sample is stale after this long without a report (default 50; "
                       "on_change: 0 = never stale)", low=0.0, optional=True) = None
    report: Annotated[list[HidInputReport], Field(min_length=1)]


class HidOutputField(HidReportField):
    """An output field: a wrench component (fx fy fz tx ty tz twist, optionally '-'), or sequence / enable."""

    source: Optional[Text] = Field(None, description="fx, fy, fz, tx, ty, tz, twist (a '-' flips it), sequence "
                                   "or enable; default: the field's name")
    scale: quantity("counts/N", "counts per N, or per N·m for a torque (required for a wrench source)",
                    low=0.0, high=MAX_OUTPUT_SCALE, open_low=True, optional=True) = None
    min: quantity("counts", "saturation in counts (default: the type's range, symmetric for a signed integer)",
                  optional=True) = None
    max: quantity("counts", "saturation in counts", optional=True) = None


class HidOutput(Table):
    """[output]: the report a force goes out in."""

    id: ReportId
    size: count("payload bytes", low=1, high=4095, unit="bytes")
    fields: Annotated[dict[str, HidOutputField], Field(min_length=1, description="name = {offset, type, source, ...}")]


class HidAxes(Table):
    """[axes]: which input field is which axis of the finger ("-field" flips it)."""

    x: FieldName
    y: FieldName
    z: FieldName
    twist: Optional[FieldName] = None


class HidStatus(Table):
    """[status]: bits of the `status` field that must be set (e.g. calibrated) or clear (e.g. fault)."""

    require_set: Mask = 0
    require_clear: Mask = 0


class HidProfileFile(Table):
    """A HID device profile (devices/profiles/README.md)."""

    name: Optional[Name] = Field(None, description="default: the file's name")
    description: Text = ""
    mode: choice(HID_MODES, "default motion mode") = "position"
    max_force: quantity("N", "what the device renders safely; 0: renders no force", low=0.0, high=MAX_FORCE_N,
                        hint_high="max_force is in N") = 0.0
    max_torque: quantity("N·m", "what the device renders safely; 0: renders no torque", low=0.0,
                         high=MAX_TORQUE_NM, hint_high="max_torque is in N·m: 100 N·mm is 0.1") = 0.0
    max_stiffness: quantity("N/m", "the stiffest coupling the device renders stably: a stiffer finger is capped "
                            "(default: none known, nothing capped)", low=10.0, high=1e5, optional=True) = None
    max_damping: quantity("N·s/m", "the most coupling damping the device renders stably (default: none known)",
                          low=0.0, high=1e3, optional=True) = None
    finger_axis: SignedAxis = "z"
    match: list[HidMatch] = []
    input: HidInput
    axes: HidAxes
    status: HidStatus = Field(default_factory=HidStatus)
    output: Optional[HidOutput] = None


# ---------------------------------------------------------------------------------------------
# A scene's [device] table, per device type (each adapter's `from_config` in softproxy.devices
# builds the device and checks what depends on the device: a limit within its profile's or its
# SDK's). Declared here for editors (`softproxy schema`); a test keeps the fields equal to each
# adapter's. A device type of a plugin has a table of its own, not declared here.

SIM_FAULT_KINDS = ("nan", "drop", "spike", "stall")
"""Faults the simulated device injects (softproxy.devices.simulated.FAULT_KINDS)."""

def _keyframe(value):
    """Before the tuple check: 5 finite numbers."""
    items = value if isinstance(value, (list, tuple)) else ()
    if len(items) != 5 or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                                  for v in items):
        raise PydanticCustomError("input", "5 finite numbers [t, x, y, z, twist]")
    return tuple(float(v) for v in items)


Keyframe = Annotated[tuple[float, float, float, float, float], BeforeValidator(_keyframe),
                     Field(description="[t (s), x, y, z (m, device frame), twist (rad)], t increasing")]
Probability = quantity("", "a probability per read", low=0.0, high=1.0, says="a probability per read in [0, 1]")
WorkspaceScale = quantity("", "device position × scale + offset is the world position", low=0.0, open_low=True)
WorkspaceOffset = vector3("added to the scaled device position", "m")


class SimFinger(Table):
    """[[device.finger]]: one scripted finger."""

    keyframes: Annotated[list[Keyframe], Field(min_length=1)]


class SimDeviceTable(Table):
    """[device] of the simulated device (`type = "sim"`): scripted fingers, noise, latency, faults."""

    type: Literal["sim"]
    noise_m: quantity("m", "position noise, standard deviation", low=0.0) = 0.0
    noise_rad: quantity("rad", "twist noise, standard deviation", low=0.0) = 0.0
    latency_s: quantity("s", "a sample is this old when read", low=0.0) = 0.0
    quantum_m: quantity("m", "encoder resolution of a position (0: none)", low=0.0) = 0.0
    quantum_rad: quantity("rad", "encoder resolution of the twist (0: none)", low=0.0) = 0.0
    max_force_N: quantity("N", "the motor saturates here", low=0.0, optional=True) = None
    max_torque_Nm: quantity("N·m", "the motor saturates here", low=0.0, optional=True) = None
    max_stiffness_N_per_m: quantity("N/m", "the stiffest coupling it renders stably: a stiffer finger is capped "
                                    "(default: no limit)", low=10.0, optional=True) = None
    max_damping_Ns_per_m: quantity("N·s/m", "the most coupling damping it renders stably (default: no limit)",
                                   low=0.0, optional=True) = None
    seed: count("seed of the noise and faults") = 0
    finger: Annotated[list[SimFinger], Field(min_length=1)]
    faults: dict[Literal[SIM_FAULT_KINDS], Probability] = {}


class HidDeviceTable(Table):
    """[device] of a HID device (`type = "hid"`), described by a profile."""

    type: Literal["hid"]
    profile: text("the name of a HID profile (e.g. \"spacemouse\") or a path to one")
    path: Optional[text("a HID device path (a string, see `softproxy devices`)", description=(
        "the HID device path (`softproxy devices`); default: the first device the profile matches"))] = None
    mode: Optional[choice(HID_MODES, "motion mode (default: the profile's)")] = None
    workspace_scale: WorkspaceScale = 1.0
    workspace_offset: WorkspaceOffset = (0.0, 0.0, 0.0)
    workspace_half_m: vector3("rate mode: half the workspace box", "m", low=0.0, open_low=True) = (0.1, 0.1, 0.1)
    twist_limit_rad: quantity("rad", "rate mode: the twist is kept within ±this", low=0.0, open_low=True) = math.pi
    stale_ms: quantity("ms", "periodic devices: invalid after this long without a report (default: the profile's)",
                       low=0.0, optional=True) = None
    max_force_N: quantity("N", "lowers the profile's limit (never raises it)", low=0.0, optional=True) = None
    max_torque_Nm: quantity("N·m", "lowers the profile's limit (never raises it)", low=0.0, optional=True) = None


class ForceDimensionDeviceTable(Table):
    """[device] of a Force Dimension device (`type = "forcedimension"`, the vendor's SDK)."""

    type: Literal["forcedimension"]
    index: Optional[count("which connected device (give index or serial)", low=0)] = None
    serial: Optional[count("the device's serial number (give index or serial)", low=0)] = None
    gripper: Annotated[Union[Annotated[bool, Tag("flag")], Annotated[Literal["auto", "on", "off"], Tag("choice")]],
                       Discriminator(lambda v: "flag" if isinstance(v, bool) else "choice" if v in ("auto", "on", "off")
                                     else None, custom_error_type="input",
                                     custom_error_message="true, false, \"auto\", \"on\" or \"off\"")] = Field(
        "auto", description="the gripper turns the finger (true: \"on\", false: \"off\")")
    gripper_axis: choice(("x", "y", "z"), "the finger axis the gripper turns about") = "z"
    workspace_scale: WorkspaceScale = 1.0
    workspace_offset: WorkspaceOffset = (0.0, 0.0, 0.0)
    max_force_N: quantity("N", "lowers the device's limit (never raises it)", low=0.0, optional=True) = None
    max_torque_Nm: quantity("N·m", "lowers the device's limit (never raises it)", low=0.0, optional=True) = None
    max_gripper_force_N: quantity("N", "lowers the gripper's limit", low=0.0, optional=True) = None
    stall_ms: quantity("ms", "a force not renewed for this long is replaced by zero (0: never)", low=0.0,
                       high=1000.0) = 50.0


class OpenHapticsDeviceTable(Table):
    """[device] of a 3D Systems Touch (`type = "openhaptics"`, the OpenHaptics SDK)."""

    type: Literal["openhaptics"]
    device_name: text("the device's name in Touch Setup (e.g. \"Default Device\")") = "Default Device"
    workspace_scale: WorkspaceScale = 1.0
    workspace_offset: WorkspaceOffset = (0.0, 0.0, 0.0)
    max_force_N: quantity("N", "lowers the device's peak force (never raises it)", low=0.0, optional=True) = None
    stale_ms: quantity("ms", "a sample older than this is invalid", low=0.0, high=1000.0, open_low=True,
                       optional=True) = None
    command_timeout_ms: quantity("ms", "a scheduler call not answered in this long is a fault", low=0.0,
                                 high=1000.0, open_low=True, optional=True) = None


class HaplyDeviceTable(Table):
    """[device] of a Haply Inverse3 with an optional VerseGrip (`type = "haply"`, the HaplyHardwareAPI binding)."""

    type: Literal["haply"]
    port: Optional[text("the Inverse3's serial port, e.g. \"/dev/ttyACM0\" (give port or index)")] = None
    index: Optional[count("which detected Inverse3 (give port or index)", low=0)] = None
    grip: text("\"auto\" (the first VerseGrip detected, if any), \"off\", or the VerseGrip's serial port") = "auto"
    twist_axis: choice(("x", "y", "z"), "the VerseGrip's axis the finger's twist turns about") = "z"
    workspace_scale: WorkspaceScale = 1.0
    workspace_offset: WorkspaceOffset = (0.0, 0.0, 0.0)
    max_force_N: quantity("N", "lowers the device's limit (never raises it)", low=0.0, optional=True) = None
    stall_ms: quantity("ms", "a force not renewed for this long is replaced by zero (0: never)", low=0.0,
                       high=1000.0) = 50.0
    timeout_ms: quantity("ms", "a serial exchange not answered in this long is a fault", low=0.0, high=1000.0,
                         open_low=True) = 20.0
    grip_stale_ms: quantity("ms", "a VerseGrip reading older than this makes the sample invalid", low=0.0,
                            high=5000.0, open_low=True) = 100.0


class ReplayDeviceTable(Table):
    """[device] that replays a recording (`type = "replay"`)."""

    type: Literal["replay"]
    path: text("the recording file's path (softproxy run --record)")


DEVICE_TABLES = {"sim": SimDeviceTable, "hid": HidDeviceTable, "forcedimension": ForceDimensionDeviceTable,
                 "openhaptics": OpenHapticsDeviceTable, "haply": HaplyDeviceTable, "replay": ReplayDeviceTable}
"""The declared [device] table of each shipped device type."""
DeviceTable = Annotated[Union[tuple(DEVICE_TABLES.values())], Field(discriminator="type")]



# ---------------------------------------------------------------------------------------------
# JSON Schema for editors (`softproxy schema`)


def json_schemas() -> dict[str, dict]:
    """The JSON Schema (draft 2020-12) of each input file, by file name: a scene TOML, a HID
    profile, a [device] table. A scene's [device] may also be a plugin device type's own table."""
    device = TypeAdapter(DeviceTable).json_schema()
    scene = SceneFile.model_json_schema()
    scene.setdefault("$defs", {}).update(device.get("$defs", {}))
    plugin = {"type": "object", "description": "the table of a device type installed as a plugin",
              "properties": {"type": {"type": "string", "not": {"enum": list(DEVICE_TABLES)}}}, "required": ["type"]}
    shipped = {k: v for k, v in device.items() if k != "$defs"}
    one = {"anyOf": [shipped, plugin]}
    several = {"type": "array", "items": one, "minItems": 1, "maxItems": MAX_DEVICES,
               "description": "[[device]]: one table per device; a finger names its device by index (`device`)"}
    scene["properties"]["device"] = {"description": DeviceTableAny.__doc__, "anyOf": [one, several]}
    schemas = {"scene.schema.json": scene, "hid_profile.schema.json": HidProfileFile.model_json_schema(),
               "device.schema.json": device}
    for name, js in schemas.items():
        js["$schema"] = "https://json-schema.org/draft/2020-12/schema"
        js.setdefault("title", name.split(".")[0])
    return schemas


def write_json_schemas(folder) -> list[Path]:
    """Write `json_schemas()` into `folder` (made if missing); the files written."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = []
    for name, js in json_schemas().items():
        path = folder / name
        path.write_text(json.dumps(js, indent=1, ensure_ascii=False) + "\n", encoding="utf-8")
        written.append(path)
    return written
