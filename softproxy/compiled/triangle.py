"""One triangle's nearest point to a point, and the distance between two segments.

A triangle is a row of the mesh table T (`softproxy.compiled.layout`: corners A, B, C, edges
AB and AC, unit normal, and AB·AB, AB·AC, AC·AC); its features are named in
`softproxy.compiled.layout`: FACE, EDGE_AB/BC/CA, VERTEX_A/B/C.
"""

from __future__ import annotations

from numba import njit

from softproxy.compiled.layout import (EDGE_AB, EDGE_BC, EDGE_CA, FACE, T_AA, T_ABAC, T_AB, T_AC, T_A, T_B, T_C,
                                       T_CC, T_N, VERTEX_A, VERTEX_B, VERTEX_C)


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
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
