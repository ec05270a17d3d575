"""HID device profiles, and the pure functions that parse input reports and build output reports.

A profile is a TOML file (shipped ones in `devices/profiles/`, format in
`devices/profiles/README.md`) that says which USB ids it matches, where each number sits
in the device's input reports, how it converts to SI units, which device axis is which
axis of the finger, and, for a device that renders force, how a force and a torque are
packed into its output report. A user adds a device by writing a profile, not code.

Everything here is a pure function of its arguments, because HID reports are untrusted
input (README, "Safety"):

* `parse_input(profile, data, mode)` turns one input report (bytes as `hid.device.read`
  returns them: report id first for a numbered report) into SI values. On a truncated,
  oversized, empty or non-finite report it raises `ReportError` (a ValueError) and nothing
  else; it never returns NaN or Inf. A report id the profile does not use gives None.
* `build_output(profile, sequence, fx, fy, fz, tx, ty, tz, enable)` packs a force (N) and a
  torque (N·m) into the output report's bytes (report id first, as `hid.device.write`
  wants). Non-finite input gives a zero-force report with enable = 0; everything else is
  clamped to the profile's max_force / max_torque and to each field's count limits.
* `load_profile(name_or_path)` / `parse_profile(doc, source)` validate a profile; every
  error is a `ProfileError` (a ValueError) naming the file, the field and what was expected.
  Each field's type and bounds are declared in `softproxy.schema.HidProfileFile` (whose JSON
  Schema `softproxy schema` writes); what depends on other fields is checked here.
  Limits are bounded, not only finite: `max_force` <= MAX_FORCE_N (100 N), `max_torque` <=
  MAX_TORQUE_NM (10 N·m), an input `scale` / `rate_scale` <= MAX_INPUT_SCALE (1e3 SI per
  count), an output `scale` <= MAX_OUTPUT_SCALE (1e9 counts per N or N·m). A finger-sized
  device renders a few newtons; a number beyond these is a typo or a unit slip, refused.
* `load_profiles()` loads every profile found by name and says which file shadows which:
  a profile in `$SOFTPROXY_HID_PROFILES` named like a shipped one (or like one in a later
  folder) wins - that is how a user adapts a shipped profile - but never silently
  (`ProfileSet.shadowing`; `softproxy devices` prints a warning line for each).

Report offsets count bytes of the report's payload, i.e. after the report id byte of a
numbered report (the layout a firmware author writes in the HID report descriptor).
"""

from __future__ import annotations

import math
import os
import struct
import tomllib
from dataclasses import dataclass, field
from pathlib import Path
from typing import NamedTuple

from softproxy import schema
from softproxy.input_error import InputError, must_be
from softproxy.schema import MAX_FORCE_N, MAX_INPUT_SCALE, MAX_OUTPUT_SCALE, MAX_TORQUE_NM  # noqa: F401

PROFILE_DIR = Path(__file__).resolve().parent / "profiles"
"""The shipped profiles."""

PROFILE_PATH_ENV = "SOFTPROXY_HID_PROFILES"
"""Environment variable: extra folders of profiles (os.pathsep-separated), searched first."""

# type name -> (struct code, bytes, kind) ; kind: "int" signed, "uint" unsigned, "float"
TYPES = {
    "int8": ("b", 1, "int"), "uint8": ("B", 1, "uint"),
    "int16": ("h", 2, "int"), "uint16": ("H", 2, "uint"),
    "int32": ("i", 4, "int"), "uint32": ("I", 4, "uint"),
    "float32": ("f", 4, "float"),
}
ENDIAN = {"little": "<", "big": ">"}
RAW_FIELDS = ("sequence", "status", "buttons")
"""Input field names with a fixed meaning: unsigned integers, read raw (no scale)."""
AXES = ("x", "y", "z", "twist")
WRENCH = ("fx", "fy", "fz", "tx", "ty", "tz")
OUTPUT_SOURCES = WRENCH + ("twist", "sequence", "enable")
MODES, REPORTING = schema.HID_MODES, schema.HID_REPORTING
FLOAT32_MAX = 3.4028234663852886e38
MAX_PROFILE_BYTES = 1 << 20
"""Largest profile file read (bytes): the shipped ones are under 4 KiB."""


class ProfileError(ValueError):
    """A profile that cannot be used; the message names the file, the field and what was expected."""


class ReportError(ValueError):
    """A malformed input report: empty, truncated, oversized, or carrying a non-finite float."""


class InputReport(NamedTuple):
    """One parsed input report: its id, its payload length, and its field values.

    `values` maps field name to value: SI units (m, rad; m/s, rad/s in rate mode) for
    scaled fields, raw unsigned integers for sequence / status / buttons.
    """

    report_id: int
    size: int
    values: dict


@dataclass(frozen=True)
class InputField:
    name: str
    offset: int
    type: str
    endian: str
    scale: float               # SI per count in position mode (1.0 for raw fields)
    rate_scale: float | None   # SI per count in rate mode (m/s, rad/s); None: no rate mode
    deadband: float            # |counts| <= deadband read as 0

    @property
    def raw(self) -> bool:
        return self.name in RAW_FIELDS


@dataclass(frozen=True)
class InputLayout:
    """One input report layout. Several may share an id with different sizes (variants)."""

    id: int
    size: int
    fields: tuple[InputField, ...]


@dataclass(frozen=True)
class OutputField:
    name: str
    offset: int
    type: str
    endian: str
    source: str      # fx fy fz tx ty tz twist sequence enable
    sign: float      # +1 or -1 (a leading '-' on the source)
    scale: float     # counts per N (force) or per N·m (torque); 1 for sequence / enable
    lo: float        # saturation limits in counts
    hi: float


@dataclass(frozen=True)
class OutputLayout:
    id: int
    size: int
    fields: tuple[OutputField, ...]


@dataclass(frozen=True)
class Match:
    """USB ids a profile claims; usage_page / usage / interface narrow a multi-interface device."""

    vendor_id: int
    product_id: int
    model: str = ""
    usage_page: int | None = None
    usage: int | None = None
    interface: int | None = None

    def matches(self, info: dict) -> bool:
        """True when an `hid.enumerate()` entry is this device."""
        if info.get("vendor_id") != self.vendor_id or info.get("product_id") != self.product_id:
            return False
        for key, want in (("usage_page", self.usage_page), ("usage", self.usage),
                          ("interface_number", self.interface)):
            if want is not None and info.get(key) != want:
                return False
        return True


@dataclass(frozen=True)
class Profile:
    """A validated device profile (see the module docstring and devices/profiles/README.md)."""

    name: str
    description: str
    source: str                              # file it came from
    mode: str                                # default motion mode
    modes: tuple[str, ...]                   # modes the axis fields support
    max_force: float                         # N; 0 = renders no force
    max_torque: float                        # N·m; 0 = renders no torque
    finger_axis: tuple[float, float, float]  # unit axis in the sample frame: what `twist` is about
    matches: tuple[Match, ...]
    numbered: bool                           # input reports start with a report id byte
    max_bytes: int                           # longest input report accepted, id byte included
    reporting: str                           # "periodic" or "on_change"
    stale_ms: float                          # periodic: sample stale after this long without a report
    reports: dict                            # id -> tuple[InputLayout, ...], longest first
    axes: dict                               # "x"/"y"/"z"/"twist" -> (field name, sign)
    status_set: int                          # status bits that must be 1 (e.g. calibrated)
    status_clear: int                        # status bits that must be 0 (e.g. fault)
    has_status: bool
    sequence_bits: int                       # width of the sequence field (0: none)
    output: OutputLayout | None
    max_stiffness: float | None = None       # N/m the device renders stably (softproxy.stiffness_cap); None: unknown
    max_damping: float | None = None         # N·s/m, likewise
    plans: dict = field(default_factory=dict, repr=False, compare=False)  # parse plans per mode (cache)

    @property
    def renders_force(self) -> bool:
        return self.output is not None

    def ids(self) -> list[str]:
        """The USB ids this profile matches, as 'vvvv:pppp'."""
        return [f"{m.vendor_id:04x}:{m.product_id:04x}" for m in self.matches]


# ---------------------------------------------------------------------------------------
# loading and validation


def _fail(source: str, field: str, expected: str, got) -> ProfileError:
    """The one-line error of softproxy.schema's format, as a ProfileError."""
    return ProfileError(str(must_be(field, expected, got, source=source)))


def _type_range(type_name: str) -> tuple[float, float]:
    code, size, kind = TYPES[type_name]
    if kind == "float":
        return -FLOAT32_MAX, FLOAT32_MAX
    bits = 8 * size
    if kind == "uint":
        return 0, (1 << bits) - 1
    return -(1 << (bits - 1)), (1 << (bits - 1)) - 1


def _parse_signed_name(text: str) -> tuple[str, float]:
    text = text.strip()
    if text.startswith("-"):
        return text[1:].strip(), -1.0
    if text.startswith("+"):
        return text[1:].strip(), 1.0
    return text, 1.0


def _ends_within(source: str, where: str, spec, limit: int) -> None:
    """A field's bytes lie within the report's `limit` payload bytes."""
    if spec.offset + TYPES[spec.type][1] > limit:
        raise _fail(source, f"{where}.offset", f"such that the {spec.type} ends within the report's "
                    f"{limit} payload bytes", spec.offset)


def _parse_input_field(source: str, where: str, name: str, spec: schema.HidInputField, given: set,
                       size: int) -> InputField:
    if not name.isidentifier():
        raise _fail(source, where, "named by an identifier (letters, digits, _)", name)
    _ends_within(source, where, spec, size)
    if name in RAW_FIELDS:
        extra = sorted(given - {"offset", "type", "endian"})
        if extra:
            raise ProfileError(f"{source}: {where} has unknown field(s) {extra}; a raw `{name}` field takes "
                               "offset, type and endian only")
        if TYPES[spec.type][2] != "uint":
            raise _fail(source, f"{where}.type", f"an unsigned integer type (uint8/uint16/uint32) for `{name}`",
                        spec.type)
        return InputField(name, spec.offset, spec.type, spec.endian, 1.0, 1.0, 0.0)
    return InputField(name, spec.offset, spec.type, spec.endian, spec.scale, spec.rate_scale, spec.deadband)


def _parse_output_field(source: str, where: str, name: str, spec: schema.HidOutputField, size: int) -> OutputField:
    _ends_within(source, where, spec, size)
    src_text = name if spec.source is None else spec.source
    src, sign = _parse_signed_name(src_text)
    if src not in OUTPUT_SOURCES or (sign < 0 and src in ("sequence", "enable")):
        raise _fail(source, f"{where}.source", f"one of {list(OUTPUT_SOURCES)} (a wrench source may carry a '-')",
                    src_text)
    tlo, thi = _type_range(spec.type)
    kind = TYPES[spec.type][2]
    if src in ("sequence", "enable"):
        if kind != "uint":
            raise _fail(source, f"{where}.type", f"an unsigned integer type for a `{src}` field", spec.type)
        if spec.scale is not None or spec.min is not None or spec.max is not None:
            raise ProfileError(f"{source}: {where}: a `{src}` field takes no scale, min or max")
        return OutputField(name, spec.offset, spec.type, spec.endian, src, 1.0, 1.0, tlo, thi)
    if spec.scale is None:
        raise ProfileError(f"{source}: {where}.scale is required (counts per N, or per N·m for a torque)")
    if kind == "int":  # symmetric by default: -32767..32767, so that -x is representable whenever x is
        tlo = -thi
    for key in ("min", "max"):
        v = getattr(spec, key)
        if v is not None and not tlo <= v <= thi:
            raise _fail(source, f"{where}.{key}", f"a number within the {spec.type} range [{tlo:g}, {thi:g}]", v)
    lo = tlo if spec.min is None else spec.min
    hi = thi if spec.max is None else spec.max
    if not lo <= 0 <= hi:
        raise ProfileError(f"{source}: {where}: min must be <= 0 <= max (zero force must be representable), "
                           f"got min = {lo!r}, max = {hi!r}")
    if kind != "float":
        lo, hi = math.ceil(lo), math.floor(hi)
    return OutputField(name, spec.offset, spec.type, spec.endian, src, sign, spec.scale, lo, hi)


def _axis_vector(text: str) -> tuple[float, float, float]:
    name, sign = _parse_signed_name(text)  # "x", "y" or "z" (the schema checked it)
    return tuple(sign if a == name else 0.0 for a in ("x", "y", "z"))


def parse_profile(doc: dict, source: str = "<profile>") -> Profile:
    """Validate a profile given as a dict (a parsed TOML document); errors name source and field.

    Each field's type and bounds are declared in `softproxy.schema.HidProfileFile`; what depends
    on other fields is checked here."""
    if not isinstance(doc, dict):
        raise _fail(source, "profile", "a table", doc)
    try:
        p = schema.validate(schema.HidProfileFile, doc, source=source)
    except InputError as exc:
        raise ProfileError(str(exc)) from None
    stem = Path(source).stem if source.endswith(".toml") else "profile"
    name = stem if p.name is None else p.name
    matches = [Match(m.vendor_id, m.product_id, m.model, m.usage_page, m.usage, m.interface) for m in p.match]

    # [input]
    inp = p.input
    max_bytes, reporting = inp.max_bytes, inp.reporting
    stale_ms = (50.0 if reporting == "periodic" else 0.0) if inp.stale_ms is None else inp.stale_ms
    reports: dict[int, list[InputLayout]] = {}
    field_types: dict[str, str] = {}
    for i, r in enumerate(inp.report):
        where = f"input.report[{i}]"
        rid, size = r.id, r.size
        if size + (1 if rid else 0) > max_bytes:
            raise _fail(source, f"{where}.size", f"at most input.max_bytes = {max_bytes} bytes with the report id",
                        size)
        parsed = []
        for fname, spec in r.fields.items():
            given = set(doc["input"]["report"][i]["fields"][fname])
            f = _parse_input_field(source, f"{where}.fields.{fname}", fname, spec, given, size)
            if fname == "sequence" and field_types.setdefault(fname, f.type) != f.type:
                raise _fail(source, f"{where}.fields.{fname}.type", f"{field_types[fname]}, as in the other "
                            "reports (the counter's width decides where it wraps)", f.type)
            parsed.append(f)
        variants = reports.setdefault(rid, [])
        if any(v.size == size for v in variants):
            raise _fail(source, f"{where}.size", f"different from the other reports with id {rid} (variants are "
                        "told apart by their size)", size)
        variants.append(InputLayout(rid, size, tuple(parsed)))
    if 0 in reports and len(reports) > 1:
        raise _fail(source, "input.report[].id", "all 0 (unnumbered) or all 1..255 (numbered), not a mix",
                    sorted(reports))
    numbered = 0 not in reports
    reports_sorted = {rid: tuple(sorted(v, key=lambda layout: -layout.size)) for rid, v in reports.items()}

    # [axes]
    axes = {}
    by_name = {}
    for layouts in reports_sorted.values():
        for layout in layouts:
            for f in layout.fields:
                by_name.setdefault(f.name, f)
    for axis in AXES:
        text = getattr(p.axes, axis)
        if text is None:
            continue
        fname, sign = _parse_signed_name(text)
        if fname not in by_name or by_name[fname].raw:
            raise _fail(source, f"axes.{axis}", "\"field\" or \"-field\" naming a scaled input field (have: "
                        f"{sorted(n for n in by_name if n not in RAW_FIELDS)})", text)
        axes[axis] = (fname, sign)
    modes = ["position"]
    rate_ok = True
    for fname, _ in axes.values():
        for layouts in reports_sorted.values():
            for layout in layouts:
                for f in layout.fields:
                    if f.name == fname and f.rate_scale is None:
                        rate_ok = False
    if rate_ok:
        modes.append("rate")
    if p.mode not in modes:
        raise ProfileError(f"{source}: mode = \"rate\" needs a rate_scale on every field named in [axes]")

    # [status]
    has_status = "status" in by_name
    if doc.get("status") and not has_status:
        raise ProfileError(f"{source}: [status] needs an input field named `status`")
    status_set, status_clear = p.status.require_set, p.status.require_clear
    if status_set & status_clear:
        raise _fail(source, "status.require_clear", "disjoint from require_set", status_clear)
    sequence_bits = 8 * TYPES[by_name["sequence"].type][1] if "sequence" in by_name else 0

    # [output]
    output = None
    if p.output is not None:
        out = p.output
        parsed = tuple(_parse_output_field(source, f"output.fields.{n}", n, s, out.size) for n, s in out.fields.items())
        spans = sorted((f.offset, f.offset + TYPES[f.type][1], f.name) for f in parsed)
        for (a0, a1, an), (b0, b1, bn) in zip(spans, spans[1:]):
            if b0 < a1:
                raise ProfileError(f"{source}: output.fields.{bn} overlaps output.fields.{an}")
        output = OutputLayout(out.id, out.size, parsed)
    sources = {f.source for f in output.fields} if output else set()
    if p.max_force > 0 and not sources & {"fx", "fy", "fz"}:
        raise _fail(source, "max_force", "0 for a profile whose [output] carries no force (fx/fy/fz)", p.max_force)
    if p.max_torque > 0 and not sources & {"tx", "ty", "tz", "twist"}:
        raise _fail(source, "max_torque", "0 for a profile whose [output] carries no torque (tx/ty/tz/twist)",
                    p.max_torque)

    return Profile(name=name.strip(), description=p.description, source=source, mode=p.mode, modes=tuple(modes),
                   max_force=p.max_force, max_torque=p.max_torque, finger_axis=_axis_vector(p.finger_axis),
                   matches=tuple(matches), numbered=numbered, max_bytes=max_bytes, reporting=reporting,
                   stale_ms=stale_ms, reports=reports_sorted, axes=axes, status_set=status_set,
                   status_clear=status_clear, has_status=has_status, sequence_bits=sequence_bits, output=output,
                   max_stiffness=p.max_stiffness, max_damping=p.max_damping)


def profile_dirs() -> list[Path]:
    """Folders searched for profiles by name: $SOFTPROXY_HID_PROFILES first, then the shipped ones."""
    dirs = [Path(p) for p in os.environ.get(PROFILE_PATH_ENV, "").split(os.pathsep) if p.strip()]
    dirs.append(PROFILE_DIR)
    return dirs


def find_profile(name_or_path: str, base: Path | None = None) -> Path:
    """The file of a profile given by name (searched in `profile_dirs()`) or by path.

    A value containing a path separator or ending in .toml is a path, relative to `base`
    (e.g. the scene's folder) when given.
    """
    text = str(name_or_path)
    if text.endswith(".toml") or "/" in text or os.sep in text:
        p = Path(text).expanduser()
        if not p.is_absolute() and base is not None:
            p = base / p
        if not p.is_file():
            raise ProfileError(f"{p}: profile file not found")
        return p
    for d in profile_dirs():
        p = d / f"{text}.toml"
        if p.is_file():
            return p
    raise ProfileError(f"no HID profile named {text!r}; have: {', '.join(available_profiles()) or 'none'} "
                       f"(searched {', '.join(str(d) for d in profile_dirs())})")


def load_profile(name_or_path, base: Path | None = None) -> Profile:
    """Load and validate a profile by name or path (`find_profile`); a Profile passes through."""
    if isinstance(name_or_path, Profile):
        return name_or_path
    path = find_profile(name_or_path, base)
    try:
        with open(path, "rb") as fh:
            data = fh.read(MAX_PROFILE_BYTES + 1)
    except OSError as exc:
        raise ProfileError(f"{path}: cannot read: {exc.strerror or exc}") from None
    if len(data) > MAX_PROFILE_BYTES:
        raise ProfileError(f"{path}: over {MAX_PROFILE_BYTES} bytes; a profile is a short TOML file")
    try:
        doc = tomllib.loads(data.decode("utf-8"))
    except UnicodeDecodeError as exc:
        raise ProfileError(f"{path}: not UTF-8 text (byte {exc.start} is {data[exc.start]:#04x}); a profile is a "
                           f"TOML file in UTF-8") from None
    except tomllib.TOMLDecodeError as exc:
        raise ProfileError(f"{path}: not valid TOML: {exc}") from None
    except RecursionError:
        raise ProfileError(f"{path}: not valid TOML: nested too deeply") from None
    return parse_profile(doc, str(path))


def available_profiles() -> list[str]:
    """Names (file stems) of the profiles found in `profile_dirs()`."""
    names = set()
    for d in profile_dirs():
        if d.is_dir():
            names.update(p.stem for p in d.glob("*.toml"))
    return sorted(names)


class Shadowing(NamedTuple):
    """A profile file that hides another of the same name: `source` is used, `shadowed` is not."""

    name: str       # the name both files answer to (their file stem)
    source: str     # the file found first (an earlier folder of `profile_dirs()`)
    shadowed: str   # the file it hides (e.g. the shipped one)

    def warning(self) -> str:
        """One line for the user: which file is used, which is hidden, and how to keep both."""
        return (f"profile {self.name!r} from {self.source} shadows {self.shadowed} (${PROFILE_PATH_ENV} is "
                f"searched first); rename {Path(self.source).name} to keep both")


class ProfileSet(NamedTuple):
    """What `load_profiles()` found: usable profiles, broken ones (one line each), shadowed files."""

    profiles: list
    errors: list
    shadowing: list


def load_profiles() -> ProfileSet:
    """Every profile found by name; a broken one is reported (`errors`), not fatal.

    When two folders hold a profile of the same name, the earlier folder's wins (the one
    `load_profile(name)` finds) and the pair is reported in `shadowing`, never dropped silently.
    """
    profiles, errors, shadowing = [], [], []
    first: dict[str, Path] = {}
    for d in profile_dirs():
        if not d.is_dir():
            continue
        for p in sorted(d.glob("*.toml")):
            if p.stem in first:
                if p.resolve() != first[p.stem].resolve():  # a folder listed twice hides nothing
                    shadowing.append(Shadowing(p.stem, str(first[p.stem]), str(p)))
                continue
            first[p.stem] = p
            try:
                profiles.append(load_profile(str(p)))
            except ProfileError as exc:
                errors.append(str(exc))
    return ProfileSet(profiles, errors, shadowing)


# ---------------------------------------------------------------------------------------
# input reports

_UNPACKERS: dict[tuple[str, str], struct.Struct] = {
    (t, e): struct.Struct(ENDIAN[e] + TYPES[t][0]) for t in TYPES for e in ENDIAN
}


def _plan(profile: Profile, mode: str) -> dict:
    """Per report id: [(size, [(name, unpack_from, offset, factor, deadband, is_float, raw)])], longest first."""
    plan = profile.plans.get(mode)
    if plan is None:
        plan = {}
        for rid, layouts in profile.reports.items():
            plan[rid] = [(layout.size, [(f.name, _UNPACKERS[(f.type, f.endian)].unpack_from, f.offset,
                                         f.rate_scale if (mode == "rate" and f.rate_scale is not None) else f.scale,
                                         f.deadband, TYPES[f.type][2] == "float", f.raw)
                                        for f in layout.fields])
                         for layout in layouts]
        profile.plans[mode] = plan
    return plan


def parse_input(profile: Profile, data, mode: str = "position") -> InputReport | None:
    """Parse one input report into SI values (see `InputReport`); None for an id the profile does not use.

    `data` is the report as `hid.device.read` returns it (bytes or a list of ints), report
    id first when the profile's reports are numbered. A report may be longer than its
    layout (hidapi on Windows pads every report to the device's longest): the longest
    layout of that id that fits is used and the rest ignored, up to `max_bytes`.
    Raises ReportError, and only ReportError, on anything malformed; never returns NaN/Inf.
    """
    try:
        buf = data if isinstance(data, bytes) else bytes(data)
    except (TypeError, ValueError, OverflowError) as exc:
        raise ReportError(f"not a byte string: {exc}") from None
    n = len(buf)
    if n == 0:
        raise ReportError("empty report")
    if n > profile.max_bytes:
        raise ReportError(f"oversized report: {n} bytes, {profile.name} sends at most {profile.max_bytes}")
    plan = _plan(profile, mode)
    if profile.numbered:
        rid, start = buf[0], 1
    else:
        rid, start = 0, 0
    variants = plan.get(rid)
    if variants is None:
        return None
    payload = n - start
    for size, fields in variants:
        if size <= payload:
            break
    else:
        raise ReportError(f"truncated report id {rid}: {payload} payload bytes, needs at least {variants[-1][0]}")
    values = {}
    for name, unpack, offset, factor, deadband, is_float, raw in fields:
        v = unpack(buf, start + offset)[0]
        if raw:
            values[name] = v
            continue
        if is_float and not math.isfinite(v):
            raise ReportError(f"report id {rid}: field {name} is {v!r} (non-finite float32)")
        if -deadband <= v <= deadband:
            values[name] = 0.0
            continue
        v = v * factor
        if not math.isfinite(v):  # a float32 near its max times a large scale
            raise ReportError(f"report id {rid}: field {name} overflows once scaled")
        values[name] = v
    return InputReport(rid, payload, values)


# ---------------------------------------------------------------------------------------
# output reports


_SEQUENCE, _ENABLE = -1, -2
_SOURCE_INDEX = {"fx": 0, "fy": 1, "fz": 2, "tx": 3, "ty": 4, "tz": 5, "twist": 6,
                 "sequence": _SEQUENCE, "enable": _ENABLE}


def _output_plan(profile: Profile) -> list:
    """[(pack_into, offset in the report, source index, sign*scale, lo, hi, integer?)] per output field."""
    plan = []
    for f in profile.output.fields:
        is_int = TYPES[f.type][2] != "float"
        lo, hi = (int(f.lo), int(f.hi)) if is_int else (f.lo, f.hi)
        if f.source == "sequence":
            hi = (1 << (8 * TYPES[f.type][1])) - 1  # the counter's mask
        plan.append((_UNPACKERS[(f.type, f.endian)].pack_into, 1 + f.offset, _SOURCE_INDEX[f.source],
                     f.sign * f.scale, lo, hi, is_int))
    return plan


_SNAP_COUNTS = 1e-9
"""A value this close to a whole count (in counts) is that count: float noise (5 N x 1000
counts/N giving 4999.999999999999) must not cost a whole count."""
_CLAMP_MARGIN = 1.0 - 1e-12
"""Where the fallback aims, as a fraction of the limit (see `build_output`)."""


def _toward_zero(v: float, is_int: bool, snap: bool):
    """A field's value in counts, rounded toward zero: integers truncated (after snapping float
    noise to the whole count when `snap`), float32 to the float32 at or inside `v`."""
    if not is_int:
        return _float32_toward_zero(v)
    n = round(v)
    if snap and abs(v - n) <= _SNAP_COUNTS:
        return int(n)
    return int(v)


def _float32_toward_zero(v: float) -> float:
    """The float32 nearest `v` that is not farther from zero than `v` (packing rounds to nearest)."""
    f = _F32.unpack(_F32.pack(v))[0]
    if abs(f) > abs(v):  # then f != 0: one less in its bit pattern is one float32 nearer zero, either sign
        f = _F32.unpack(_U32.pack(_U32.unpack(_F32.pack(f))[0] - 1))[0]
    return f


_F32, _U32 = struct.Struct("<f"), struct.Struct("<I")


def _wrench_counts(plan: list, vals: list[float], axis, snap: bool) -> tuple[list, float, float]:
    """Each wrench field's value (counts), and |F| (N) and |T| (N·m) as a device decodes them
    (fields of one source add up, as `parse_output` readers would render them)."""
    counts = []
    force, torque = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
    for _, _, index, factor, lo, hi, is_int in plan:
        if index < 0:
            counts.append(None)
            continue
        v = factor * vals[index]
        v = _toward_zero(lo if v < lo else hi if v > hi else v, is_int, snap)
        counts.append(v)
        rendered = v / factor
        if index < 3:
            force[index] += rendered
        elif index < 6:
            torque[index - 3] += rendered
        else:  # the torque about the finger axis
            for i in range(3):
                torque[i] += rendered * axis[i]
    return counts, math.hypot(*force), math.hypot(*torque)


def zero_output(profile: Profile, sequence: int = 0) -> bytes:
    """The zero-force, motors-disabled output report (enable = 0)."""
    return build_output(profile, sequence, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, enable=False)


def build_output(profile: Profile, sequence: int, fx: float, fy: float, fz: float,
                 tx: float, ty: float, tz: float, enable: bool = True,
                 max_force: float | None = None, max_torque: float | None = None) -> bytes:
    """The output report (report id byte first, as `hid.device.write` wants it) for a wrench.

    Force (N) and torque (N·m) are in the sample frame. Non-finite input of any component
    gives the zero-force report with enable = 0. Otherwise |F| is clamped to max_force and
    |T| to max_torque (the profile's, or lower ones given here; 0 = nothing rendered), then
    each field to its count limits. `twist` fields carry the torque about the profile's
    finger axis. Counts are rounded toward zero (integers truncated, float32 fields to the
    float32 at or inside the value; a value within `_SNAP_COUNTS` of a whole count is that
    count), and the wrench the report decodes to is checked against the limits: should the
    snap have lifted it over one, it is built again aiming `_CLAMP_MARGIN` under the limits
    without the snap. A device never decodes more than the clamp, not even by a rounding.
    """
    out = profile.output
    if out is None:
        raise ValueError(f"profile {profile.name!r} has no output report (input-only device)")
    fmax, tmax = profile.max_force, profile.max_torque
    if max_force is not None and max_force < fmax:
        fmax = max(0.0, max_force)
    if max_torque is not None and max_torque < tmax:
        tmax = max(0.0, max_torque)
    vals = [fx, fy, fz, tx, ty, tz]
    try:
        finite = all(math.isfinite(v) for v in vals)
    except TypeError:
        finite = False
    if not finite:
        vals = [0.0] * 6
        enable = False
    else:
        vals = [float(v) for v in vals]
    plan = profile.plans.get("output")
    if plan is None:
        plan = profile.plans["output"] = _output_plan(profile)
    axis = profile.finger_axis
    counts = None
    for margin, snap in ((1.0, True), (_CLAMP_MARGIN, False)):
        clamped = list(vals)
        for i0, limit in ((0, fmax * margin), (3, tmax * margin)):
            a, b, c = clamped[i0:i0 + 3]
            m = math.hypot(a, b, c)
            if m > limit:
                k = limit / m if limit > 0.0 and math.isfinite(m) else 0.0  # |F| overflowed: direction unknown
                clamped[i0:i0 + 3] = [a * k, b * k, c * k]
        clamped.append(clamped[3] * axis[0] + clamped[4] * axis[1] + clamped[5] * axis[2])  # 6: about the finger
        counts, force, torque = _wrench_counts(plan, clamped, axis, snap)
        if force <= fmax and torque <= tmax:
            break
    buf = bytearray(1 + out.size)
    buf[0] = out.id
    for (pack, offset, index, _, _, hi, _), v in zip(plan, counts):
        if index == _SEQUENCE:
            v = int(sequence) & hi
        elif index == _ENABLE:
            v = 1 if enable else 0
        pack(buf, offset, v)
    return bytes(buf)


def parse_output(profile: Profile, data) -> dict:
    """Decode an output report back to SI (N, N·m) and raw sequence / enable: for tests and firmware authors.

    Raises ReportError on a report of the wrong id or length.
    """
    out = profile.output
    if out is None:
        raise ReportError(f"profile {profile.name!r} has no output report")
    buf = bytes(data)
    if len(buf) != 1 + out.size or buf[0] != out.id:
        raise ReportError(f"not an output report of {profile.name}: {len(buf)} bytes, id {buf[:1].hex() or '-'}")
    result = {}
    for f in out.fields:
        v = _UNPACKERS[(f.type, f.endian)].unpack_from(buf, 1 + f.offset)[0]
        result[f.name] = v if f.source in ("sequence", "enable") else f.sign * v / f.scale
    return result
