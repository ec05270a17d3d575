"""Materials: which geoms a scene's materials go to, and what each shape's record holds of them.

A geom's surface comes from two places (docs/materials.md):

- its MJCF friction, combined with the finger's as engines combine two bodies' (Bullet's
  product rule): the finger's coefficients times the geom's sliding friction, so a geom at
  MuJoCo's default (1) feels as the finger's own and one at 0.3 as 0.3 of it; a geom with
  a `priority` above 0 keeps its own friction, as in MuJoCo, where the higher priority's
  friction is the pair's (its dynamic one the finger's dynamic ÷ static ratio of it);
- a `Material` given to it (`World(materials=...)`, a scene's `[materials.NAME]`), whose
  fields override: friction given there is the pair's; stiffness and damping render the
  softer of the surface's and the finger's; effects as CHAI3D's `cMaterial`.

`softproxy.compiled.material` renders it. Units: SI (N/m, N·s/m, N, m, Hz).
"""

from __future__ import annotations

import math
from pathlib import Path

import mujoco

from softproxy.geometry import ShapeSet
from softproxy.schema import Material

MUJOCO_FRICTION = 1.0
"""MuJoCo's default sliding friction of a geom: the finger's own coefficients on it."""


def geom_classes(mjcf: str | Path, model: mujoco.MjModel) -> list[str]:
    """The MJCF default class of each geom of `model` compiled from `mjcf`, in geom order ("main":
    none named). ValueError when the file's geoms do not match the model's."""
    spec = mujoco.MjSpec.from_file(str(mjcf))
    geoms = list(spec.geoms)
    if len(geoms) != model.ngeom:
        raise ValueError(f"{mjcf}: {len(geoms)} geoms in the MJCF, {model.ngeom} in its model")
    out = []
    for g, geom in enumerate(geoms):
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        if (geom.name or None) != name:
            raise ValueError(f"{mjcf}: geom {g} is {geom.name!r} in the MJCF and {name!r} in its model")
        cls = geom.classname
        out.append(getattr(cls, "name", None) or str(cls or "main"))
    return out


def materials_by_geom(model: mujoco.MjModel, materials: dict, classes: list[str] | None = None,
                      where: str = "materials") -> dict[int, Material]:
    """Each geom's material from `materials`, keyed by a geom name, a body name or (with
    `classes`, `geom_classes`) an MJCF default class name, or by a geom id; a geom takes its own
    name's first, then its body's, then its class's. ValueError naming a key that is none of them."""
    by_geom: dict[int, Material] = {}
    names = {}
    for key, mat in materials.items():
        if not isinstance(mat, Material):
            raise ValueError(f"{where}[{key!r}] must be a softproxy.Material, got {type(mat).__name__}")
        if isinstance(key, int):
            if not 0 <= key < model.ngeom:
                raise ValueError(f"{where}: geom id {key} is not a geom of the model (0..{model.ngeom - 1})")
            by_geom[key] = mat
        else:
            names[str(key)] = mat
    known_classes = set(classes or ())
    for key in names:
        if (mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, key) < 0
                and mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, key) < 0 and key not in known_classes):
            what = "geom, body or default class" if classes is not None else "geom or body"
            raise ValueError(f"{where}.{key} names no {what} of the model")
    for g in range(model.ngeom):
        if g in by_geom:
            continue
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, int(model.geom_bodyid[g]))
        for key in (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g), body,
                    classes[g] if classes is not None else None):
            if key is not None and key in names:
                by_geom[g] = names[key]
                break
    return by_geom


def surface(model: mujoco.MjModel, geom: int, material: Material | None) -> dict | None:
    """The material fields of a geom's SHAPE record (`softproxy.compiled.layout.SHAPE`), or
    None when it feels as the finger's own (MuJoCo's default friction, no material)."""
    out: dict = {}
    friction = float(model.geom_friction[geom, 0])
    if int(model.geom_priority[geom]) > 0:
        out["friction"] = (friction, math.nan)  # its own; dynamic: the finger's ratio of it
    elif friction != MUJOCO_FRICTION:
        out["friction_scale"] = friction
    if material is not None:
        m = material
        if m.stiffness is not None:
            out["stiffness"] = m.stiffness
        if m.damping is not None:
            out["damping"] = m.damping
        if m.mu_s is not None:
            out["friction"] = (m.mu_s, m.mu_d if m.mu_d is not None else 0.8 * m.mu_s)
        out["torsion"] = m.torsion
        out["viscosity"] = m.viscosity
        out["vibration"] = (m.vibration_hz, m.vibration_amplitude)
        out["magnet"] = (m.magnet_force, m.magnet_reach)
        out["stick_slip"] = (m.stick_slip_force, m.stick_slip_stiffness)
        out["texture"] = (*m.texture_axis, m.texture_period, m.texture_height, m.texture_friction)
        out["popthrough"] = m.popthrough_force
    if not out:
        return None
    out["material"] = True
    return out


def apply(shapes: ShapeSet, model: mujoco.MjModel, materials: dict[int, Material]) -> None:
    """Give each shape its surface (`surface`), into its record of the shapes' table now and
    at every rebuild (`ShapeSet.build`)."""
    for k, s in enumerate(shapes):
        s.surface = surface(model, s.geom, materials.get(s.geom))
        for field, value in (s.surface or {}).items():
            shapes.S[k][field] = value
