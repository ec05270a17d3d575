"""The shapes a finger touches: one per collidable MuJoCo geom, and the table the engine reads.

Each collidable geom becomes a `Shape` (its type, body and sizes, read from the model once):
a primitive as itself, a mesh as its own triangles or as the convex hull MuJoCo collides
with (`mesh_surface`), a height field as the solid MuJoCo collides with (its surface over
its base, a mesh). SDF geoms are refused by name unless excluded from haptic contact, and
flexes (deformable bodies) are not felt, which a `FlexWarning` says (`shapes_of`; the
user's view is docs/models.md). The shapes of a model form a `ShapeSet`: its table `S`
(one `SHAPE` record per shape, `softproxy.compiled.layout`) and, when it has meshes, the mesh
tables (T, C). The engine's queries (`softproxy.compiled.shapes`) answer, in world
coordinates, with the pose read straight from MuJoCo's `geom_xpos` / `geom_xmat`:
- `distance(x, y, z)`: signed distance from the geom's surface (m, < 0 inside) and the
  outward unit normal at the closest surface point;
- `sweep(...)`: the first point where a sphere of radius r moving on a segment touches the
  geom *while moving into it* (continuous collision: nothing is skipped between ticks).
A `Shape`'s methods call those same compiled queries on its row of its set: there is one
implementation of each, and a subclass cannot answer differently from the engine.
"""

from __future__ import annotations

import json
import math
import os
import sys
import warnings

import mujoco
import numpy as np

from softproxy.compiled import shapes as kernels
from softproxy.compiled.dispatch import EntryPoints
from softproxy.compiled.layout import (
    GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH, GEOM_PLANE, GEOM_SPHERE, SHAPE, Shapes,
)


class Shape:
    """One MuJoCo geom as seen by a proxy: what it is (type, body, sizes) and its queries.

    `flat`: every face is planar (plane, box). `convex`: the shape (and so the shape inflated
    by the proxy's radius) lies behind every plane that touches it (every primitive)."""

    gtype = -1
    flat = False
    convex = False

    __slots__ = ("geom", "body", "name", "static", "rbound", "size", "data", "set", "row", "surface")

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, geom: int, static: bool) -> None:
        self.geom = geom
        self.body = int(model.geom_bodyid[geom])
        self.name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or f"geom{geom}"
        self.static = static
        plane = int(model.geom_type[geom]) == int(mujoco.mjtGeom.mjGEOM_PLANE)
        self.rbound = math.inf if plane else float(model.geom_rbound[geom])
        self.size = tuple(float(v) for v in model.geom_size[geom])  # MuJoCo's geom_size (m)
        self.data = data
        self.set: ShapeSet | None = None  # the first set made of it answers its queries
        self.row = -1
        self.surface: dict | None = None  # its material's SHAPE fields (`softproxy.material.surface`)

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
        return s.run(kernels.shape_distance, s.tables, self.row, float(x), float(y), float(z))

    def on_face(self, nx: float, ny: float, nz: float) -> bool:
        """True when a contact of normal n (world) lies on a planar face, not on a rounded
        edge or corner of the proxy-swept shape (plane; box faces)."""
        s = self._tables()
        return s.run(kernels.shape_on_face, s.S, s.xmat, self.row, float(nx), float(ny), float(nz))

    def sweep(self, x0: float, y0: float, z0: float, dx: float, dy: float, dz: float, r: float):
        """First touch of a sphere (radius r, m) moving from x0 by (dx, dy, dz) (m) into the
        geom: (fraction in [0, 1), nx, ny, nz), or None when it touches nothing."""
        s = self._tables()
        hit = s.run(kernels.shape_sweep, s.tables, self.row, float(x0), float(y0), float(z0),
                    float(dx), float(dy), float(dz), float(r))
        return None if hit[0] < 0.0 else hit


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


class _AxialShape(Shape):
    """A shape round about the geom's z axis: radius and half-length (m), MuJoCo's geom_size[:2]."""

    convex = True
    __slots__ = ("radius", "half")

    def __init__(self, model, data, geom, static):
        self.radius, self.half = (float(v) for v in model.geom_size[geom][:2])
        super().__init__(model, data, geom, static)


class CapsuleShape(_AxialShape):
    """Capsule: radius, half-length along the geom's z axis."""

    gtype = GEOM_CAPSULE
    __slots__ = ()


class CylinderShape(_AxialShape):
    """Cylinder: radius, half-height along the geom's z axis (flat caps, sharp rims)."""

    gtype = GEOM_CYLINDER
    __slots__ = ()


class BoxShape(Shape):
    """Box: half-sizes along the geom axes."""

    gtype = GEOM_BOX
    flat = True
    convex = True
    __slots__ = ("hx", "hy", "hz")

    def __init__(self, model, data, geom, static):
        self.hx, self.hy, self.hz = (float(v) for v in model.geom_size[geom][:3])
        super().__init__(model, data, geom, static)


class EllipsoidShape(Shape):
    """Ellipsoid: semi-axes along the geom axes (exact distance by a 1-D root find)."""

    gtype = GEOM_ELLIPSOID
    convex = True
    __slots__ = ("a", "b", "c")

    def __init__(self, model, data, geom, static):
        self.a, self.b, self.c = (float(v) for v in model.geom_size[geom][:3])
        super().__init__(model, data, geom, static)


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
            r.geom_size[:] = s.size
            r.hint = r.feature = -1
            r.stiffness = r.damping = math.inf  # no material: the finger's own
            r.friction[:] = math.nan
            r.friction_scale = r.torsion = 1.0
            for field, value in (s.surface or {}).items():
                r[field] = value
        self.S = S
        self.T = self.C = None
        if any(s.gtype == GEOM_MESH for s in self):
            from softproxy.mesh_tables import mesh_tables

            self.T, self.C = mesh_tables(self, S)
        self.tables = Shapes(self.S, self.T, self.C, self.xpos, self.xmat, self.cvel)

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
"""The primitives, by MuJoCo geom type; meshes and height fields become `softproxy.mesh.MeshShape`s."""

MESH_SURFACES = ("true", "hull")
"""What a mesh geom feels like: its own triangles ("true"), or the convex hull MuJoCo collides
it with ("hull": what the simulated bodies feel, so a finger and a body agree on it)."""
GEOM_GROUPS = 6
"""MuJoCo's geom groups (mjNGROUP): `exclude_groups` takes 0 to 5."""

_MESH = int(mujoco.mjtGeom.mjGEOM_MESH)
_HFIELD = int(mujoco.mjtGeom.mjGEOM_HFIELD)


class FlexWarning(UserWarning):
    """Flexes (deformable bodies) that collide in MuJoCo but that the fingers do not feel."""


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


def geom_label(model: mujoco.MjModel, geom: int) -> str:
    """A geom as a message names it: 'name' (type), or #index (type) when it has no name."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom)
    kind = mujoco.mjtGeom(int(model.geom_type[geom])).name.removeprefix("mjGEOM_").lower()
    return f"{name!r} ({kind})" if name else f"#{geom} ({kind})"


# ---------------------------------------------------------------------------------------
# Triangles for the mesh shape: a height field's surface, a mesh's convex hull
# ---------------------------------------------------------------------------------------

def hfield_triangles(model: mujoco.MjModel, geom: int) -> tuple[np.ndarray, np.ndarray]:
    """A height-field geom as the solid MuJoCo collides with, triangulated in its geom frame (m).

    MuJoCo's height field: nrow × ncol elevations in [0, 1] (`hfield_data`, row-major; row r at
    y = size_y (2r / (nrow - 1) - 1), column c at x = size_x (2c / (ncol - 1) - 1)), each
    scaled by elevation_z (`hfield_size` = size_x, size_y, elevation_z, base_z). Each cell is
    two triangles split along its (r, c)-(r+1, c+1) diagonal, and MuJoCo collides with the
    prisms under them, down to the base at z = -base_z. The mesh is that solid, watertight
    (so a finger below the surface is inside): the surface, four walls and the bottom (a fan
    about its centre). Returns (vertices (n, 3), faces (m, 3), outward counter-clockwise)."""
    if int(model.geom_type[geom]) != _HFIELD:
        raise ValueError(f"geom {geom_label(model, geom)} is not a height field")
    h = int(model.geom_dataid[geom])
    nrow, ncol = int(model.hfield_nrow[h]), int(model.hfield_ncol[h])
    sx, sy, sz, base = (float(v) for v in model.hfield_size[h])
    adr = int(model.hfield_adr[h])
    z = np.asarray(model.hfield_data[adr:adr + nrow * ncol], dtype=np.float64).reshape(nrow, ncol) * sz
    x, y = np.meshgrid(np.linspace(-sx, sx, ncol), np.linspace(-sy, sy, nrow))
    top = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)

    r, c = np.meshgrid(np.arange(nrow - 1), np.arange(ncol - 1), indexing="ij")
    i00 = (r * ncol + c).ravel()
    i01, i10, i11 = i00 + 1, i00 + ncol, i00 + ncol + 1
    surface = np.concatenate([np.stack([i00, i01, i11], 1), np.stack([i00, i11, i10], 1)])

    # the boundary, counter-clockwise seen from +z (corners once): y = -sy, x = +sx, y = +sy, x = -sx
    ring = np.concatenate([np.arange(ncol - 1), (ncol - 1) + ncol * np.arange(nrow - 1),
                           (nrow * ncol - 1) - np.arange(ncol - 1), ncol * (nrow - 1) - ncol * np.arange(nrow - 1)])
    bottom = top[ring] * [1.0, 1.0, 0.0] - [0.0, 0.0, base]
    b = len(top) + np.arange(len(ring))           # the bottom's ring
    centre = len(top) + len(ring)                 # the bottom's centre
    t_next, b_next = np.roll(ring, -1), np.roll(b, -1)
    walls = np.concatenate([np.stack([ring, b, b_next], 1), np.stack([ring, b_next, t_next], 1)])
    floor = np.stack([np.full(len(ring), centre), b_next, b], 1)
    vertices = np.concatenate([top, bottom, [[0.0, 0.0, -base]]])
    return vertices, np.concatenate([surface, walls, floor]).astype(np.int64)


def hull_triangles(model: mujoco.MjModel, geom: int) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull MuJoCo collides a mesh geom with, in its geom frame (m): MuJoCo's own
    compiled hull (`mesh_graph`: vertex count, face count, then per vertex its edge address
    and mesh vertex id, the edges, and per face its three mesh vertex ids) when the model has
    it, else the convex hull (scipy) of the mesh's vertices. Returns (vertices, faces), faces
    counter-clockwise seen from outside, only the hull's vertices kept."""
    mesh = int(model.geom_dataid[geom])
    if int(model.geom_type[geom]) != _MESH or mesh < 0:
        raise ValueError(f"geom {geom_label(model, geom)} is not a mesh geom")
    va, vn = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
    vertices = np.array(model.mesh_vert[va:va + vn], dtype=np.float64)
    adr = int(model.mesh_graphadr[mesh])
    if adr >= 0:
        graph = model.mesh_graph
        nv, nf = int(graph[adr]), int(graph[adr + 1])
        first = adr + 2 + 3 * nv + 3 * nf
        faces = np.array(graph[first:first + 3 * nf], dtype=np.int64).reshape(nf, 3)
    else:
        from scipy.spatial import QhullError

        try:
            return convex_hull(vertices)
        except QhullError:
            raise ValueError(f"geom {geom_label(model, geom)}: its mesh has no convex hull (flat, or fewer than "
                             "4 vertices); feel its own triangles (mesh_surface \"true\") or exclude it") from None
    used, faces = np.unique(faces, return_inverse=True)
    return vertices[used], faces.reshape(-1, 3)


def convex_hull(vertices) -> tuple[np.ndarray, np.ndarray]:
    """The convex hull (scipy's Qhull) of points (n, 3): (its vertices, its faces counter-clockwise
    seen from outside); a mesh's hull when the model has no compiled one."""
    from scipy.spatial import ConvexHull

    vertices = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    hull = ConvexHull(vertices)
    faces = np.array(hull.simplices, dtype=np.int64)
    p = vertices[faces]
    outward = np.einsum("ij,ij->i", np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), hull.equations[:, :3]) > 0.0
    faces[~outward] = faces[~outward][:, ::-1]
    used, faces = np.unique(faces, return_inverse=True)
    return vertices[used], faces.reshape(-1, 3)


# ---------------------------------------------------------------------------------------
# What is touched: exclusions, refusals, flexes
# ---------------------------------------------------------------------------------------

def exclusions(model: mujoco.MjModel, exclude=(), exclude_groups=()) -> tuple[set[int], set[int]]:
    """The geoms and flexes (ids) kept out of haptic contact: those named in `exclude` and those
    in a geom group of `exclude_groups` (0 to 5). MuJoCo still collides with them. ValueError,
    one line, for a name that is no geom or flex of the model, or a group out of range."""
    if not isinstance(exclude, (list, tuple, set, frozenset)) or not all(isinstance(n, str) for n in exclude):
        raise ValueError(f"exclude must be a list of geom or flex names, got {exclude!r}")
    if not isinstance(exclude_groups, (list, tuple, set, frozenset)) or not all(
            isinstance(g, int) and not isinstance(g, bool) and 0 <= g < GEOM_GROUPS for g in exclude_groups):
        raise ValueError(f"exclude_groups must be a list of geom groups (integers 0 to {GEOM_GROUPS - 1}), "
                         f"got {exclude_groups!r}")
    groups = set(exclude_groups)
    geoms = {g for g in range(model.ngeom) if int(model.geom_group[g]) in groups}
    flexes = {f for f in range(model.nflex) if int(model.flex_group[f]) in groups}
    for name in exclude:
        g = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, name)
        f = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_FLEX, name)
        if g < 0 and f < 0:
            geom_names = (mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, k) for k in range(model.ngeom))
            named = [n for n in geom_names if n]
            listed = ", ".join(named[:12]) + (", ..." if len(named) > 12 else "") if named else "none named"
            raise ValueError(f"exclude names {name!r}, which is no geom or flex of the model; its geoms: {listed}")
        if g >= 0:
            geoms.add(g)
        if f >= 0:
            flexes.add(f)
    return geoms, flexes


def unsupported_geoms(model: mujoco.MjModel, excluded=frozenset()) -> list[int]:
    """Touchable geoms, not excluded, of a type the fingers cannot touch (SDF)."""
    return [g for g in range(model.ngeom) if touchable(model, g) and g not in excluded
            and int(model.geom_type[g]) not in SHAPES and int(model.geom_type[g]) not in (_MESH, _HFIELD)]


def unsupported_message(model: mujoco.MjModel, geoms: list[int], scene: bool = False) -> str:
    """One line naming every geom in `geoms` and how to keep them in MuJoCo's physics but out of
    haptic contact: the `World` / `shapes_of` arguments, or the scene's [haptics] fields."""
    names = [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in geoms]
    groups = sorted({int(model.geom_group[g]) for g, n in zip(geoms, names) if not n})
    named = [n for n in names if n]
    if scene:
        fixes = ([f"exclude = {json.dumps(named)}"] if named else []) + ([f"exclude_groups = {groups}"] if groups else [])
        fix = "set " + " and ".join(fixes) + " in the scene's [haptics] table"
    else:
        fixes = ([f"exclude={named}"] if named else []) + ([f"exclude_groups={groups}"] if groups else [])
        fix = "pass " + ", ".join(fixes) + " to World (or shapes_of)"
    return (f"the fingers cannot touch geom(s) {', '.join(geom_label(model, g) for g in geoms)}: an SDF's "
            f"distance lives inside MuJoCo's collision code; to keep them in MuJoCo's physics but out of "
            f"haptic contact, {fix}")


def unfelt_flexes(model: mujoco.MjModel, excluded=frozenset()) -> list[int]:
    """Flexes that collide in MuJoCo (contype or conaffinity set), not excluded: the fingers pass
    through them (a flex deforms every step; the engine's meshes are rigid)."""
    return [f for f in range(model.nflex) if f not in excluded
            and (int(model.flex_contype[f]) or int(model.flex_conaffinity[f]))]


def flex_message(model: mujoco.MjModel, flexes: list[int]) -> str:
    """One line naming the flexes the fingers do not feel."""
    labels = []
    for f in flexes:
        name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_FLEX, f)
        labels.append(f"{name!r}" if name else f"#{f}")
    return (f"flex(es) {', '.join(labels)} collide in MuJoCo but the fingers do not feel them (a finger passes "
            f"through a deformable body); exclude them by name or group to silence this")


def _outside_softproxy() -> int:
    """The `stacklevel` that points a warning at the first caller outside softproxy (the user's
    `World(...)` or `shapes_of(...)` line, not softproxy's own)."""
    package = os.path.dirname(os.path.abspath(__file__)) + os.sep
    frame, level = sys._getframe(1), 1
    while frame is not None and os.path.abspath(frame.f_code.co_filename).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def shapes_of(model: mujoco.MjModel, data: mujoco.MjData, mesh_shape=None, *, exclude=(), exclude_groups=(),
              mesh_surface: str = "true") -> ShapeSet:
    """The ShapeSet of every touchable geom not excluded (see `exclusions`).

    Primitives are themselves; a mesh geom is its own triangles (`mesh_surface="true"`) or the
    convex hull MuJoCo collides with ("hull", `hull_triangles`); a height field is its solid
    (`hfield_triangles`). Meshes and height fields are built by `mesh_shape(model, data, geom,
    static, triangles=(vertices, faces))` (default `softproxy.mesh.MeshShape`; a true-surface
    mesh is called without `triangles`). A touchable SDF geom not excluded raises ValueError
    naming every such geom and the fix; collidable flexes not excluded are named by one
    `FlexWarning` (the fingers do not feel them).
    """
    if mesh_surface not in MESH_SURFACES:
        raise ValueError(f"mesh_surface must be one of {', '.join(map(repr, MESH_SURFACES))}, got {mesh_surface!r}")
    geoms, flexes = exclusions(model, exclude, exclude_groups)
    refused = unsupported_geoms(model, geoms)
    if refused:
        raise ValueError(unsupported_message(model, refused))
    unfelt = unfelt_flexes(model, flexes)
    if unfelt:
        warnings.warn(flex_message(model, unfelt), FlexWarning, stacklevel=_outside_softproxy())
    out = []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _touchable_shapes(model, data, mesh_shape, mesh_surface, geoms, out)
    _warn_once_per_cause(caught)
    return ShapeSet(out, data)


def _warn_once_per_cause(caught: list) -> None:
    """Warnings caught while building shapes, said again: a mesh defect once per asset and
    defect however many geoms use the asset (`MeshWarning.of` names them), others as they were."""
    merged = {}
    for w in caught:
        m = w.message
        if getattr(m, "defect", "") and hasattr(type(m), "of"):
            names = merged.setdefault((type(m), m.mesh, m.file, m.defect), [])
            for g in m.geoms:
                if g not in names:
                    names.append(g)
        else:
            warnings.warn_explicit(m, w.category, w.filename, w.lineno)
    for (cls, mesh, file, defect), names in merged.items():
        warnings.warn(cls.of(mesh, names, file, defect), stacklevel=_outside_softproxy())


def _touchable_shapes(model, data, mesh_shape, mesh_surface: str, geoms: set, out: list) -> None:
    """Append to `out` a shape for every touchable geom not in `geoms` (`shapes_of`)."""
    for g in range(model.ngeom):
        if not touchable(model, g) or g in geoms:
            continue
        gtype = int(model.geom_type[g])
        static = body_is_static(model, int(model.geom_bodyid[g]))
        cls = SHAPES.get(gtype)
        if cls is not None:
            out.append(cls(model, data, g, static))
            continue
        if mesh_shape is None:
            from softproxy.mesh import MeshShape as mesh_shape  # trimesh is imported only for worlds with meshes
        if gtype == _HFIELD:
            out.append(mesh_shape(model, data, g, static, triangles=hfield_triangles(model, g)))
        elif mesh_surface == "hull":
            out.append(mesh_shape(model, data, g, static, triangles=hull_triangles(model, g)))
        else:
            out.append(mesh_shape(model, data, g, static))
