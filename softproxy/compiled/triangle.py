"""One triangle's nearest point to a point, and the distance between two segments.

A triangle is a row of the mesh table T (`softproxy.compiled.layout`: corners A, B, C, edges
AB and AC, unit normal, and AB·AB, AB·AC, AC·AC); its features are 0 its face, 1-3 its edges
AB, BC, CA and 4-6 its vertices A, B, C.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, error_model="numpy")
def closest(T, i, px, py, pz):
    """Closest point of triangle row i to p: (squared distance, qx, qy, qz, feature).
    Ericson's Voronoi-region walk, the dot products about B and C derived from those about A."""
    t = T[i]
    ax, ay, az, bx, by, bz, cx, cy, cz = t[0], t[1], t[2], t[3], t[4], t[5], t[6], t[7], t[8]
    ux, uy, uz, vx, vy, vz, nx, ny, nz = t[9], t[10], t[11], t[12], t[13], t[14], t[15], t[16], t[17]
    aa, ab, cc = t[18], t[19], t[20]
    wx, wy, wz = px - ax, py - ay, pz - az
    d1 = ux * wx + uy * wy + uz * wz
    d2 = vx * wx + vy * wy + vz * wz
    if d1 <= 0.0 and d2 <= 0.0:
        return (wx * wx + wy * wy + wz * wz, ax, ay, az, 4)
    d3 = d1 - aa
    d4 = d2 - ab
    if d3 >= 0.0 and d4 <= d3:
        ex, ey, ez = px - bx, py - by, pz - bz
        return (ex * ex + ey * ey + ez * ez, bx, by, bz, 5)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / aa
        qx, qy, qz = ax + s * ux, ay + s * uy, az + s * uz
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, 1)
    d5 = d1 - ab
    d6 = d2 - cc
    if d6 >= 0.0 and d5 <= d6:
        ex, ey, ez = px - cx, py - cy, pz - cz
        return (ex * ex + ey * ey + ez * ez, cx, cy, cz, 6)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / cc
        qx, qy, qz = ax + s * vx, ay + s * vy, az + s * vz
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, 3)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 >= d3 and d5 >= d6:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz)
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, 2)
    h = nx * wx + ny * wy + nz * wz  # inside the face's prism: straight down to the plane
    return (h * h, px - h * nx, py - h * ny, pz - h * nz, 0)


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
