"""Proxy-vs-shape queries: signed distance, outward normal and swept contact, per shape record.

Each function answers one query (distance, sweep, on_face, to_local) for row k of the shape
table S (`SHAPE` records, `softproxy.compiled.layout`) with the pose read straight from
MuJoCo's `geom_xpos` / `geom_xmat`; the `Shape` methods users call are these functions.
Every primitive is convex, so a sphere that touches it and moves along or away from the
tangent plane can never enter it: `shape_sweep` reports nothing then, which is what lets
the god-object slide along faces. Meshes are answered by `softproxy.compiled.mesh` from the
mesh tables T and C; in a world without meshes T and C are None, and numba prunes the mesh
branch on that type, so the mesh kernels are not compiled at all.
"""

import math

from numba import njit

from softproxy.compiled.layout import (
    GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH, GEOM_PLANE, GEOM_SPHERE,
)
from softproxy.compiled.mesh import mesh_distance, mesh_sweep
from softproxy.compiled.tolerances import CONTACT_TOL, FACE_PARALLEL, GRAZE, MAX_ADVANCE_STEPS


@njit(cache=True, error_model="numpy")
def shape_to_local(S, xpos, xmat, k, x, y, z):
    """World point (m) to shape k's geom frame (m), as `Shape.to_local`."""
    g = int(S[k].geom)
    dx, dy, dz = x - xpos[g, 0], y - xpos[g, 1], z - xpos[g, 2]
    return (xmat[g, 0] * dx + xmat[g, 3] * dy + xmat[g, 6] * dz,
            xmat[g, 1] * dx + xmat[g, 4] * dy + xmat[g, 7] * dz,
            xmat[g, 2] * dx + xmat[g, 5] * dy + xmat[g, 8] * dz)


@njit(cache=True, error_model="numpy")
def shape_to_world(S, xpos, xmat, k, lx, ly, lz):
    """Point in shape k's geom frame (m) to world (m): the inverse of `shape_to_local`."""
    g = int(S[k].geom)
    return (xmat[g, 0] * lx + xmat[g, 1] * ly + xmat[g, 2] * lz + xpos[g, 0],
            xmat[g, 3] * lx + xmat[g, 4] * ly + xmat[g, 5] * lz + xpos[g, 1],
            xmat[g, 6] * lx + xmat[g, 7] * ly + xmat[g, 8] * lz + xpos[g, 2])


@njit(cache=True, error_model="numpy")
def _capsule_local(radius, half, x, y, z):
    """CapsuleShape.local_distance: signed distance (m) and outward normal, geom frame."""
    h = half
    zc = z - (h if z > h else -h if z < -h else z)
    n = math.sqrt(x * x + y * y + zc * zc)
    if n == 0.0:
        return (-radius, 1.0, 0.0, 0.0)
    return (n - radius, x / n, y / n, zc / n)


@njit(cache=True, error_model="numpy")
def _cylinder_local(radius, half, x, y, z):
    """CylinderShape.local_distance: signed distance (m) and outward normal, geom frame."""
    rho = math.sqrt(x * x + y * y)
    dr = rho - radius
    dz = abs(z) - half
    sz = 1.0 if z >= 0.0 else -1.0
    if rho > 0.0:
        ux, uy = x / rho, y / rho
    else:
        ux, uy = 1.0, 0.0
    if dr <= 0.0 and dz <= 0.0:
        if dr > dz:
            return (dr, ux, uy, 0.0)
        return (dz, 0.0, 0.0, sz)
    if dr <= 0.0:
        return (dz, 0.0, 0.0, sz)
    if dz <= 0.0:
        return (dr, ux, uy, 0.0)
    n = math.sqrt(dr * dr + dz * dz)
    return (n, ux * dr / n, uy * dr / n, sz * dz / n)


@njit(cache=True, error_model="numpy")
def _ellipsoid_local(a, b, c, x, y, z):
    """EllipsoidShape.local_distance: signed distance (m) and outward normal, geom frame."""
    a2, b2, c2 = a * a, b * b, c * c
    lo = -min(a2, b2, c2)
    g = (x * x) / a2 + (y * y) / b2 + (z * z) / c2
    if g == 0.0:
        m = min(a, b, c)
        if m == a:
            return (-m, 1.0, 0.0, 0.0)
        if m == b:
            return (-m, 0.0, 1.0, 0.0)
        return (-m, 0.0, 0.0, 1.0)
    hi = max(a, b, c) * math.sqrt(x * x + y * y + z * z) + 0.0
    hi = hi if hi > 0.0 else 1.0
    lo_t = lo * (1.0 - 1e-12) if g < 1.0 else 0.0
    hi_t = 0.0 if g < 1.0 else hi
    t = 0.5 * (lo_t + hi_t)
    for _ in range(100):
        ea, eb, ec = a2 + t, b2 + t, c2 + t
        fx, fy, fz = a * x / ea, b * y / eb, c * z / ec
        f = fx * fx + fy * fy + fz * fz - 1.0
        if f > 0.0:
            lo_t = t
        else:
            hi_t = t
        df = -2.0 * (fx * fx / ea + fy * fy / eb + fz * fz / ec)
        nt = t - f / df if df != 0.0 else 0.5 * (lo_t + hi_t)
        if not (lo_t < nt and nt < hi_t):
            nt = 0.5 * (lo_t + hi_t)
        if abs(nt - t) <= 1e-15 * (abs(t) + a2):
            t = nt
            break
        t = nt
    qx, qy, qz = a2 * x / (a2 + t), b2 * y / (b2 + t), c2 * z / (c2 + t)
    ex, ey, ez = x - qx, y - qy, z - qz
    dist = math.sqrt(ex * ex + ey * ey + ez * ez)
    gx, gy, gz = qx / a2, qy / b2, qz / c2
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    return ((dist if g >= 1.0 else -dist), gx / gn, gy / gn, gz / gn)


@njit(cache=True, error_model="numpy")
def shape_distance(S, T, C, xpos, xmat, k, x, y, z):
    """Signed distance (m, < 0 inside) from shape k and outward unit normal, world frame."""
    t = int(S[k].type)
    if t == GEOM_MESH:
        if T is None:  # a world without meshes (T, C are None): the mesh kernels are not compiled
            return (math.inf, 0.0, 0.0, 1.0)
        return mesh_distance(S, T, C, xpos, xmat, k, x, y, z)
    g = int(S[k].geom)
    px, py, pz = xpos[g, 0], xpos[g, 1], xpos[g, 2]
    r00, r01, r02 = xmat[g, 0], xmat[g, 1], xmat[g, 2]
    r10, r11, r12 = xmat[g, 3], xmat[g, 4], xmat[g, 5]
    r20, r21, r22 = xmat[g, 6], xmat[g, 7], xmat[g, 8]
    if t == GEOM_PLANE:
        return (r02 * (x - px) + r12 * (y - py) + r22 * (z - pz), r02, r12, r22)
    if t == GEOM_SPHERE:
        radius = S[k].a
        dx, dy, dz = x - px, y - py, z - pz
        n = math.sqrt(dx * dx + dy * dy + dz * dz)
        if n == 0.0:
            return (-radius, r02, r12, r22)
        return (n - radius, dx / n, dy / n, dz / n)
    dx, dy, dz = x - px, y - py, z - pz
    lx = r00 * dx + r10 * dy + r20 * dz
    ly = r01 * dx + r11 * dy + r21 * dz
    lz = r02 * dx + r12 * dy + r22 * dz
    if t == GEOM_BOX:
        sx = 1.0 if lx >= 0.0 else -1.0
        sy = 1.0 if ly >= 0.0 else -1.0
        sz = 1.0 if lz >= 0.0 else -1.0
        qx, qy, qz = sx * lx - S[k].a, sy * ly - S[k].b, sz * lz - S[k].c
        if qx <= 0.0 and qy <= 0.0 and qz <= 0.0:
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
        return (n, r00 * ox + r01 * oy + r02 * oz, r10 * ox + r11 * oy + r12 * oz,
                r20 * ox + r21 * oy + r22 * oz)
    if t == GEOM_CAPSULE:
        d, nx, ny, nz = _capsule_local(S[k].a, S[k].b, lx, ly, lz)
    elif t == GEOM_CYLINDER:
        d, nx, ny, nz = _cylinder_local(S[k].a, S[k].b, lx, ly, lz)
    elif t == GEOM_ELLIPSOID:
        d, nx, ny, nz = _ellipsoid_local(S[k].a, S[k].b, S[k].c, lx, ly, lz)
    else:
        raise ValueError("shape_distance: unsupported shape type")
    return (d,
            r00 * nx + r01 * ny + r02 * nz,
            r10 * nx + r11 * ny + r12 * nz,
            r20 * nx + r21 * ny + r22 * nz)


@njit(cache=True, error_model="numpy")
def shape_sweep(S, T, C, xpos, xmat, k, x0, y0, z0, dx, dy, dz, r):
    """First touch (fraction in [0, 1), world normal) of a sphere of radius r (m) moving from
    x0 by (dx, dy, dz) (m) into shape k; (-1.0, 0.0, 0.0, 0.0) when it touches nothing."""
    t = int(S[k].type)
    if t == GEOM_MESH:
        if T is None:
            return (-1.0, 0.0, 0.0, 0.0)
        return mesh_sweep(S, T, C, xpos, xmat, k, x0, y0, z0, dx, dy, dz, r)
    if t == GEOM_PLANE:
        g = int(S[k].geom)
        nx, ny, nz = xmat[g, 2], xmat[g, 5], xmat[g, 8]
        gap = nx * (x0 - xpos[g, 0]) + ny * (y0 - xpos[g, 1]) + nz * (z0 - xpos[g, 2]) - r
        approach = nx * dx + ny * dy + nz * dz
        if approach >= -GRAZE * math.sqrt(dx * dx + dy * dy + dz * dz):
            return (-1.0, 0.0, 0.0, 0.0)
        if gap <= CONTACT_TOL:
            return (0.0, nx, ny, nz)
        lam = gap / -approach
        if lam < 1.0:
            return (lam, nx, ny, nz)
        return (-1.0, 0.0, 0.0, 0.0)
    length = math.sqrt(dx * dx + dy * dy + dz * dz)
    if length == 0.0:
        return (-1.0, 0.0, 0.0, 0.0)
    graze = GRAZE * length
    lam = 0.0
    nx, ny, nz = 0.0, 0.0, 0.0
    for _ in range(MAX_ADVANCE_STEPS):
        d, nx, ny, nz = shape_distance(S, T, C, xpos, xmat, k, x0 + lam * dx, y0 + lam * dy, z0 + lam * dz)
        approach = -(nx * dx + ny * dy + nz * dz)
        if approach <= graze:
            return (-1.0, 0.0, 0.0, 0.0)
        gap = d - r
        if gap <= CONTACT_TOL:
            return (lam, nx, ny, nz)
        lam += gap / approach
        if lam >= 1.0:
            return (-1.0, 0.0, 0.0, 0.0)
    return (lam, nx, ny, nz)


@njit(cache=True, error_model="numpy")
def shape_on_face(S, xmat, k, nx, ny, nz):
    """True when world normal n lies on a planar face of shape k (plane always, box faces;
    never on a mesh: see `softproxy.compiled.mesh`)."""
    t = int(S[k].type)
    if t == GEOM_PLANE:
        return True
    if t == GEOM_BOX:
        g = int(S[k].geom)
        return (abs(xmat[g, 0] * nx + xmat[g, 3] * ny + xmat[g, 6] * nz) > FACE_PARALLEL
                or abs(xmat[g, 1] * nx + xmat[g, 4] * ny + xmat[g, 7] * nz) > FACE_PARALLEL
                or abs(xmat[g, 2] * nx + xmat[g, 5] * ny + xmat[g, 8] * nz) > FACE_PARALLEL)
    return False
