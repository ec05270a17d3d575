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

from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (
    GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_MESH, GEOM_PLANE, GEOM_SPHERE,
)
from softproxy.compiled.mesh import mesh_distance, mesh_sweep, mesh_triangle_distance, mesh_walk_distance
from softproxy.compiled.tolerances import CONTACT_TOL, FACE_PARALLEL, GRAZE, MAX_ADVANCE_STEPS
from softproxy.compiled.vector import point_in_geom_frame, to_world_frame

ELLIPSOID_STEPS = 64
"""Most steps of the ellipsoid's root finder (a Newton step each, and a bisection where Newton
is slow). It reaches the root to rounding in at most 12 over 10⁵ random points of ellipsoids
from round to 1 nm thin, on and off their mid-planes and axes, from 1e-300 m to 5 km out."""


@kernel
def shape_to_local(S, xpos, xmat, k, x, y, z):
    """World point (m) to shape k's geom frame (m), as `Shape.to_local`."""
    g = int(S[k].geom)
    return point_in_geom_frame(xpos, xmat, g, x, y, z)


@kernel
def shape_to_world(S, xpos, xmat, k, lx, ly, lz):
    """Point in shape k's geom frame (m) to world (m): the inverse of `shape_to_local`."""
    g = int(S[k].geom)
    wx, wy, wz = to_world_frame(xmat, g, lx, ly, lz)
    return wx + xpos[g, 0], wy + xpos[g, 1], wz + xpos[g, 2]


@kernel
def _capsule_local(radius, half, x, y, z):
    """Capsule (radius, half-length along z): signed distance (m) and outward normal, geom frame."""
    h = half
    zc = z - (h if z > h else -h if z < -h else z)
    n = math.sqrt(x * x + y * y + zc * zc)
    if n == 0.0:
        return (-radius, 1.0, 0.0, 0.0)
    return (n - radius, x / n, y / n, zc / n)


@kernel
def _cylinder_local(radius, half, x, y, z):
    """Cylinder (radius, half-height along z): signed distance (m) and outward normal, geom frame."""
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


@kernel
def _ellipsoid_f(k0, k1, k2, d0, d1, d2, w):
    """F(w) = Σ (k_i / (d_i + w))² - 1 and F'(w), the terms with k_i = 0 left out (they are 0,
    even where d_i + w is: on the mid-plane of a shortest semi-axis at w = 0)."""
    f, df = -1.0, 0.0
    if k0 > 0.0:
        q = k0 / (d0 + w)
        f += q * q
        df -= 2.0 * q * q / (d0 + w)
    if k1 > 0.0:
        q = k1 / (d1 + w)
        f += q * q
        df -= 2.0 * q * q / (d1 + w)
    if k2 > 0.0:
        q = k2 / (d2 + w)
        f += q * q
        df -= 2.0 * q * q / (d2 + w)
    return f, df


@kernel
def _ellipsoid_local(a, b, c, x, y, z):
    """Ellipsoid (semi-axes a, b, c): signed distance (m) and outward normal, geom frame.

    The nearest point is q_i = a_i² p_i / (a_i² + t) for the root t > -m² (m: the shortest
    semi-axis) of Σ (a_i p_i / (a_i² + t))² = 1. It is solved for w = t + m² > 0, so that w
    keeps its full relative precision where the root nears the pole t = -m² (inside, near the
    mid-plane across the shortest semi-axis, where q leaves that plane: t + m² would cancel):
    F(w) = Σ (k_i / (d_i + w))² - 1, k_i = a_i |p_i|, d_i = a_i² - m² >= 0 (0 for every
    shortest semi-axis), is convex and decreasing, so Newton's step from below never passes
    the root; a bisection (geometric while the bracket spans more than a factor 2) helps where
    Newton is slow. On that mid-plane itself (every k_i of a shortest semi-axis 0) with
    F(0) <= 0 the root is w = 0 and q lies off the plane, along the first shortest semi-axis,
    by the rest of the unit sum (Eberly, "Distance from a point to an ellipse, an ellipsoid,
    or a hyperellipsoid": the degenerate case; the centre of a ball is one)."""
    m = min(a, b, c)
    k0, k1, k2 = a * abs(x), b * abs(y), c * abs(z)
    d0, d1, d2 = (a - m) * (a + m), (b - m) * (b + m), (c - m) * (c + m)
    lo = max(k0 - d0, k1 - d1, k2 - d2, 0.0)  # each term is <= 1 at the root: d_i + w >= k_i
    top = max(k0, k1, k2)  # hi = |k| (each d_i + w >= w: F(hi) <= 0), scaled: k_i² may underflow
    hi = top * math.sqrt((k0 / top) ** 2 + (k1 / top) ** 2 + (k2 / top) ** 2) if top > 0.0 else 0.0
    f_lo, df_lo = _ellipsoid_f(k0, k1, k2, d0, d1, d2, lo)
    if f_lo <= 0.0 and lo == 0.0:
        # on the mid-plane (or axis, or centre) of the shortest semi-axes, inside the evolute:
        # u_i = k_i / d_i along the others, and the rest of the unit sum off the plane
        u0 = k0 / d0 if d0 > 0.0 else 0.0
        u1 = k1 / d1 if d1 > 0.0 else 0.0
        u2 = k2 / d2 if d2 > 0.0 else 0.0
        off = math.sqrt(-f_lo)
        if d0 == 0.0:
            u0 = off
        elif d1 == 0.0:
            u1 = off
        else:
            u2 = off
    else:
        for _ in range(ELLIPSOID_STEPS):
            if not (f_lo > 0.0):
                break  # F(lo) <= 0: lo is the root (to F's rounding)
            width = hi - lo
            w = lo - f_lo / df_lo  # Newton from below: past the root only by F's rounding
            if not (w > lo * (1.0 + 1e-15)):
                break  # a step of a few ulps: lo is the root
            if w >= hi:
                lo = hi  # past a point known to lie past the root: hi is the root to rounding
                break
            lo = w
            f_lo, df_lo = _ellipsoid_f(k0, k1, k2, d0, d1, d2, w)
            if hi - lo > 0.5 * width:  # slow (far from the root): halve the bracket too
                w = math.sqrt(lo) * math.sqrt(hi) if hi > 2.0 * lo else 0.5 * (lo + hi)
                if not (lo < w < hi):
                    break  # lo and hi adjacent floats
                f, df = _ellipsoid_f(k0, k1, k2, d0, d1, d2, w)
                if f >= 0.0:
                    lo, f_lo, df_lo = w, f, df
                else:
                    hi = w
        u0 = k0 / (d0 + lo) if k0 > 0.0 else 0.0
        u1 = k1 / (d1 + lo) if k1 > 0.0 else 0.0
        u2 = k2 / (d2 + lo) if k2 > 0.0 else 0.0
    # the nearest point q_i = a_i u_i on p's side (u_i = q_i / a_i, Σ u_i² = 1: no under- or
    # overflow whatever the scale), its outward normal along q_i / a_i² = u_i / a_i
    qx, qy, qz = math.copysign(a * u0, x), math.copysign(b * u1, y), math.copysign(c * u2, z)
    ex, ey, ez = x - qx, y - qy, z - qz
    dist = math.sqrt(ex * ex + ey * ey + ez * ez)
    gx, gy, gz = math.copysign(u0 / a, x), math.copysign(u1 / b, y), math.copysign(u2 / c, z)
    gn = math.sqrt(gx * gx + gy * gy + gz * gz)
    inside = (x / a) ** 2 + (y / b) ** 2 + (z / c) ** 2 < 1.0
    return ((-dist if inside else dist), gx / gn, gy / gn, gz / gn)


@kernel
def shape_feature(S, k):
    """The feature of shape k its last distance query or touching sweep ended on: on a mesh
    the row of T of the triangle, as a float for a plane's column; -1.0 for any other shape
    (its surface is one feature)."""
    return float(S[k].feature) if int(S[k].type) == GEOM_MESH else -1.0


@kernel
def shape_feature_distance(S, T, xpos, xmat, k, row, x, y, z):
    """Unsigned distance (m) from the world point p to feature `row` of mesh shape k (a
    triangle), and the unit direction (world) from the feature's nearest point to p."""
    if T is None:
        return (math.inf, 0.0, 0.0, 1.0)
    return mesh_triangle_distance(T, xpos, xmat, int(S[k].geom), row, x, y, z)


@kernel
def shape_walk_distance(sh, k, row, x, y, z):
    """Distance (m, unsigned) from mesh shape k at the world point p, unit normal toward p and
    row of T, as seen from triangle `row` of it (`mesh_walk_distance`): the nearest triangle
    a walk from there reaches, which may be farther than the mesh's nearest."""
    return _mesh_walk_distance(sh.T, sh, k, row, x, y, z)


# A world without meshes has T and C None and never compiles the mesh kernels: numba drops
# the branch of an `is None` test on a None argument, so the test is on T as an argument.

@kernel
def _mesh_walk_distance(T, sh, k, row, x, y, z):
    if T is None:
        return (math.inf, 0.0, 0.0, 1.0, -1)
    return mesh_walk_distance(sh, k, row, x, y, z)


@kernel
def _mesh_distance(T, sh, k, x, y, z):
    if T is None:
        return (math.inf, 0.0, 0.0, 1.0)
    return mesh_distance(sh, k, x, y, z)


@kernel
def _mesh_sweep(T, sh, k, x0, y0, z0, dx, dy, dz, r):
    if T is None:
        return (-1.0, 0.0, 0.0, 0.0)
    return mesh_sweep(sh, k, x0, y0, z0, dx, dy, dz, r)


@kernel
def shape_distance(sh, k, x, y, z):
    """Signed distance (m, < 0 inside) from shape k and outward unit normal, world frame."""
    S, xpos, xmat = sh.S, sh.xpos, sh.xmat
    t = int(S[k].type)
    if t == GEOM_MESH:
        return _mesh_distance(sh.T, sh, k, x, y, z)
    g = int(S[k].geom)
    px, py, pz = xpos[g, 0], xpos[g, 1], xpos[g, 2]
    r00, r01, r02 = xmat[g, 0], xmat[g, 1], xmat[g, 2]
    r10, r11, r12 = xmat[g, 3], xmat[g, 4], xmat[g, 5]
    r20, r21, r22 = xmat[g, 6], xmat[g, 7], xmat[g, 8]
    if t == GEOM_PLANE:
        return (r02 * (x - px) + r12 * (y - py) + r22 * (z - pz), r02, r12, r22)
    if t == GEOM_SPHERE:
        radius = S[k].geom_size[0]
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
        hx, hy, hz = S[k].geom_size
        qx, qy, qz = sx * lx - hx, sy * ly - hy, sz * lz - hz
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
        d, nx, ny, nz = _capsule_local(S[k].geom_size[0], S[k].geom_size[1], lx, ly, lz)
    elif t == GEOM_CYLINDER:
        d, nx, ny, nz = _cylinder_local(S[k].geom_size[0], S[k].geom_size[1], lx, ly, lz)
    elif t == GEOM_ELLIPSOID:
        a, b, c = S[k].geom_size
        d, nx, ny, nz = _ellipsoid_local(a, b, c, lx, ly, lz)
    else:
        raise ValueError("shape_distance: unsupported shape type")
    return (d,
            r00 * nx + r01 * ny + r02 * nz,
            r10 * nx + r11 * ny + r12 * nz,
            r20 * nx + r21 * ny + r22 * nz)


@kernel
def shape_sweep(sh, k, x0, y0, z0, dx, dy, dz, r):
    """First touch (fraction in [0, 1), world normal) of a sphere of radius r (m) moving from
    x0 by (dx, dy, dz) (m) into shape k; (-1.0, 0.0, 0.0, 0.0) when it touches nothing."""
    S, xpos, xmat = sh.S, sh.xpos, sh.xmat
    t = int(S[k].type)
    if t == GEOM_MESH:
        return _mesh_sweep(sh.T, sh, k, x0, y0, z0, dx, dy, dz, r)
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
        d, nx, ny, nz = shape_distance(sh, k, x0 + lam * dx, y0 + lam * dy, z0 + lam * dz)
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


@kernel
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
