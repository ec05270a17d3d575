"""Scenes: a MuJoCo MJCF file plus a TOML file that says what the haptic side needs.

A scene is `NAME.toml` beside its MJCF. Tables (every key optional unless marked):

    [scene]            mjcf (required, path relative to the TOML), description, rate_hz (1000;
                       10 to 100000 Hz), physics_rate_hz (two rates: MuJoCo steps at this
                       rate, a whole fraction of rate_hz; default: a step every tick),
                       duration_s (5.0; at most 24 h), audit (true: track proxy penetration every tick),
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
    [[device]]         instead of [device], one table per device, for several devices in one
                       loop (two hands): a finger names its device by `device` (an index, in
                       the order of the tables; default 0) and its finger by `device_finger`
    [haptics]          what the fingers touch (docs/models.md): exclude (geom or flex names) and
                         exclude_groups (geom groups 0-5) kept out of haptic contact, still in
                         MuJoCo's physics; mesh_surface ("true": a mesh's own triangles;
                         "hull": the convex hull MuJoCo collides it with)
    [materials.NAME]   a material (`softproxy.Material`: stiffness, damping, mu_s, mu_d, torsion
                         and the effects) for the geom, body or MJCF default class NAME
                         (docs/materials.md)

Scenes are found by name in the folders registered under the `softproxy.scene_dirs` entry
point (the shipped `scenes/` folder), or given as a path. The tables, their fields, bounds
and units are declared in `softproxy.schema` (`SceneFile`; `softproxy schema` writes its JSON
Schema for editors); every error is one line naming the file, the field and what was
expected. `Scene.load_model` also checks the MJCF against what the servo loop can run: no
RK4 integrator (the loop steps MuJoCo in two halves), no touchable geom of a type the fingers
cannot touch (SDFs) unless [haptics] excludes it, [haptics] names that are geoms or flexes
of the model, a `[measure]` object that is a body.
"""

from __future__ import annotations

import math
import tomllib
from dataclasses import dataclass, field
from importlib.metadata import entry_points
from pathlib import Path

import mujoco

from softproxy import schema
from softproxy.geometry import exclusions, unsupported_geoms, unsupported_message
from softproxy.mjcf_files import ModelFileError, check_model_files
from softproxy.material import geom_classes, materials_by_geom
from softproxy.schema import FingerParams, InputError, Material, SensingSpec, TactileSpec

_CHANNELS = {"tactile": TactileSpec, "sensing": SensingSpec}


class SceneError(InputError):
    """A scene file that cannot be used; the message (one line) names the file and the field."""


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
    physics_rate_hz: float | None = None  # two rates: MuJoCo's (None: one step per tick)
    duration_s: float = 5.0
    audit: bool = True
    force_shading: bool = False
    fingers: list[FingerParams] = field(default_factory=list)
    device: dict = field(default_factory=dict)  # the first (or only) device's table
    devices: list[dict] = field(default_factory=list)  # every device's table, in order ([device]: one)
    measure: MeasureSpec | None = None
    tactile: list[TactileSpec | None] = field(default_factory=list)  # per finger; None = off
    sensing: list[SensingSpec | None] = field(default_factory=list)  # per finger; None = off
    exclude: tuple[str, ...] = ()         # geoms / flexes kept out of haptic contact, by name
    exclude_groups: tuple[int, ...] = ()  # ... and by geom group
    mesh_surface: str = "true"            # "true" | "hull": what a mesh feels like
    keyframe: str | None = None           # the MJCF <key> the world starts from (None: qpos0)
    settle_s: float = 0.0                 # s the world runs alone before the device takes over
    materials: dict = field(default_factory=dict)  # [materials.NAME]: softproxy.Material by geom, body or class name
    material_classes: list | None = None  # each geom's MJCF default class, where a material names a class

    @property
    def device_fingers(self) -> int:
        """How many fingers a device needs to drive this scene's (its highest `device_finger` + 1)."""
        return max((f.device_finger for f in self.fingers), default=0) + 1

    def fingers_of(self, device: int) -> int:
        """How many fingers device `device` needs to drive its fingers of this scene (0: none)."""
        return max((f.device_finger + 1 for f in self.fingers if f.device == device), default=0)

    def world_options(self) -> dict:
        """The keyword arguments of `World` this scene asks for (force shading, exclusions, mesh surface)."""
        return {"force_shading": self.force_shading, "exclude": self.exclude, "exclude_groups": self.exclude_groups,
                "mesh_surface": self.mesh_surface, "materials": self.materials,
                "material_classes": self.material_classes}

    def start_data(self, model: mujoco.MjModel) -> mujoco.MjData:
        """The state the run starts from: the scene's keyframe (else qpos0), then `settle_s` of
        MuJoCo on its own at the model's own timestep, nothing pushing on it, so a model that
        sags from its start state comes to rest before a finger touches it."""
        data = mujoco.MjData(model)
        if self.keyframe is not None:
            mujoco.mj_resetDataKeyframe(model, data, mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, self.keyframe))
        for _ in range(math.ceil(self.settle_s / model.opt.timestep - 1e-9)):
            mujoco.mj_step(model, data)
        mujoco.mj_forward(model, data)
        return data

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

    def _check_materials(self, model: mujoco.MjModel) -> None:
        """Every [materials.NAME] names a geom, a body or an MJCF default class (whose geoms
        are then looked up in the MJCF: `material_classes`)."""
        if not self.materials:
            return
        unnamed = [k for k in self.materials if mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, k) < 0
                   and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, k) < 0]
        try:
            self.material_classes = geom_classes(self.mjcf, model) if unnamed else None
            materials_by_geom(model, self.materials, self.material_classes, where=f"{self.path}: materials")
        except ValueError as exc:
            raise SceneError(f"{exc} ({self.mjcf.name})") from None

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
        self._check_materials(model)
        unsupported = unsupported_geoms(model, excluded)
        if unsupported:
            raise SceneError(f"{self.mjcf}: {unsupported_message(model, unsupported, scene=True)} ({self.path.name})")
        if self.keyframe is not None and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_KEY, self.keyframe) < 0:
            keys = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_KEY, k) for k in range(model.nkey)]
            named = ", ".join(repr(k) for k in keys if k) or "none named"
            raise SceneError(f"{self.path}: scene.keyframe {self.keyframe!r} is not a <key> of {self.mjcf.name}; "
                             f"its keys: {named}")
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


def _channel(where: str, name: str, label: str, default, value):
    """A finger's `tactile` / `sensing` entry (true, false or a table, over the default's; both
    already checked against the schema) -> spec or None."""
    chosen = value if value is not None else default
    if chosen is None or chosen is False:
        return None
    table = dict(default) if isinstance(default, dict) else {}
    if isinstance(value, dict):
        table.update(value)
    return schema.build(_CHANNELS[name], table, source=where, path=label)


def _finger(where: str, defaults: dict, entry: dict, index: int) -> tuple[FingerParams, TactileSpec | None,
                                                                           SensingSpec | None]:
    """One [[finger]] merged over [finger_defaults] (each checked against the schema already)."""
    label = f"finger[{index}]"
    tactile, sensing = (_channel(where, name, f"{label}.{name}", defaults.get(name), entry.get(name))
                        for name in _CHANNELS)
    merged = {k: v for k, v in {**defaults, **entry}.items() if k not in _CHANNELS}
    merged.setdefault("name", f"finger{index}")
    return schema.build(FingerParams, merged, source=where, path=label), tactile, sensing


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
    try:
        return _scene(path, doc)
    except SceneError:
        raise
    except InputError as exc:  # the schema's one line, as a SceneError
        raise SceneError(str(exc)) from None


def _scene(path: Path, doc: dict) -> Scene:
    """A parsed scene file checked against `schema.SceneFile` and built into a Scene."""
    where = str(path)
    checked = schema.validate(schema.SceneFile, doc, source=where)
    s = checked.scene
    mjcf = (path.parent / s.mjcf).resolve()
    if not mjcf.is_file():
        raise SceneError(f"{where}: scene.mjcf {s.mjcf!r} does not exist ({mjcf})")
    scene = Scene(name=path.stem, path=path, mjcf=mjcf, description=s.description, rate_hz=s.rate_hz,
                  physics_rate_hz=s.physics_rate_hz, duration_s=s.duration_s, audit=s.audit, force_shading=s.force_shading, keyframe=s.keyframe,
                  settle_s=s.settle_s)
    defaults = doc.get("finger_defaults", {})
    parsed = [_finger(where, defaults, f, i) for i, f in enumerate(doc["finger"])]
    scene.fingers = [p[0] for p in parsed]
    scene.tactile = [p[1] for p in parsed]
    scene.sensing = [p[2] for p in parsed]
    tables = doc.get("device", {})
    scene.devices = [dict(t) for t in tables] if isinstance(tables, list) else [tables]
    scene.device = scene.devices[0]
    for i, params in enumerate(scene.fingers):
        if params.device >= len(scene.devices):
            said = "[[device]] tables" if isinstance(tables, list) else "device (its [device] table)"
            raise SceneError(f"{where}: finger[{i}].device is {params.device}, but the scene has {len(scene.devices)} "
                             f"{said}: give one [[device]] table per device, or device = 0..{len(scene.devices) - 1}")
    scene.materials = {name: schema.build(Material, t.model_dump(), source=where, path=f"materials.{name}")
                       for name, t in checked.materials.items()}
    h = checked.haptics
    scene.exclude, scene.exclude_groups, scene.mesh_surface = tuple(h.exclude), tuple(h.exclude_groups), h.mesh_surface
    if checked.measure is not None:
        g = checked.measure
        scene.measure = MeasureSpec(g.object, g.axis, g.start_s)
    return scene
