"""Scenes: a MuJoCo MJCF file plus a TOML file that says what the haptic side needs.

A scene is `NAME.toml` beside its MJCF. Tables (every key optional unless marked):

    [scene]            mjcf (required, path relative to the TOML), description, rate_hz (1000;
                       10 to 100000 Hz), duration_s (5.0; at most 24 h), audit (true: track proxy penetration every tick),
                       force_shading (false: mesh contacts report the faceted normal; true:
                       the normal interpolated from the vertex normals)
    [measure]          object (body name), axis ([x, y, z]), start_s: the run reports how far
                       the object turned about the axis from start_s (e.g. the end of a
                       grasp's squeeze) to the end of the run
    [finger_defaults]  any `FingerParams` field, for every finger, and `tactile` / `sensing`
    [[finger]]         one per finger: any `FingerParams` field (name, device_finger, offset, ...),
                       and the fidelity options (softproxy.fingertip_sensors; off unless asked):
                       tactile = true, or a table of rate_hz (100), radius, side (m; default
                         the finger radius and 2 × it), cells (10), supersample (2),
                         youngs_modulus (Pa), indentation ("force" | "depth"), max_substeps
                         (10), pad, distal ([x, y, z] world), history (20 frames)
                       sensing = true, or a table of rate_hz (100), noise ("none" | "gauss" |
                         "quantise"), seed (0), pad, distal, history
                       a finger's table is merged over [finger_defaults]'s; false turns it off
    [device]           handed as is to the device named by its `type` (e.g. "sim")
    [haptics]          what the fingers touch (docs/models.md): exclude (geom or flex names) and
                         exclude_groups (geom groups 0-5) kept out of haptic contact, still in
                         MuJoCo's physics; mesh_surface ("true": a mesh's own triangles;
                         "hull": the convex hull MuJoCo collides it with)

Scenes are found by name in the folders registered under the `softproxy.scene_dirs` entry
point (the shipped `scenes/` folder), or given as a path. Every error names the file, the
field and what was expected. `Scene.load_model` also checks the MJCF against what the servo
loop can run: no RK4 integrator (the loop steps MuJoCo in two halves), no touchable geom of a
type the fingers cannot touch (SDFs) unless [haptics] excludes it, [haptics] names that are
geoms or flexes of the model, a `[measure]` object that is a body.
"""

from __future__ import annotations

import dataclasses
import math
import tomllib
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path

import mujoco

from softproxy.finger import FingerParams
from softproxy.fingertip import MODELS
from softproxy.fingertip_sensors import SensingSpec, TactileSpec
from softproxy.mjcf_files import ModelFileError, check_model_files
from softproxy.geometry import GEOM_GROUPS, MESH_SURFACES, exclusions, unsupported_geoms, unsupported_message
from softproxy.servo import MAX_RATE_HZ, MIN_RATE_HZ

"""Servo rates a run accepts, Hz (what `ServoLoop` can run)."""
MAX_DURATION_S = 86_400.0
"""Longest run a scene (duration_s) or `softproxy run --duration` may ask for, s (24 h); more is
taken for a mistake (a run's recording and video grow with its length)."""

_SCENE_KEYS = {"mjcf", "description", "rate_hz", "duration_s", "audit", "force_shading"}
_MEASURE_KEYS = {"object", "axis", "start_s"}
_HAPTICS_KEYS = {"exclude", "exclude_groups", "mesh_surface"}
_FINGER_KEYS = {f.name for f in dataclasses.fields(FingerParams)}
_OPTION_SPECS = {"tactile": TactileSpec, "sensing": SensingSpec}
_OPTION_KEYS = {name: {f.name for f in dataclasses.fields(spec)} for name, spec in _OPTION_SPECS.items()}
_OPTION_STRINGS = {"indentation", "noise"}
_OPTION_VECTORS = {"pad", "distal"}
_OPTION_INTEGERS = {"cells", "supersample", "max_substeps", "history", "seed"}


class SceneError(ValueError):
    """A scene file that cannot be used; the message names the file and the field."""


@dataclass
class MeasureSpec:
    """Which body's rotation the run reports, about which world axis, from when (s)."""

    object: str
    axis: tuple[float, float, float]
    start_s: float


@dataclass
class Scene:
    name: str
    path: Path
    mjcf: Path
    description: str = ""
    rate_hz: float = 1000.0
    duration_s: float = 5.0
    audit: bool = True
    force_shading: bool = False
    fingers: list[FingerParams] = field(default_factory=list)
    device: dict = field(default_factory=dict)
    measure: MeasureSpec | None = None
    tactile: list[TactileSpec | None] = field(default_factory=list)  # per finger; None = off
    sensing: list[SensingSpec | None] = field(default_factory=list)  # per finger; None = off
    exclude: tuple[str, ...] = ()         # geoms / flexes kept out of haptic contact, by name
    exclude_groups: tuple[int, ...] = ()  # ... and by geom group
    mesh_surface: str = "true"            # "true" | "hull": what a mesh feels like

    def world_options(self) -> dict:
        """The keyword arguments of `World` this scene asks for (force shading, exclusions, mesh surface)."""
        return {"force_shading": self.force_shading, "exclude": self.exclude, "exclude_groups": self.exclude_groups,
                "mesh_surface": self.mesh_surface}

    def load_model(self) -> mujoco.MjModel:
        """Compile the scene's MJCF and check that the servo loop can run it (see the module
        docstring); SceneError naming the file, the culprits and the fix otherwise."""
        try:
            check_model_files(self.mjcf)  # a mesh that is a FIFO would block MuJoCo's loader forever
        except ModelFileError as exc:
            raise SceneError(str(exc)) from None
        try:
            model = mujoco.MjModel.from_xml_path(str(self.mjcf))
        except Exception as exc:  # mujoco raises ValueError with the XML error in it
            raise SceneError(f"{self.mjcf}: MJCF does not compile: {exc}") from None
        self._check_model(model)
        return model

    def _check_model(self, model: mujoco.MjModel) -> None:
        if int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
            # mj_step1/mj_step2 (the two halves the fingers act between) are not valid for RK4
            raise SceneError(f'{self.mjcf}: integrator "RK4" cannot run in the servo loop, which steps MuJoCo '
                             f'in two halves (RK4 has no split step): use <option integrator="implicitfast"/> '
                             f'(or "Euler")')
        try:
            excluded, _ = exclusions(model, self.exclude, self.exclude_groups)
        except ValueError as exc:
            raise SceneError(f"{self.path}: [haptics] {exc} ({self.mjcf.name})") from None
        unsupported = unsupported_geoms(model, excluded)
        if unsupported:
            raise SceneError(f"{self.mjcf}: {unsupported_message(model, unsupported, scene=True)} ({self.path.name})")
        if self.measure is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, self.measure.object) < 0:
            bodies = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in range(1, model.nbody)]
            named = [b for b in bodies if b]
            listed = ", ".join(named[:12]) + (", ..." if len(named) > 12 else "") if named else "none named"
            raise SceneError(f"{self.path}: measure.object {self.measure.object!r} is not a body of "
                             f"{self.mjcf.name}; its bodies: {listed}")


def scene_dirs() -> list[Path]:
    """Folders searched for scenes by name."""
    dirs = []
    for ep in entry_points(group="softproxy.scene_dirs"):
        try:
            dirs.append(Path(ep.load()))
        except Exception:
            continue
    return dirs


def list_scenes() -> list[Path]:
    """Every scene TOML in the registered folders."""
    return sorted(p for d in scene_dirs() for p in d.glob("*.toml"))


def find_scene(name_or_path: str) -> Path:
    """Resolve a scene name (e.g. `two_finger_grasp`) or a path to its TOML file."""
    p = Path(name_or_path)
    if p.suffix == ".toml" and p.is_file():
        return p
    for d in scene_dirs():
        q = d / f"{name_or_path}.toml"
        if q.is_file():
            return q
    known = ", ".join(q.stem for q in list_scenes()) or "none found"
    raise SceneError(f"no scene {name_or_path!r}: give a .toml path or one of: {known}")


def _number(where: str, key: str, value, *, positive=False, non_negative=False, within=None) -> float:
    """`value` as a finite float (> 0, >= 0, in `within` = (low, high, unit) if asked); SceneError otherwise."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{where}: {key} must be a number, got {value!r}")
    try:
        value = float(value)
    except OverflowError:  # a TOML integer past a float's range
        raise SceneError(f"{where}: {key} must be finite, got {value!r}") from None
    if not math.isfinite(value):
        raise SceneError(f"{where}: {key} must be finite, got {value!r}")
    if positive and value <= 0.0:
        raise SceneError(f"{where}: {key} must be > 0, got {value!r}")
    if non_negative and value < 0.0:
        raise SceneError(f"{where}: {key} must be >= 0, got {value!r}")
    if within is not None and not within[0] <= value <= within[1]:
        low, high, unit = within
        raise SceneError(f"{where}: {key} must be between {low:g} and {high:g} {unit}, got {value!r}")
    return value


def _flag(where: str, key: str, value) -> bool:
    if not isinstance(value, bool):
        raise SceneError(f"{where}: {key} must be true or false, got {value!r}")
    return value


def _table(where: str, doc: dict, key: str, allowed: set | None) -> dict:
    t = doc.get(key, {})
    if not isinstance(t, dict):
        raise SceneError(f"{where}: [{key}] must be a table")
    if allowed is not None:
        unknown = set(t) - allowed
        if unknown:
            raise SceneError(f"{where}: [{key}] has unknown field(s) {sorted(unknown)}; expected some of {sorted(allowed)}")
    return t


def _option(where: str, name: str, label: str, default, value):
    """A finger's `tactile` / `sensing` entry (true, false or a table, over the default's) -> spec or None."""
    for v, lab in ((default, f"finger_defaults.{name}"), (value, label)):
        if v is not None and not isinstance(v, (bool, dict)):
            raise SceneError(f"{where}: {lab} must be true, false or a table, got {v!r}")
    chosen = value if value is not None else default
    if chosen is None or chosen is False:
        return None
    table = dict(default) if isinstance(default, dict) else {}
    if isinstance(value, dict):
        table.update(value)
    unknown = set(table) - _OPTION_KEYS[name]
    if unknown:
        raise SceneError(f"{where}: {label} has unknown field(s) {sorted(unknown)}; "
                         f"expected some of {sorted(_OPTION_KEYS[name])}")
    for key, v in table.items():
        field_name = f"{label}.{key}"
        if key in _OPTION_STRINGS:
            if not isinstance(v, str):
                raise SceneError(f"{where}: {field_name} must be a string, got {v!r}")
        elif key in _OPTION_VECTORS:
            if not isinstance(v, list) or len(v) != 3:
                raise SceneError(f"{where}: {field_name} must be [x, y, z] (a world direction), got {v!r}")
            table[key] = tuple(_number(where, field_name, c) for c in v)
        elif key in _OPTION_INTEGERS:
            if isinstance(v, bool) or not isinstance(v, int):
                raise SceneError(f"{where}: {field_name} must be an integer, got {v!r}")
        else:
            table[key] = _number(where, field_name, v, positive=True)
    try:
        return _OPTION_SPECS[name](**table)
    except (ValueError, TypeError) as exc:
        raise SceneError(f"{where}: {label}: {exc}") from None


def _finger(where: str, defaults: dict, entry: dict, index: int) -> tuple[FingerParams, TactileSpec | None,
                                                                           SensingSpec | None]:
    if not isinstance(entry, dict):
        raise SceneError(f"{where}: finger[{index}] must be a table")
    options = [_option(where, name, f"finger[{index}].{name}", defaults.get(name), entry.get(name))
               for name in _OPTION_SPECS]
    merged = {k: v for k, v in {**defaults, **entry}.items() if k not in _OPTION_SPECS}
    unknown = set(merged) - _FINGER_KEYS
    if unknown:
        raise SceneError(f"{where}: finger[{index}] has unknown field(s) {sorted(unknown)}; expected some of {sorted(_FINGER_KEYS)}")
    merged.setdefault("name", f"finger{index}")
    if "model" in merged and merged["model"] not in MODELS:
        raise SceneError(f"{where}: finger[{index}].model is {merged['model']!r}; expected one of {', '.join(MODELS)}")
    if "offset" in merged:
        off = merged["offset"]
        if not isinstance(off, list) or len(off) != 3:
            raise SceneError(f"{where}: finger[{index}].offset must be [x, y, z] in m, got {off!r}")
        merged["offset"] = tuple(_number(where, f"finger[{index}].offset", v) for v in off)
    for key, value in merged.items():
        if key in ("name", "model", "offset", "saturate", "device_finger"):
            continue
        if value is not None:
            merged[key] = _number(where, f"finger[{index}].{key}", value)
    if "device_finger" in merged and (isinstance(merged["device_finger"], bool) or not isinstance(merged["device_finger"], int)):
        raise SceneError(f"{where}: finger[{index}].device_finger must be an integer, got {merged['device_finger']!r}")
    try:
        return FingerParams(**merged), options[0], options[1]
    except (ValueError, TypeError) as exc:
        raise SceneError(f"{where}: finger[{index}]: {exc}") from None


def _haptics(where: str, table: dict, scene: Scene) -> None:
    """The [haptics] table into `scene` (names are checked against the model by `load_model`)."""
    names = table.get("exclude", [])
    if not isinstance(names, list) or not all(isinstance(n, str) and n for n in names):
        raise SceneError(f'{where}: haptics.exclude must be a list of geom or flex names, e.g. ["ring"], got {names!r}')
    groups = table.get("exclude_groups", [])
    if not isinstance(groups, list) or not all(
            isinstance(g, int) and not isinstance(g, bool) and 0 <= g < GEOM_GROUPS for g in groups):
        raise SceneError(f"{where}: haptics.exclude_groups must be a list of geom groups "
                         f"(integers 0 to {GEOM_GROUPS - 1}), got {groups!r}")
    surface = table.get("mesh_surface", "true")
    if surface not in MESH_SURFACES:
        raise SceneError(f"{where}: haptics.mesh_surface must be one of {', '.join(map(repr, MESH_SURFACES))} "
                         f"(a mesh's own triangles, or the convex hull MuJoCo collides with), got {surface!r}")
    scene.exclude, scene.exclude_groups, scene.mesh_surface = tuple(names), tuple(groups), surface


def load_scene(name_or_path: str) -> Scene:
    """Read and validate a scene (the MJCF is compiled later, by `Scene.load_model`)."""
    path = find_scene(name_or_path)
    where = str(path)
    try:
        doc = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise SceneError(f"{where}: not valid TOML: {exc}") from None
    except RecursionError:  # tomllib parses nested arrays and inline tables recursively
        raise SceneError(f"{where}: not valid TOML: arrays or tables nested too deeply") from None
    unknown = set(doc) - {"scene", "measure", "finger_defaults", "finger", "device", "haptics"}
    if unknown:
        raise SceneError(f"{where}: unknown table(s) {sorted(unknown)}")
    s = _table(where, doc, "scene", _SCENE_KEYS)
    if "mjcf" not in s or not isinstance(s["mjcf"], str):
        raise SceneError(f"{where}: [scene] mjcf is required: the MJCF file name, relative to the scene file")
    mjcf = (path.parent / s["mjcf"]).resolve()
    if not mjcf.is_file():
        raise SceneError(f"{where}: [scene] mjcf {s['mjcf']!r} does not exist ({mjcf})")
    scene = Scene(
        name=path.stem, path=path, mjcf=mjcf, description=str(s.get("description", "")),
        rate_hz=_number(where, "scene.rate_hz", s.get("rate_hz", 1000.0), positive=True,
                        within=(MIN_RATE_HZ, MAX_RATE_HZ, "Hz")),
        duration_s=_number(where, "scene.duration_s", s.get("duration_s", 5.0), positive=True,
                           within=(0.0, MAX_DURATION_S, "s")),
        audit=_flag(where, "scene.audit", s.get("audit", True)),
        force_shading=_flag(where, "scene.force_shading", s.get("force_shading", False)),
    )
    defaults = _table(where, doc, "finger_defaults", _FINGER_KEYS | set(_OPTION_SPECS))
    fingers = doc.get("finger", [])
    if not isinstance(fingers, list) or not fingers:
        raise SceneError(f"{where}: at least one [[finger]] table is required")
    parsed = [_finger(where, defaults, f, i) for i, f in enumerate(fingers)]
    scene.fingers = [p[0] for p in parsed]
    scene.tactile = [p[1] for p in parsed]
    scene.sensing = [p[2] for p in parsed]
    scene.device = _table(where, doc, "device", None)
    _haptics(where, _table(where, doc, "haptics", _HAPTICS_KEYS), scene)
    if "measure" in doc:
        g = _table(where, doc, "measure", _MEASURE_KEYS)
        axis = g.get("axis", [1.0, 0.0, 0.0])
        if not isinstance(axis, list) or len(axis) != 3:
            raise SceneError(f"{where}: measure.axis must be [x, y, z], got {axis!r}")
        axis = [_number(where, "measure.axis", v) for v in axis]
        norm = math.sqrt(sum(v * v for v in axis))
        if not 0.0 < norm < math.inf:
            raise SceneError(f"{where}: measure.axis must be a non-zero direction of finite length, got {axis!r}")
        if not isinstance(g.get("object"), str):
            raise SceneError(f"{where}: measure.object must be the name of a body")
        scene.measure = MeasureSpec(g["object"], tuple(v / norm for v in axis),
                                    _number(where, "measure.start_s", g.get("start_s", 0.0), non_negative=True,
                                            within=(0.0, MAX_DURATION_S, "s")))
    return scene
