"""Proxy-vs-shape queries on MuJoCo geoms: signed distance, outward normal, and swept contact.

Each collidable geom of a MuJoCo model becomes a `Shape` that answers, in world coordinates:
- `distance(x, y, z)`: signed distance from the geom's surface (m, < 0 inside) and the
  outward unit normal at the closest surface point;
- `sweep(...)`: the first point where a sphere of radius r moving on a segment touches the
  geom *while moving into it* (continuous collision: nothing is skipped between ticks).

Every primitive is convex, so a sphere that touches it and moves along or away from the
tangent plane can never enter it: `sweep` reports nothing in that case, which is what lets
the god-object slide along faces. Non-convex meshes are sets of triangles, each convex.
The hot path is scalar Python on cached poses; `refresh` copies a moving geom's pose once
per tick.
"""

from __future__ import annotations

import math

import mujoco

CONTACT_TOL = 1e-9
"""A sphere within this distance (m) of a surface touches it."""
GRAZE = 1e-9
"""A touching sphere moves *into* a surface only if the motion's inward component exceeds
this fraction of its length; below it the motion is tangent (rounding noise)."""
FACE_PARALLEL = 1.0 - 1e-12
"""A normal this aligned with a face's normal (cosine) is that face's."""
MAX_ADVANCE_STEPS = 32
"""Conservative-advancement iterations before a grazing sweep stops short (safe side)."""


class Shape:
    """One MuJoCo geom as seen by a proxy. Subclasses give the signed distance in the geom
    frame (`local_distance`), or override `distance` whole where the world-frame form is
    cheaper (plane, sphere, box: the shapes touched most)."""

    flat = False
    """True when every face is planar (the solver then needs no curvature refinement)."""
    convex = False
    """True when the shape (and so the shape inflated by the proxy's radius) is convex: it then
    lies behind every plane that touches it, which lets the god-object skip sweeping it along
    such a plane (`GodObject._sweep`)."""

    __slots__ = ("geom", "body", "name", "static", "rbound", "px", "py", "pz",
                 "r00", "r01", "r02", "r10", "r11", "r12", "r20", "r21", "r22", "_xpos", "_xmat", "cvel")

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, geom: int, static: bool) -> None:
        self.geom = geom
        self.body = int(model.geom_bodyid[geom])
        self.name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, geom) or f"geom{geom}"
        self.static = static
        self.rbound = math.inf if int(model.geom_type[geom]) == int(mujoco.mjtGeom.mjGEOM_PLANE) else float(model.geom_rbound[geom])
        # views into mjData, kept: each `data.geom_xpos` access builds a new array object
        self._xpos = data.geom_xpos[geom]
        self._xmat = data.geom_xmat[geom]
        self.cvel = data.cvel[self.body]
        """The body's velocity (ω, v) in MuJoCo's com-based frame, rad/s and m/s, current after
        mj_step1: a view into mjData, ω read by the fingers that touch it (eqs 41–42)."""
        self.refresh()

    def refresh(self) -> None:
        """Copy the geom's world pose from mjData (after mj_kinematics / mj_step1)."""
        self.px, self.py, self.pz = self._xpos.tolist()
        (self.r00, self.r01, self.r02, self.r10, self.r11, self.r12,
         self.r20, self.r21, self.r22) = self._xmat.tolist()

    def prepare(self, radius: float) -> None:
        """Get ready for a proxy of `radius` (m): build now whatever its queries would otherwise
        build inside the servo tick. Primitives need nothing; meshes build certificates."""

    def to_local(self, x: float, y: float, z: float) -> tuple[float, float, float]:
        dx, dy, dz = x - self.px, y - self.py, z - self.pz
        return (self.r00 * dx + self.r10 * dy + self.r20 * dz,
                self.r01 * dx + self.r11 * dy + self.r21 * dz,
                self.r02 * dx + self.r12 * dy + self.r22 * dz)

    def local_distance(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        """Signed distance and outward normal in the geom frame."""
        raise NotImplementedError

    def distance(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        """Signed distance from the surface (m) and outward unit normal, world frame."""
        dx, dy, dz = x - self.px, y - self.py, z - self.pz
        d, nx, ny, nz = self.local_distance(self.r00 * dx + self.r10 * dy + self.r20 * dz,
                                            self.r01 * dx + self.r11 * dy + self.r21 * dz,
                                            self.r02 * dx + self.r12 * dy + self.r22 * dz)
        return (d,
                self.r00 * nx + self.r01 * ny + self.r02 * nz,
                self.r10 * nx + self.r11 * ny + self.r12 * nz,
                self.r20 * nx + self.r21 * ny + self.r22 * nz)

    def on_face(self, nx: float, ny: float, nz: float) -> bool:
        """True when a contact of normal n (world) lies on a planar face, not on a rounded
        edge or corner of the proxy-swept shape: the contact plane then holds as long as the
        proxy touches the shape (see `GodObject._solve`)."""
        return False

    def sweep(self, x0: float, y0: float, z0: float, dx: float, dy: float, dz: float, r: float):
        """First touch of a sphere (radius r) moving from x0 by (dx, dy, dz) into the geom.

        Returns (fraction in [0, 1), nx, ny, nz) or None. Conservative advancement to the
        supporting plane: the shape is convex, so it lies behind the tangent plane at its
        point nearest the sphere, and the sphere cannot touch it before reaching that plane;
        a thin plate crossed at any speed stops the sphere on its near side. Convexity also
        ends the search early: the distance is convex along the segment, so once the motion
        stops approaching (n·d ≥ 0, within GRAZE) the sphere never comes closer.
        """
        length = math.sqrt(dx * dx + dy * dy + dz * dz)
        if length == 0.0:
            return None
        graze = GRAZE * length
        lam = 0.0
        for _ in range(MAX_ADVANCE_STEPS):
            d, nx, ny, nz = self.distance(x0 + lam * dx, y0 + lam * dy, z0 + lam * dz)
            approach = -(nx * dx + ny * dy + nz * dz)
            if approach <= graze:  # along or away from the surface: never closer
                return None
            gap = d - r
            if gap <= CONTACT_TOL:
                return (lam, nx, ny, nz)
            lam += gap / approach
            if lam >= 1.0:
                return None
        # grazing approach not yet converged: stop here, short of the surface (safe)
        return (lam, nx, ny, nz)


class PlaneShape(Shape):
    """MuJoCo plane: infinite for collision, outward normal +z of the geom frame."""

    flat = True
    convex = True
    __slots__ = ()

    def on_face(self, nx, ny, nz):
        return True

    def distance(self, x, y, z):
        nx, ny, nz = self.r02, self.r12, self.r22
        return (nx * (x - self.px) + ny * (y - self.py) + nz * (z - self.pz), nx, ny, nz)

    def sweep(self, x0, y0, z0, dx, dy, dz, r):
        nx, ny, nz = self.r02, self.r12, self.r22
        gap = nx * (x0 - self.px) + ny * (y0 - self.py) + nz * (z0 - self.pz) - r
        approach = nx * dx + ny * dy + nz * dz
        if approach >= -GRAZE * math.sqrt(dx * dx + dy * dy + dz * dz):
            return None
        if gap <= CONTACT_TOL:
            return (0.0, nx, ny, nz)
        lam = gap / -approach
        return (lam, nx, ny, nz) if lam < 1.0 else None


class SphereShape(Shape):
    convex = True
    __slots__ = ("radius",)

    def __init__(self, model, data, geom, static):
        self.radius = float(model.geom_size[geom][0])
        super().__init__(model, data, geom, static)

    def distance(self, x, y, z):
        # rotation-free: the centre is all that matters
        dx, dy, dz = x - self.px, y - self.py, z - self.pz
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        if n == 0.0:
            return (-self.radius, self.r02, self.r12, self.r22)
        return (n - self.radius, dx / n, dy / n, dz / n)


class CapsuleShape(Shape):
    """Capsule: radius, half-length along the geom's z axis."""

    convex = True
    __slots__ = ("radius", "half")

    def __init__(self, model, data, geom, static):
        self.radius, self.half = (float(v) for v in model.geom_size[geom][:2])
        super().__init__(model, data, geom, static)

    def local_distance(self, x, y, z):
        h = self.half
        zc = z - (h if z > h else -h if z < -h else z)
        n = math.sqrt(x * x + y * y + zc * zc)
        if n == 0.0:
            return (-self.radius, 1.0, 0.0, 0.0)
        return (n - self.radius, x / n, y / n, zc / n)


class CylinderShape(Shape):
    """Cylinder: radius, half-height along the geom's z axis (flat caps, sharp rims)."""

    convex = True
    __slots__ = ("radius", "half")

    def __init__(self, model, data, geom, static):
        self.radius, self.half = (float(v) for v in model.geom_size[geom][:2])
        super().__init__(model, data, geom, static)

    def local_distance(self, x, y, z):
        rho = math.sqrt(x * x + y * y)
        dr = rho - self.radius
        dz = abs(z) - self.half
        sz = 1.0 if z >= 0.0 else -1.0
        if rho > 0.0:
            ux, uy = x / rho, y / rho
        else:
            ux, uy = 1.0, 0.0
        if dr <= 0.0 and dz <= 0.0:  # inside: nearest of side and cap
            return (dr, ux, uy, 0.0) if dr > dz else (dz, 0.0, 0.0, sz)
        if dr <= 0.0:
            return (dz, 0.0, 0.0, sz)
        if dz <= 0.0:
            return (dr, ux, uy, 0.0)
        n = math.sqrt(dr * dr + dz * dz)  # nearest point on the rim
        return (n, ux * dr / n, uy * dr / n, sz * dz / n)


class BoxShape(Shape):
    """Box: half-sizes along the geom axes."""

    flat = True
    convex = True
    __slots__ = ("hx", "hy", "hz")

    def __init__(self, model, data, geom, static):
        self.hx, self.hy, self.hz = (float(v) for v in model.geom_size[geom][:3])
        super().__init__(model, data, geom, static)

    def distance(self, x, y, z):
        # Shape.distance with the local query inlined: the box is the commonest shape touched
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (self.r00, self.r01, self.r02, self.r10, self.r11,
                                                       self.r12, self.r20, self.r21, self.r22)
        dx, dy, dz = x - self.px, y - self.py, z - self.pz
        lx = r00 * dx + r10 * dy + r20 * dz
        ly = r01 * dx + r11 * dy + r21 * dz
        lz = r02 * dx + r12 * dy + r22 * dz
        sx = 1.0 if lx >= 0.0 else -1.0
        sy = 1.0 if ly >= 0.0 else -1.0
        sz = 1.0 if lz >= 0.0 else -1.0
        qx, qy, qz = sx * lx - self.hx, sy * ly - self.hy, sz * lz - self.hz
        if qx <= 0.0 and qy <= 0.0 and qz <= 0.0:  # inside: the nearest face
            if qx >= qy and qx >= qz:
                return (qx, sx * r00, sx * r10, sx * r20)
            if qy >= qz:
                return (qy, sy * r01, sy * r11, sy * r21)
            return (qz, sz * r02, sz * r12, sz * r22)
        ox = sx * qx if qx > 0.0 else 0.0
        oy = sy * qy if qy > 0.0 else 0.0
        oz = sz * qz if qz > 0.0 else 0.0
        n = math.sqrt(ox * ox + oy * oy + oz * oz)
        ox, oy, oz = ox / n, oy / n, oz / n
        return (n, r00 * ox + r01 * oy + r02 * oz, r10 * ox + r11 * oy + r12 * oz, r20 * ox + r21 * oy + r22 * oz)

    def on_face(self, nx, ny, nz):
        # a face normal is a geom axis; an edge or corner normal of the rounded box is not
        return (abs(self.r00 * nx + self.r10 * ny + self.r20 * nz) > FACE_PARALLEL
                or abs(self.r01 * nx + self.r11 * ny + self.r21 * nz) > FACE_PARALLEL
                or abs(self.r02 * nx + self.r12 * ny + self.r22 * nz) > FACE_PARALLEL)


class EllipsoidShape(Shape):
    """Ellipsoid: semi-axes along the geom axes. Exact distance by a 1-D root find."""

    convex = True
    __slots__ = ("a", "b", "c")

    def __init__(self, model, data, geom, static):
        self.a, self.b, self.c = (float(v) for v in model.geom_size[geom][:3])
        super().__init__(model, data, geom, static)

    def local_distance(self, x, y, z):
        # Closest point q_i = a_i² p_i / (t + a_i²), where t solves
        # f(t) = Σ (a_i p_i / (t + a_i²))² - 1 = 0; f decreases on t > -min a_i².
        a2, b2, c2 = self.a * self.a, self.b * self.b, self.c * self.c
        lo = -min(a2, b2, c2)
        g = (x * x) / a2 + (y * y) / b2 + (z * z) / c2
        if g == 0.0:  # the centre: nearest is the end of the shortest axis
            m = min(self.a, self.b, self.c)
            return (-m, 1.0, 0.0, 0.0) if m == self.a else (-m, 0.0, 1.0, 0.0) if m == self.b else (-m, 0.0, 0.0, 1.0)
        hi = max(self.a, self.b, self.c) * math.sqrt(x * x + y * y + z * z) + 0.0
        hi = hi if hi > 0.0 else 1.0
        lo_t = lo * (1.0 - 1e-12) if g < 1.0 else 0.0
        hi_t = 0.0 if g < 1.0 else hi
        t = 0.5 * (lo_t + hi_t)
        for _ in range(100):
            ea, eb, ec = a2 + t, b2 + t, c2 + t
            fx, fy, fz = self.a * x / ea, self.b * y / eb, self.c * z / ec
            f = fx * fx + fy * fy + fz * fz - 1.0
            if f > 0.0:
                lo_t = t
            else:
                hi_t = t
            df = -2.0 * (fx * fx / ea + fy * fy / eb + fz * fz / ec)
            nt = t - f / df if df != 0.0 else 0.5 * (lo_t + hi_t)
            if not lo_t < nt < hi_t:
                nt = 0.5 * (lo_t + hi_t)
            if abs(nt - t) <= 1e-15 * (abs(t) + a2):
                t = nt
                break
            t = nt
        qx, qy, qz = a2 * x / (a2 + t), b2 * y / (b2 + t), c2 * z / (c2 + t)
        ex, ey, ez = x - qx, y - qy, z - qz
        dist = math.sqrt(ex * ex + ey * ey + ez * ez)
        # outward normal at q is the gradient of the implicit function there
        gx, gy, gz = qx / a2, qy / b2, qz / c2
        gn = math.sqrt(gx * gx + gy * gy + gz * gz)
        return ((dist if g >= 1.0 else -dist), gx / gn, gy / gn, gz / gn)


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


def shapes_of(model: mujoco.MjModel, data: mujoco.MjData, mesh_shape=None) -> list[Shape]:
    """A Shape for every touchable geom. Unsupported geom types raise ValueError naming the geom.

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
    return out
