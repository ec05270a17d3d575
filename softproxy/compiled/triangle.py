"""One triangle's nearest point to a point, and the distance between two segments.

A triangle is a row of the mesh table T (`softproxy.compiled.layout`: corners A, B, C, edges
AB and AC, unit normal, and AB·AB, AB·AC, AC·AC); its features are named in
`softproxy.compiled.layout`: FACE, EDGE_AB/BC/CA, VERTEX_A/B/C.
"""

from __future__ import annotations

import math
from collections import namedtuple

from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (EDGE_AB, EDGE_BC, EDGE_CA, EDGE_WIDTH, FACE, T_A, T_AA, T_AB, T_ABAC, T_AC, T_B,
                                       T_C, T_CC, T_EDGES, T_INV, T_N, T_VN, VERTEX_A, VERTEX_B, VERTEX_C)
from softproxy.compiled.tolerances import CONTACT_TOL


@kernel
def closest(T, i, px, py, pz):
    """Closest point of triangle row i to p: (squared distance, qx, qy, qz, feature).
    Ericson's Voronoi-region walk, the dot products about B and C derived from those about A."""
    t = T[i]
    ax, ay, az = t[T_A], t[T_A + 1], t[T_A + 2]
    bx, by, bz = t[T_B], t[T_B + 1], t[T_B + 2]
    cx, cy, cz = t[T_C], t[T_C + 1], t[T_C + 2]
    ux, uy, uz = t[T_AB], t[T_AB + 1], t[T_AB + 2]
    vx, vy, vz = t[T_AC], t[T_AC + 1], t[T_AC + 2]
    nx, ny, nz = t[T_N], t[T_N + 1], t[T_N + 2]
    aa, ab, cc = t[T_AA], t[T_ABAC], t[T_CC]
    wx, wy, wz = px - ax, py - ay, pz - az
    d1 = ux * wx + uy * wy + uz * wz
    d2 = vx * wx + vy * wy + vz * wz
    if d1 <= 0.0 and d2 <= 0.0:
        return (wx * wx + wy * wy + wz * wz, ax, ay, az, VERTEX_A)
    d3 = d1 - aa
    d4 = d2 - ab
    if d3 >= 0.0 and d4 <= d3:
        ex, ey, ez = px - bx, py - by, pz - bz
        return (ex * ex + ey * ey + ez * ez, bx, by, bz, VERTEX_B)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / aa
        qx, qy, qz = ax + s * ux, ay + s * uy, az + s * uz
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, EDGE_AB)
    d5 = d1 - ab
    d6 = d2 - cc
    if d6 >= 0.0 and d5 <= d6:
        ex, ey, ez = px - cx, py - cy, pz - cz
        return (ex * ex + ey * ey + ez * ez, cx, cy, cz, VERTEX_C)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / cc
        qx, qy, qz = ax + s * vx, ay + s * vy, az + s * vz
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, EDGE_CA)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 >= d3 and d5 >= d6:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz)
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, EDGE_BC)
    h = nx * wx + ny * wy + nz * wz  # inside the face's prism: straight down to the plane
    return (h * h, px - h * nx, py - h * ny, pz - h * nz, FACE)


@kernel
def segments_gap2(px, py, pz, qx, qy, qz, sx, sy, sz, tx, ty, tz):
    """Squared distance (m²) between segments p..q and s..t (Ericson, Real-Time Collision
    Detection, 5.1.9)."""
    d1x, d1y, d1z = qx - px, qy - py, qz - pz
    d2x, d2y, d2z = tx - sx, ty - sy, tz - sz
    rx, ry, rz = px - sx, py - sy, pz - sz
    a = d1x * d1x + d1y * d1y + d1z * d1z
    e = d2x * d2x + d2y * d2y + d2z * d2z
    f = d2x * rx + d2y * ry + d2z * rz
    c = d1x * rx + d1y * ry + d1z * rz
    b = d1x * d2x + d1y * d2y + d1z * d2z
    denom = a * e - b * b
    s = min(1.0, max(0.0, (b * f - c * e) / denom)) if denom > 1e-30 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0.0:
        t, s = 0.0, min(1.0, max(0.0, -c / a))
    elif t > 1.0:
        t, s = 1.0, min(1.0, max(0.0, (b - c) / a))
    wx = rx + s * d1x - t * d2x
    wy = ry + s * d1y - t * d2y
    wz = rz + s * d1z - t * d2z
    return wx * wx + wy * wy + wz * wz


Sweep = namedtuple("Sweep", "ax ay az ux uy uz r dd graze")
"""A sphere's sweep in a mesh's geom frame: from a (m) by u (m, the whole move), radius r (m),
dd = |u|² (m²) and graze = GRAZE·|u| (m): a touch whose motion into the surface is slower
than that is a graze, not a hit."""


MISS = (-1.0, 0.0, 0.0, 0.0, FACE)
"""A sweep's answer when the sphere does not touch the triangle: lam -1 (no feature)."""


@kernel
def pressed(dist, into, r, graze):
    """Whether a sphere of radius r touching a triangle, its centre `dist` (m) from it, is
    pressed into it by a motion whose component along the outward direction (from the nearest
    point to the centre) is `into` (m, negative inward): it moves in by more than a graze, and
    so far that the end of the motion would be more than CONTACT_TOL deeper than a touch. The
    distance along the motion is convex (the triangle inflated by r is), so it never falls
    below its tangent line dist + λ·into: a motion that keeps that line within CONTACT_TOL of
    r never takes the sphere further in than a touch. Without that allowance a sphere resting
    on two nearly parallel features (the rim edges meeting at a vertex of a bowl) and sliding
    on one's tangent plane is pressed into the other by that plane's rounding, and stopped at
    once, sweep after sweep."""
    return into < -graze and dist + into < r - CONTACT_TOL


@kernel
def sweep_triangle(T, i, sweep, far2):
    """First touch of a sphere (radius r) from a moving by d into triangle row i, geom frame:
    (lam, nx, ny, nz, feature), lam in [0, 1), n the unit normal of the inflated triangle at
    the touch (out of it, against the motion); lam -1.0 when none. dd = |d|², far2: the
    squared distance from a beyond which the triangle is out of reach, graze = GRAZE |d|."""
    ax, ay, az, dx, dy, dz, r, dd, graze = sweep
    t = T[i]
    nx, ny, nz = t[T_N], t[T_N + 1], t[T_N + 2]
    h0 = nx * (ax - t[T_A]) + ny * (ay - t[T_A + 1]) + nz * (az - t[T_A + 2])
    hd = nx * dx + ny * dy + nz * dz
    h1 = h0 + hd
    reach = r + CONTACT_TOL
    if (h0 > reach and h1 > reach) or (h0 < -reach and h1 < -reach):
        return MISS  # the segment never comes within r of the plane
    d2, qx, qy, qz, feature = closest(T, i, ax, ay, az)
    if d2 > far2:
        return MISS  # farther than the sphere can reach on this segment
    if d2 <= reach * reach:
        # touching now: a hit only if pressed into it (`pressed`)
        dist = math.sqrt(d2)
        if dist > 1e-12:
            mx, my, mz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
        elif hd != 0.0:  # the centre on the triangle (a point proxy): the side it comes from
            s = -1.0 if hd > 0.0 else 1.0
            mx, my, mz = s * nx, s * ny, s * nz
        else:
            return MISS
        if pressed(dist, mx * dx + my * dy + mz * dz, r, graze):
            return (0.0, mx, my, mz, feature)
        return MISS
    # 1. the face: the slab |h| <= r is entered at most once; if the sphere enters it over
    #    the triangle's interior, nothing of the inflated triangle was reached before
    if h0 > r or h0 < -r:
        s = 1.0 if h0 > 0.0 else -1.0
        rate = s * hd
        if rate >= -graze:
            return MISS  # along or away from the plane: never entered
        lam = (s * h0 - r) / -rate
        if lam >= 1.0:
            return MISS
        wx = ax + lam * dx - s * r * nx - t[T_A]
        wy = ay + lam * dy - s * r * ny - t[T_A + 1]
        wz = az + lam * dz - s * r * nz - t[T_A + 2]
        d1 = t[T_AB] * wx + t[T_AB + 1] * wy + t[T_AB + 2] * wz
        e2 = t[T_AC] * wx + t[T_AC + 1] * wy + t[T_AC + 2] * wz
        inv = t[T_INV]
        v = (t[T_CC] * d1 - t[T_ABAC] * e2) * inv
        w = (t[T_AA] * e2 - t[T_ABAC] * d1) * inv
        if v >= 0.0 and w >= 0.0 and v + w <= 1.0:
            return (lam, s * nx, s * ny, s * nz, FACE)
    # 2. the edges (cylinders of radius r; their ends belong to the vertex balls)
    best = 1.0
    found = False
    mx = my = mz = 0.0
    feature = EDGE_AB
    for e in range(3):
        c = T_EDGES + EDGE_WIDTH * e
        px, py, pz, ex, ey, ez, length = t[c], t[c + 1], t[c + 2], t[c + 3], t[c + 4], t[c + 5], t[c + 6]
        wx, wy, wz = ax - px, ay - py, az - pz
        we = wx * ex + wy * ey + wz * ez
        de = dx * ex + dy * ey + dz * ez
        qa = dd - de * de
        qb = wx * dx + wy * dy + wz * dz - we * de
        if qa <= 0.0 or qb >= 0.0:
            continue  # along the edge, or moving away from its axis
        qc = wx * wx + wy * wy + wz * wz - we * we - r * r
        if qc <= 0.0:
            continue  # already within r of the axis, beyond the edge's ends: a vertex ball first
        disc = qb * qb - qa * qc
        if disc <= 0.0:
            continue
        lam = (-qb - math.sqrt(disc)) / qa
        if lam < best:
            s = we + lam * de
            if 0.0 <= s <= length:
                best = lam
                found = True
                mx, my, mz = wx + lam * dx - s * ex, wy + lam * dy - s * ey, wz + lam * dz - s * ez
                feature = EDGE_AB + e
    # 3. the vertices (balls of radius r)
    for k in range(3):
        wx, wy, wz = ax - t[T_A + 3 * k], ay - t[T_A + 3 * k + 1], az - t[T_A + 3 * k + 2]
        qb = wx * dx + wy * dy + wz * dz
        if qb >= 0.0:
            continue
        qc = wx * wx + wy * wy + wz * wz - r * r
        disc = qb * qb - dd * qc
        if disc <= 0.0:
            continue
        lam = (-qb - math.sqrt(disc)) / dd
        if lam < best:
            best = lam
            found = True
            mx, my, mz = wx + lam * dx, wy + lam * dy, wz + lam * dz
            feature = VERTEX_A + k
    if not found:
        return MISS
    n = math.sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx / n, my / n, mz / n
    if mx * dx + my * dy + mz * dz >= -graze:
        return MISS  # a tangent graze: the sphere touches without entering
    return (best if best > 0.0 else 0.0, mx, my, mz, feature)


@kernel
def shade(T, i, qx, qy, qz, nx, ny, nz):
    """Force shading: the vertex normals of triangle row i interpolated at q (barycentric,
    clamped to the triangle), on n's side; n itself where they disagree with the face."""
    t = T[i]
    wx, wy, wz = qx - t[T_A], qy - t[T_A + 1], qz - t[T_A + 2]
    d1 = t[T_AB] * wx + t[T_AB + 1] * wy + t[T_AB + 2] * wz
    d2 = t[T_AC] * wx + t[T_AC + 1] * wy + t[T_AC + 2] * wz
    v = (t[T_CC] * d1 - t[T_ABAC] * d2) * t[T_INV]
    w = (t[T_AA] * d2 - t[T_ABAC] * d1) * t[T_INV]
    v = 0.0 if v < 0.0 else 1.0 if v > 1.0 else v
    w = 0.0 if w < 0.0 else 1.0 - v if w > 1.0 - v else w
    u = 1.0 - v - w
    a = T_VN
    sx = u * t[a] + v * t[a + 3] + w * t[a + 6]
    sy = u * t[a + 1] + v * t[a + 4] + w * t[a + 7]
    sz = u * t[a + 2] + v * t[a + 5] + w * t[a + 8]
    if sx * t[T_N] + sy * t[T_N + 1] + sz * t[T_N + 2] < 0.0:
        return (nx, ny, nz)  # the vertex normals disagree with the face: the geometric one
    if sx * nx + sy * ny + sz * nz < 0.0:  # n on the back of the face (an open mesh)
        sx, sy, sz = -sx, -sy, -sz
    s = math.sqrt(sx * sx + sy * sy + sz * sz)
    if s > 0.0:
        return (sx / s, sy / s, sz / s)
    return (nx, ny, nz)
