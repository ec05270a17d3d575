"""`World`: the MuJoCo side of the coupling — shapes for the proxies, wrenches on the bodies.

MuJoCo is stepped in two halves (mj_step1 / mj_step2) so that each tick sees the bodies
where they are *now*: mj_step1 computes positions and velocities of the current state, the
fingers then move their proxies with the bodies they touch and compute their forces, the
equal and opposite wrenches go into `xfrc_applied`, and mj_step2 integrates. This needs
MuJoCo's Euler or implicit integrator (RK4 has no split step).
"""

from __future__ import annotations

import functools

import mujoco
import numpy as np

from softproxy import material
from softproxy.compiled import finger as kernel
from softproxy.compiled.dispatch import entry
from softproxy.geometry import ShapeSet, shapes_of


class World:
    """A MuJoCo model and data plus the shapes the fingers touch. SI units, world frame."""

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData | None = None, mesh_shape=None,
                 force_shading: bool = False, *, exclude=(), exclude_groups=(), mesh_surface: str = "true",
                 materials: dict | None = None, material_classes: list[str] | None = None) -> None:
        """`force_shading`: mesh contacts report the normal interpolated from the vertex normals
        (smooth feel of a faceted surface); the proxy still stops on the true triangles.
        `exclude` (geom or flex names), `exclude_groups` (geom groups 0-5): kept out of haptic
        contact, still in MuJoCo's physics. `mesh_surface`: "true" (a mesh's own triangles) or
        "hull" (the convex hull MuJoCo collides with). See `softproxy.geometry.shapes_of`.
        `materials`: a `softproxy.Material` per geom name, body name or geom id (or, with
        `material_classes`, the MJCF default class of each geom, an MJCF default class name);
        every geom's MJCF friction is read too (`softproxy.material`)."""
        if int(model.opt.integrator) == int(mujoco.mjtIntegrator.mjINT_RK4):
            raise ValueError("the servo loop steps MuJoCo in two halves; RK4 cannot: use Euler or implicitfast")
        self.model = model
        self.data = data if data is not None else mujoco.MjData(model)
        mujoco.mj_forward(self.model, self.data)
        meshes = (int(mujoco.mjtGeom.mjGEOM_MESH), int(mujoco.mjtGeom.mjGEOM_HFIELD))
        if mesh_shape is None and force_shading and any(int(t) in meshes for t in model.geom_type):
            from softproxy.mesh import MeshShape  # trimesh is imported only for scenes with meshes

            mesh_shape = functools.partial(MeshShape, shading=True)
        self.shapes: ShapeSet = shapes_of(model, self.data, mesh_shape, exclude=exclude,
                                          exclude_groups=exclude_groups, mesh_surface=mesh_surface)
        material.apply(self.shapes, model, material.materials_by_geom(model, materials or {}, material_classes))
        # this tick's wrench per body: force (N) and moment about the world origin (N·m), so a
        # push needs no body position; the bodies touched this tick and pushed last tick
        # (rows of `bodies`, lengths in `counts`), and those welded to the world (never pushed)
        self.wrench = np.zeros((model.nbody, 6))
        self.bodies = np.zeros((3, model.nbody), dtype=np.int64)
        self.bodies[kernel.FIXED] = [int(w) == 0 for w in model.body_weldid]
        self.counts = np.zeros(2, dtype=np.int64)
        self._xfrc = self.data.xfrc_applied  # views into mjData, kept
        self._xipos = self.data.xipos
        self._write = entry(kernel.write_wrenches, (self._xfrc, self._xipos, self.wrench, self.bodies, self.counts, 1.0),
                            "the wrench writer")

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    @timestep.setter
    def timestep(self, dt: float) -> None:
        if not dt > 0.0:
            raise ValueError(f"timestep must be > 0 s, got {dt!r}")
        self.model.opt.timestep = dt

    def begin_step(self) -> None:
        """First half of mj_step: kinematics and velocities of the current state (the shapes'
        poses are read from mjData by every query)."""
        mujoco.mj_step1(self.model, self.data)

    def push(self, body: int, fx, fy, fz, px, py, pz, tx, ty, tz) -> None:
        """Add force (N) at world point p (m) plus a pure torque (N·m) on `body` for this tick
        (nothing on a body welded to the world)."""
        kernel.push(self.wrench, self.bodies, self.counts, int(body), float(fx), float(fy), float(fz), float(px),
                    float(py), float(pz), float(tx), float(ty), float(tz))

    def end_step(self) -> None:
        """Write this tick's wrenches (moved to each body's centre of mass; last tick's cleared)
        into xfrc_applied, then the second half of mj_step."""
        self._write(self._xfrc, self._xipos, self.wrench, self.bodies, self.counts, 1.0)
        mujoco.mj_step2(self.model, self.data)

    def clear_wrenches(self) -> None:
        """Remove every wrench the fingers put on the bodies (the safe state)."""
        for j in range(int(self.counts[1])):
            self._xfrc[self.bodies[kernel.PUSHED, j]] = 0.0
        self.wrench[:] = 0.0
        self.counts[:] = 0

    def body_id(self, name: str) -> int:
        """Body id by name; ValueError naming the body if the model has none."""
        i = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_BODY, name)
        if i < 0:
            raise ValueError(f"the model has no body named {name!r}")
        return i
