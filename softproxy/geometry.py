"""The shapes a finger touches: one per collidable MuJoCo geom, and the table the engine reads.

Each collidable geom becomes a `Shape` (its type, body and sizes, read from the model once),
and the shapes of a model form a `ShapeSet`: its table `S` (one `SHAPE` record per shape,
`softproxy.compiled.layout`) and, when it has meshes, the mesh tables (T, C). The engine's
queries (`softproxy.compiled.shapes`) answer, in world coordinates, with the pose read straight
from MuJoCo's `geom_xpos` / `geom_xmat`:
- `distance(x, y, z)`: signed distance from the geom's surface (m, < 0 inside) and the
  outward unit normal at the closest surface point;
- `sweep(...)`: the first point where a sphere of radius r moving on a segment touches the
  geom *while moving into it* (continuous collision: nothing is skipped between ticks).
A `Shape`'s methods call those same compiled queries on its row of its set: there is one
implementation of each, and a subclass cannot answer differently from the engine.
"""

from __future__ import annotations

import math

import mujoco
import numpy as np

from softproxy.compiled import shapes as kernels
from softproxy.compiled.dispatch import EntryPoints
from softproxy.compiled.layout import (
    GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH, GEOM_PLANE, GEOM_SPHERE, SHAPE,
)


class Shape:
    """One MuJoCo geom as seen by a proxy: what it is (type, body, sizes) and its queries.

    `flat`: every face is planar (plane, box). `convex`: the shape (and so the shape inflated
    by the proxy's radius) lies behind every plane that touches it (every primitive)."""

    gtype = -1
    flat = False
    convex = False

    __slots__ = ("geom", "body", "name", "static", "rbound", "data", "set", "row")

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, geom: int, static: bool) -> None:
        self.geom = geom
        self.body = int(model.geom_bodyid[geom])
        self.name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or f"geom{geom}"
        self.static = static
        plane = int(model.geom_type[geom]) == int(mujoco.mjtGeom.mjGEOM_PLANE)
        self.rbound = math.inf if plane else float(model.geom_rbound[geom])
        self.data = data
        self.set: ShapeSet | None = None  # the first set made of it answers its queries
        self.row = -1

    def prepare(self, radius: float) -> bool:
        """Get ready for a proxy of `radius` (m): build now whatever its queries would otherwise
        build inside the servo tick. True when the engine's tables must be rebuilt (meshes)."""
        return False

    def _tables(self):
        if self.set is None:
            ShapeSet([self])
        return self.set

    def to_local(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        """World point (m) in the geom's frame (m)."""
        s = self._tables()
        return s.run(kernels.shape_to_local, s.S, s.xpos, s.xmat, self.row, float(x), float(y), float(z))

    def distance(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        """Signed distance from the surface (m) and outward unit normal, world frame."""
        s = self._tables()
        return s.run(kernels.shape_distance, s.S, s.T, s.C, s.xpos, s.xmat, self.row, float(x), float(y), float(z))

    def on_face(self, nx: float, ny: float, nz: float) -> bool:
        """True when a contact of normal n (world) lies on a planar face, not on a rounded
        edge or corner of the proxy-swept shape (plane; box faces)."""
        s = self._tables()
        return s.run(kernels.shape_on_face, s.S, s.xmat, self.row, float(nx), float(ny), float(nz))

    def sweep(self, x0: float, y0: float, z0: float, dx: float, dy: float, dz: float, r: float):
        """First touch of a sphere (radius r, m) moving from x0 by (dx, dy, dz) (m) into the
        geom: (fraction in [0, 1), nx, ny, nz), or None when it touches nothing."""
        s = self._tables()
        hit = s.run(kernels.shape_sweep, s.S, s.T, s.C, s.xpos, s.xmat, self.row, float(x0), float(y0), float(z0),
                    float(dx), float(dy), float(dz), float(r))
        return None if hit[0] < 0.0 else hit

    def record(self, r) -> None:
        """Fill its `SHAPE` record's sizes (the rest is common)."""


class PlaneShape(Shape):
    """MuJoCo plane: infinite for collision, outward normal +z of the geom frame."""

    gtype = GEOM_PLANE
    flat = True
    convex = True
    __slots__ = ()


class SphereShape(Shape):
    gtype = GEOM_SPHERE
    convex = True
    __slots__ = ("radius",)

    def __init__(self, model, data, geom, static):
        self.radius = float(model.geom_size[geom][0])
        super().__init__(model, data, geom, static)

    def record(self, r) -> None:
        r.a = self.radius


class CapsuleShape(Shape):
    """Capsule: radius, half-length along the geom's z axis."""

    gtype = GEOM_CAPSULE
    convex = True
    __slots__ = ("radius", "half")

    def __init__(self, model, data, geom, static):
        self.radius, self.half = (float(v) for v in model.geom_size[geom][:2])
        super().__init__(model, data, geom, static)

    def record(self, r) -> None:
        r.a, r.b = self.radius, self.half


class CylinderShape(Shape):
    """Cylinder: radius, half-height along the geom's z axis (flat caps, sharp rims)."""

    gtype = GEOM_CYLINDER
    convex = True
    __slots__ = ("radius", "half")

    def __init__(self, model, data, geom, static):
        self.radius, self.half = (float(v) for v in model.geom_size[geom][:2])
        super().__init__(model, data, geom, static)

    def record(self, r) -> None:
        r.a, r.b = self.radius, self.half


class BoxShape(Shape):
    """Box: half-sizes along the geom axes."""

    gtype = GEOM_BOX
    flat = True
    convex = True
    __slots__ = ("hx", "hy", "hz")

    def __init__(self, model, data, geom, static):
        self.hx, self.hy, self.hz = (float(v) for v in model.geom_size[geom][:3])
        super().__init__(model, data, geom, static)

    def record(self, r) -> None:
        r.a, r.b, r.c = self.hx, self.hy, self.hz


class EllipsoidShape(Shape):
    """Ellipsoid: semi-axes along the geom axes (exact distance by a 1-D root find)."""

    gtype = GEOM_ELLIPSOID
    convex = True
    __slots__ = ("a", "b", "c")

    def __init__(self, model, data, geom, static):
        self.a, self.b, self.c = (float(v) for v in model.geom_size[geom][:3])
        super().__init__(model, data, geom, static)

    def record(self, r) -> None:
        r.a, r.b, r.c = self.a, self.b, self.c


class ShapeSet(list):
    """The shapes of one world, in order, and the engine's tables of them.

    `S`: one `SHAPE` record per shape; `T`, `C`: the mesh tables (None without meshes, so a
    world of primitives never compiles the mesh kernels); `xpos`, `xmat`: MuJoCo's geom poses,
    `cvel` its bodies' velocities (views into mjData, read by the kernels). A list, so it
    reads like the list of shapes."""

    def __init__(self, shapes, data: mujoco.MjData | None = None) -> None:
        super().__init__(shapes)
        if data is None:
            if not self:
                raise ValueError("a ShapeSet of no shapes needs the MuJoCo data it belongs to")
            data = self[0].data
        self.data = data
        self.xpos = data.geom_xpos
        self.xmat = data.geom_xmat
        self.cvel = data.cvel  # the bodies' velocities (ω, v) after mj_step1: ω drags the torsion (eqs 41-42)
        self.run = EntryPoints()  # the shapes' queries, without numba's per-call dispatch
        for k, s in enumerate(self):
            if s.set is None:
                s.set, s.row = self, k
        self.build()

    @classmethod
    def of(cls, shapes) -> "ShapeSet":
        """`shapes` if it is a ShapeSet, else a new set of them."""
        return shapes if isinstance(shapes, ShapeSet) else cls(shapes)

    def build(self) -> None:
        """(Re)build the tables from the shapes (after a mesh prepared for a larger proxy)."""
        S = np.zeros(len(self), dtype=SHAPE).view(np.recarray)
        for k, s in enumerate(self):
            if s.gtype < 0:
                raise ValueError(f"shape {s.name!r} ({type(s).__name__}) is not a shape the engine supports "
                                 "(plane, sphere, capsule, ellipsoid, cylinder, box, mesh)")
            r = S[k]
            r.type, r.geom, r.body = s.gtype, s.geom, s.body
            r.static, r.convex, r.planar = s.static, s.convex, s.flat
            r.rbound = s.rbound
            r.hint = -1
            s.record(r)
        self.S = S
        self.T = self.C = None
        if any(s.gtype == GEOM_MESH for s in self):
            from softproxy.compiled.mesh import mesh_tables

            self.T, self.C = mesh_tables(self, S)

    def prepare(self, radius: float) -> None:
        """Get every shape ready for a proxy of `radius` (m); rebuild the tables if a mesh grew."""
        if any([s.prepare(radius) for s in self]):
            self.build()


SHAPES = {
    int(mujoco.mjtGeom.mjGEOM_PLANE): PlaneShape,
    int(mujoco.mjtGeom.mjGEOM_SPHERE): SphereShape,
    int(mujoco.mjtGeom.mjGEOM_CAPSULE): CapsuleShape,
    int(mujoco.mjtGeom.mjGEOM_CYLINDER): CylinderShape,
    int(mujoco.mjtGeom.mjGEOM_BOX): BoxShape,
    int(mujoco.mjtGeom.mjGEOM_ELLIPSOID): EllipsoidShape,
}


def body_is_static(model: mujoco.MjModel, body: int) -> bool:
    """True when neither the body nor any ancestor has a joint and it is not mocap."""
    while body > 0:
        if model.body_jntnum[body] > 0 or model.body_mocapid[body] >= 0:
            return False
        body = int(model.body_parentid[body])
    return True


def touchable(model: mujoco.MjModel, geom: int) -> bool:
    """A geom a finger can touch: one that takes part in collisions (contype or conaffinity set)."""
    return bool(model.geom_contype[geom] or model.geom_conaffinity[geom])


def shapes_of(model: mujoco.MjModel, data: mujoco.MjData, mesh_shape=None) -> ShapeSet:
    """The ShapeSet of every touchable geom. Unsupported geom types raise ValueError naming the geom.

    `mesh_shape(model, data, geom, static)` builds mesh shapes when given (see `softproxy.mesh`).
    """
    out = []
    for g in range(model.ngeom):
        if not touchable(model, g):
            continue
        gtype = int(model.geom_type[g])
        static = body_is_static(model, int(model.geom_bodyid[g]))
        cls = SHAPES.get(gtype)
        if cls is None and gtype == int(mujoco.mjtGeom.mjGEOM_MESH) and mesh_shape is not None:
            out.append(mesh_shape(model, data, g, static))
            continue
        if cls is None:
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or f"#{g}"
            kind = mujoco.mjtGeom(gtype).name.removeprefix("mjGEOM_").lower()
            raise ValueError(
                f"geom {name!r} has type {kind}, which fingers cannot touch yet; "
                "set contype=\"0\" conaffinity=\"0\" on it to keep it out of haptic contact"
            )
        out.append(cls(model, data, g, static))
    return ShapeSet(out, data)
