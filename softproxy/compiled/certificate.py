"""The kept certificates of a mesh: which triangles can come nearer than a tangent plane.

A point p whose nearest point found so far is q, on the hint triangle, at distance d, has no
nearer triangle among those lying wholly behind the tangent plane at q (normal (p - q) / d):
each is at least as far as that plane. Nor does a sphere touching at q and sliding on or above
that plane enter any of them. So a query reads only the triangles near q that reach above it:
- q on the hint's face: the face's list, for the side p is on, of the few triangles near it
  rising above its plane (none on a convex patch; more than STATIC_ABOVE, as the rising wall
  of a bowl, and the face gives no certificate);
- q on an edge: when the plane holds both faces behind it (n in the cone of their outward
  normals: a convex edge seen from outside, `_convex_edge`), both faces' lists; a concave or
  open edge gives none;
- q on a vertex: its fan lies behind the plane when n is inside the vertex's cone (one dot
  product), else when every edge leaving it does (one per edge); a triangle off the fan lies
  behind it when its vertices lie more than the plane's tilt below the cone, so only the
  vertices near it whose sin β (their angle below the plane square to the cone's axis) is
  under the tilt's sine are tested, from a table sorted by sin β, and the fans of those
  above the plane listed. A proxy held on the pole of a uv-sphere, where ~100 thin triangles
  meet, reads none of them, and on a convex patch none is read whatever the triangles' shape.
`softproxy.mesh.MeshShape` builds the lists and tables for every face and vertex at load
(and for a larger proxy in `prepare`; `softproxy.mesh_certificates`, which packs them into
the mesh tables T and C) and `static_clear` asks them. Where they do not hold (a concave patch, a reach beyond
the one they were built for), the caller asks the ball certificate (`softproxy.mesh_balls`)
on a dense mesh, or walks its box tree.
"""

from __future__ import annotations

import math

from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (
    C_FEW, C_STAMP, C_STAMPS, EDGE_AB, FACE, FEW_SLOTS, T_ADJ, T_CLEAR, T_N, T_TV, VERTEX_A, VERTEX_WIDTH, V_AXIS,
    V_COS, V_FAN, V_RING, V_SINES, V_THRESHOLD, V_X,
)

ABOVE_TOL = 1e-9
"""A vertex this far (m) above a certificate plane counts as above it. MuJoCo stores vertices
in float32 (≈4e-9 m at 5 cm), so coplanar neighbours differ by about this much; a certified
distance may be overstated by at most this (m)."""
STATIC_ABOVE = 8
"""Most triangles reaching above a face's plane that its kept certificate lists (and a query
then reads: e.g. a vertex a rounding above a coplanar neighbour brings its fan of ~6); more,
and the face is on a concave patch: no certificate, the box tree serves it."""
VERTEX_READ = 64
"""Most vertices a kept vertex certificate tests against a tangent plane tilted from its cone's
axis (those whose sin β is below the tilt's sine); more, and the box tree serves it."""

BALL_SLACK = ABOVE_TOL
"""The resting ball is grown by this (m) when its list is built, and a query's test allows
as much: vertices are float32 in MuJoCo (≈4e-9 m at 5 cm), a list is a superset."""

assert FEW_SLOTS >= 2 * STATIC_ABOVE, "the scratch run must hold two faces' lists (an edge's certificate)"


@kernel
def _convex_edge(T, i, o, nx, ny, nz, side0, dot0):
    """The side (±1.0) of neighbour row o that the tangent plane of normal n at a point on its
    edge with row i sees (side0: the side of row i it sees, dot0 = n · row i's normal), when
    the plane holds both faces behind it: n in the cone of the two faces' outward normals, a
    convex edge seen from outside. Coplanar faces: n must be their own normal, since a sphere
    touching the edge from beside it is not held by the plane. 0.0 when it does not hold
    them (a concave or folded edge)."""
    dot1 = nx * T[o, T_N] + ny * T[o, T_N + 1] + nz * T[o, T_N + 2]
    side1 = 1.0 if dot1 >= 0.0 else -1.0
    g = side0 * side1 * (T[i, T_N] * T[o, T_N] + T[i, T_N + 1] * T[o, T_N + 1] + T[i, T_N + 2] * T[o, T_N + 2])
    det = 1.0 - g * g
    a0, a1 = side0 * dot0, side1 * dot1
    if det < 1e-12:
        return side1 if g > 0.0 and a0 > 1.0 - 1e-9 else 0.0
    if a0 - g * a1 < -1e-12 * det or a1 - g * a0 < -1e-12 * det:
        return 0.0  # n outside the cone: a concave edge
    return side1


@kernel
def face_few(T, C, i, side, at, lists=T_CLEAR):
    """Row i's list on `side` (`lists`: T_CLEAR, the triangles rising above its plane; T_BALL,
    those a ball resting on it reaches), copied to C[C_FEW + at:]; the new count, or -1 when
    it has none (a concave patch)."""
    col = lists if side > 0.0 else lists + 2
    count = int(T[i, col + 1])
    if count < 0 or at + count > C_STAMPS - C_FEW:
        return -1
    start = int(T[i, col])
    for j in range(count):
        C[C_FEW + at + j] = C[start + j]
    return at + count


@kernel
def _vertex_few(S, T, C, k, hint, feature, nx, ny, nz):
    """`static_clear` when the nearest point is vertex `feature - VERTEX_A` of row `hint`: the fan lies
    behind the tangent plane when n is inside the vertex's cone (else every edge leaving it is
    tested); a triangle off the fan does when its vertices lie more than the plane's tilt
    below the cone (sin β, from the table); the fans of the few that may not and rise above
    the plane are listed."""
    vertex = int(T[hint, T_TV + feature - VERTEX_A])
    verts = int(S[k].verts)
    rec = verts + VERTEX_WIDTH * vertex
    c = nx * C[rec + V_AXIS] + ny * C[rec + V_AXIS + 1] + nz * C[rec + V_AXIS + 2]
    if c <= 0.0:
        return -1
    if c < C[rec + V_COS]:
        r0 = int(C[rec + V_RING])
        for j in range(r0, r0 + 4 * int(C[rec + V_RING + 1]), 4):
            if nx * C[j] + ny * C[j + 1] + nz * C[j + 2] > ABOVE_TOL:
                return -1
    if c * c > C[rec + V_THRESHOLD]:
        return 0
    s0, sn = int(C[rec + V_SINES]), int(C[rec + V_SINES + 1])
    tilt = math.sqrt(max(0.0, 1.0 - c * c)) + 1e-12  # c may round above 1 (NaN would certify all)
    m = 0
    while m < sn and C[s0 + 2 * m] < tilt:  # bisect_left on sin β ascending
        m += 1
    if m > VERTEX_READ:
        return -1
    off = nx * C[rec + V_X] + ny * C[rec + V_X + 1] + nz * C[rec + V_X + 2] + ABOVE_TOL
    C[C_STAMP] += 1.0
    stamp = C[C_STAMP]
    count = 0
    for j in range(m):
        w = verts + VERTEX_WIDTH * int(C[s0 + 2 * j + 1])
        if nx * C[w + V_X] + ny * C[w + V_X + 1] + nz * C[w + V_X + 2] > off:
            f0 = int(C[w + V_FAN])
            for f in range(f0, f0 + int(C[w + V_FAN + 1])):
                i = int(C[f])
                if C[C_STAMPS + i] == stamp:
                    continue
                C[C_STAMPS + i] = stamp
                if count == STATIC_ABOVE:
                    return -1
                C[C_FEW + count] = i
                count += 1
    return count


@kernel
def static_clear(S, T, C, k, hint, feature, nx, ny, nz, need):
    """How many triangles (rows of T, listed in C[C_FEW:]) within
    `need` (m) of the nearest point on `feature` of row `hint` may reach above the tangent
    plane there (normal n, geom frame, out of the hint); every other triangle that near lies
    behind it. -1 when the certificates do not hold (a concave patch, or need beyond the
    reach they were built for): then every triangle must be asked. A point p at distance d
    has no nearer triangle off the list when need >= 2d; a sphere of radius r touching at p
    and sliding by L on or above the plane enters none when need >= 2r + L."""
    if need > S[k].kept:
        return -1
    dot0 = nx * T[hint, T_N] + ny * T[hint, T_N + 1] + nz * T[hint, T_N + 2]
    side0 = 1.0 if dot0 >= 0.0 else -1.0
    if feature == FACE:
        return face_few(T, C, hint, side0, 0)
    if feature >= VERTEX_A:
        return _vertex_few(S, T, C, k, hint, feature, nx, ny, nz)
    other = int(T[hint, T_ADJ + feature - EDGE_AB])
    if other < 0:
        return -1
    side1 = _convex_edge(T, hint, other, nx, ny, nz, side0, dot0)
    if side1 == 0.0:
        return -1
    m = face_few(T, C, hint, side0, 0)
    if m < 0:
        return -1
    return face_few(T, C, other, side1, m)
