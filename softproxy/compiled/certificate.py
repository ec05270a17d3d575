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
(and for a larger proxy in `prepare`); `certificate_tables` packs them into the mesh tables T
and C and `static_clear` asks them. Where they do not hold (a concave patch, a reach beyond
the one they were built for), the caller asks the ball certificate (`softproxy.compiled.ball`)
on a dense mesh, or walks its box tree.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from softproxy.compiled.tree_walk import LEAF, STACK, heap_offer, heap_pop
from softproxy.compiled.layout import (
    EDGE_AB, FACE, FEW_SLOTS, SCAN_COUNT, SCAN_FEW, SCAN_STAMPS, TI_ADJ, TI_CLEAR, TI_COLUMNS, TI_TV, T_N, VERTEX_A,
    VERTEX_INTS, VERTEX_WIDTH, VI_FAN, VI_FAN_NUM, VI_RING, VI_RING_NUM, VI_RING_ROW, VI_SINES, VI_SINE_NUM, VI_SINE_VERT,
    V_AXIS, V_COS, V_THRESHOLD, V_X,
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

assert FEW_SLOTS >= 2 * STATIC_ABOVE, "the scratch run must hold two faces' lists (an edge's certificate)"


def certificate_tables(s, t0: int, c0: int, i0: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, float, float]:
    """The certificates of `softproxy.mesh.MeshTables` s whose triangles are rows t0.. of T and
    whose tables start at C[c0] and CI[i0]: (its rows of TI (triangles × TI_COLUMNS), its part
    of C (vertex records, ring vectors, sin β tables), its part of CI (vertex records, ring
    rows, fans, the sin β tables' vertex ids, face lists and ball lists), the reach (m) they
    hold over, the radius (m) of the ball certificates' resting ball)."""
    n, nv = s.triangles, len(s.vpos)
    adj = np.where(s.adj >= 0, s.adj + t0, -1)
    verts = np.zeros((nv, VERTEX_WIDTH))
    verts[:, V_X:V_X + 3] = s.vpos
    verts[:, V_AXIS:V_COS + 1] = s.vcone
    vint = np.zeros((nv, VERTEX_INTS), dtype=np.int64)
    at, iat = c0 + verts.size, i0 + vint.size
    floats, ints = [verts], [vint]
    # per vertex its ring (edge vector (m) in C, a triangle on the edge in CI), then its fan (ascending)
    vint[:, VI_RING] = at + 3 * s.ring_start[:-1]
    vint[:, VI_RING_ROW] = iat + s.ring_start[:-1]
    vint[:, VI_RING_NUM] = np.diff(s.ring_start)
    floats.append(s.ring[:, :3].astype(np.float64))
    ints.append(s.ring[:, 3].astype(np.int64) + t0)
    at += 3 * len(s.ring)
    iat += len(s.ring)
    vint[:, VI_FAN] = iat + s.fan_start[:-1]
    vint[:, VI_FAN_NUM] = np.diff(s.fan_start)
    ints.append(s.fan.astype(np.int64) + t0)
    iat += len(s.fan)
    radius, start, sines, ids = s.vtable
    counts = np.diff(start)
    vint[:, VI_SINES] = at + start[:-1]
    vint[:, VI_SINE_VERT] = iat + start[:-1]
    vint[:, VI_SINE_NUM] = counts
    floats.append(np.asarray(sines, dtype=np.float64))
    ints.append(np.asarray(ids).astype(np.int64))
    at += len(sines)
    iat += len(sines)
    # the threshold on c² (c: the cosine of the plane's normal to the cone's axis) above which
    # every triangle near the vertex lies behind the plane by angle alone (2.0: never)
    least = np.ones(nv)
    least[counts > 0] = sines[start[:-1][counts > 0]]
    s0 = least - 1e-12
    verts[:, V_THRESHOLD] = np.where(s0 > 0.0, 1.0 - s0 * s0, 2.0)
    # per face and side, the few triangles rising above its plane (-1: a concave patch)
    clear = np.zeros((n, 4), dtype=np.int64)
    m = s.clear.reshape(-1)                      # face 0 front, face 0 back, face 1 front, ...
    runs = np.maximum(m, 0)
    first = iat + np.cumsum(runs) - runs
    clear[:, 0], clear[:, 2] = first[0::2], first[1::2]
    clear[:, 1], clear[:, 3] = m[0::2], m[1::2]
    clear[:, [0, 2]] = np.where(clear[:, [1, 3]] < 0, 0, clear[:, [0, 2]])
    flat = s.listed.reshape(-1, s.listed.shape[2])
    ints.append(flat[np.arange(flat.shape[1])[None, :] < runs[:, None]].astype(np.int64) + t0)
    iat += int(runs.sum())
    # per face and side, its ball list: the plane list where that holds, else its own (-1: none)
    ball = clear.copy()
    b = s.ball_count.reshape(-1)
    own = (m < 0) & (b >= 0)
    bruns = np.where(own, b, 0)
    sides = ball.reshape(-1, 2)                  # a view: (start, count) per face and side, as m
    sides[own, 0] = (iat + np.cumsum(bruns) - bruns)[own]
    sides[own, 1] = b[own]
    bflat = s.ball_listed.reshape(2 * n, s.ball_listed.shape[2])
    ints.append(bflat[np.arange(bflat.shape[1])[None, :] < bruns[:, None]].astype(np.int64) + t0)
    columns = np.column_stack([adj, s.tv, clear, ball]).astype(np.int64)
    assert columns.shape[1] == TI_COLUMNS
    return (columns, np.concatenate([f.ravel() for f in floats]), np.concatenate([i.ravel() for i in ints]),
            float(s.kept), float(s.ball))


@njit(cache=True, error_model="numpy")
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


@njit(cache=True, error_model="numpy")
def face_few(TI, CI, scan, i, side, at, lists=TI_CLEAR):
    """Row i's list on `side` (`lists`: TI_CLEAR, the triangles rising above its plane; TI_BALL,
    those a ball resting on it reaches), copied to scan[SCAN_FEW + at:]; the new count, or -1
    when it has none (a concave patch)."""
    col = lists if side > 0.0 else lists + 2
    count = TI[i, col + 1]
    if count < 0 or at + count > FEW_SLOTS:
        return -1
    start = TI[i, col]
    for j in range(count):
        scan[SCAN_FEW + at + j] = CI[start + j]
    return at + count


@njit(cache=True, error_model="numpy")
def _vertex_few(sh, k, hint, feature, nx, ny, nz):
    """`static_clear` when the nearest point is vertex `feature - VERTEX_A` of row `hint`: the fan lies
    behind the tangent plane when n is inside the vertex's cone (else every edge leaving it is
    tested); a triangle off the fan does when its vertices lie more than the plane's tilt
    below the cone (sin β, from the table); the fans of the few that may not and rise above
    the plane are listed."""
    S, C, CI, scan = sh.S, sh.C, sh.CI, sh.scan
    vertex = sh.TI[hint, TI_TV + feature - VERTEX_A]
    verts, iverts = S[k].vertadr, S[k].vertiadr
    rec, irec = verts + VERTEX_WIDTH * vertex, iverts + VERTEX_INTS * vertex
    c = nx * C[rec + V_AXIS] + ny * C[rec + V_AXIS + 1] + nz * C[rec + V_AXIS + 2]
    if c <= 0.0:
        return -1
    if c < C[rec + V_COS]:
        r0 = CI[irec + VI_RING]
        for j in range(r0, r0 + 3 * CI[irec + VI_RING_NUM], 3):
            if nx * C[j] + ny * C[j + 1] + nz * C[j + 2] > ABOVE_TOL:
                return -1
    if c * c > C[rec + V_THRESHOLD]:
        return 0
    s0, v0, sn = CI[irec + VI_SINES], CI[irec + VI_SINE_VERT], CI[irec + VI_SINE_NUM]
    tilt = math.sqrt(max(0.0, 1.0 - c * c)) + 1e-12  # c may round above 1 (NaN would certify all)
    m = 0
    while m < sn and C[s0 + m] < tilt:  # bisect_left on sin β ascending
        m += 1
    if m > VERTEX_READ:
        return -1
    off = nx * C[rec + V_X] + ny * C[rec + V_X + 1] + nz * C[rec + V_X + 2] + ABOVE_TOL
    scan[SCAN_COUNT] += 1
    stamp = scan[SCAN_COUNT]
    count = 0
    for j in range(m):
        v = CI[v0 + j]
        w = verts + VERTEX_WIDTH * v
        if nx * C[w + V_X] + ny * C[w + V_X + 1] + nz * C[w + V_X + 2] > off:
            f0 = CI[iverts + VERTEX_INTS * v + VI_FAN]
            for f in range(f0, f0 + CI[iverts + VERTEX_INTS * v + VI_FAN_NUM]):
                i = CI[f]
                if scan[SCAN_STAMPS + i] == stamp:
                    continue
                scan[SCAN_STAMPS + i] = stamp
                if count == STATIC_ABOVE:
                    return -1
                scan[SCAN_FEW + count] = i
                count += 1
    return count


@njit(cache=True, error_model="numpy")
def static_clear(sh, k, hint, feature, nx, ny, nz, need):
    """How many triangles (rows of T, listed in sh.scan[SCAN_FEW:]) within
    `need` (m) of the nearest point on `feature` of row `hint` may reach above the tangent
    plane there (normal n, geom frame, out of the hint); every other triangle that near lies
    behind it. -1 when the certificates do not hold (a concave patch, or need beyond the
    reach they were built for): then every triangle must be asked. A point p at distance d
    has no nearer triangle off the list when need >= 2d; a sphere of radius r touching at p
    and sliding by L on or above the plane enters none when need >= 2r + L."""
    T, TI, CI, scan = sh.T, sh.TI, sh.CI, sh.scan
    if need > sh.S[k].kept:
        return -1
    dot0 = nx * T[hint, T_N] + ny * T[hint, T_N + 1] + nz * T[hint, T_N + 2]
    side0 = 1.0 if dot0 >= 0.0 else -1.0
    if feature == FACE:
        return face_few(TI, CI, scan, hint, side0, 0)
    if feature >= VERTEX_A:
        return _vertex_few(sh, k, hint, feature, nx, ny, nz)
    other = TI[hint, TI_ADJ + feature - EDGE_AB]
    if other < 0:
        return -1
    side1 = _convex_edge(T, hint, other, nx, ny, nz, side0, dot0)
    if side1 == 0.0:
        return -1
    m = face_few(TI, CI, scan, hint, side0, 0)
    if m < 0:
        return -1
    return face_few(TI, CI, scan, other, side1, m)


# ---------------------------------------------------------------------------------------
# Building the kept certificates (at load, compiled; nothing here runs in the tick)
#
# Two box trees: one over the vertices, one over the few long triangles (longest edge over
# `long_edge`). A triangle within reach of a point (or a face) is either short, and then
# each of its vertices lies within reach + long_edge, found in the vertex tree, or long, found
# in the long tree: so a face or vertex reads its neighbourhood only, whatever the largest
# triangle of the mesh, and the tree walks leave out what cannot matter (boxes wholly behind
# a face's plane; boxes that cannot hold a lower sin β than a full vertex table has).
# ---------------------------------------------------------------------------------------

SINE_GRID = 2.0 ** 40
"""Steps per unit a kept vertex table's sin β is rounded down to (≈1e-12), so that equal sines sort alike."""
BUDGET = 512
"""Most tree leaves one face's or vertex's walk may open; beyond, it gets no certificate (a
neighbourhood of more than ~4k vertices or triangles within reach: a query there walks the box tree)."""
DEAD_SINE = 1e-12
"""A full vertex table whose every sin β is below this certifies nothing: a query reads the
entries below its tilt's sine (never less than 1e-12, `_vertex_few`), all of them, past
VERTEX_READ. Its walk stops there (a concave, noisy or flat neighbourhood)."""
FAN_CHECK = 64
"""A vertex beyond reach + long_edge of a vertex whose table is being built is taken when one
of its long triangles may come within reach: its fan is searched for one, unless it holds
more than this many triangles (a cap's hub), when it is taken unchecked."""
GRADE = 16.0
"""Items of a box tree whose sizes differ by about this factor or more are kept apart
(`box_tree`); on a mesh of one tessellation every item has one grade and the tree is in
Morton order alone."""


def _spread(q: np.ndarray) -> np.ndarray:
    """21-bit integers with two zero bits put between their bits (a Morton code's one axis)."""
    q = q.astype(np.uint64) & np.uint64(0x1FFFFF)
    for shift, mask in ((32, 0x1F00000000FFFF), (16, 0x1F0000FF0000FF), (8, 0x100F00F00F00F00F),
                        (4, 0x10C30C30C30C30C3), (2, 0x1249249249249249)):
        q = (q | (q << np.uint64(shift))) & np.uint64(mask)
    return q


def grades(size: np.ndarray) -> np.ndarray:
    """Per item of `size` (m, e.g. its box's longest side), its grade: how many factors of
    GRADE its size lies above or below the median's, rounded, counted from the lowest (0). A
    size of 0 takes the lowest grade."""
    size = np.asarray(size, dtype=np.float64)
    out = np.zeros(len(size), dtype=np.int64)
    sized = size > 0.0
    if not sized.any():
        return out
    out[sized] = np.rint(np.log(size[sized] / float(np.median(size[sized]))) / math.log(GRADE))
    out[~sized] = out[sized].min()
    return out - out.min()


def box_tree(lo: np.ndarray, hi: np.ndarray, ids: np.ndarray | None = None, extent: np.ndarray | None = None):
    """A box tree over items with boxes lo..hi (n × 3, m): the items by grade of their size
    (`grades` of `extent` (m), by default each box's longest side), then in Morton order of their boxes'
    centres, LEAF a leaf, leaves paired level by level into a complete binary tree (node 1
    the root, node j's children 2j and 2j + 1, leaf j node `size + j`). Returns (item ids in
    that order (`ids[...]` when given), node lower corners, node upper corners, size); an
    empty node's box is inverted (+inf..-inf), an empty tree has one empty leaf.

    By grade first, so that a few items far larger than the rest (a height field's bottom,
    a fan of slivers metres long under a field of centimetre cells) share leaves and nodes
    with each other rather than widen every node along their way: in Morton order alone a
    leaf holding one of them had a box metres wide, and every walk nearby opened it."""
    n = len(lo)
    ids = np.arange(n) if ids is None else np.asarray(ids, dtype=np.int64)
    if n == 0:
        return np.zeros(0, dtype=np.int64), np.full((2, 3), np.inf), np.full((2, 3), -np.inf), 1
    low, high = lo.min(axis=0), hi.max(axis=0)
    centre = 0.5 * (lo + hi)
    q = np.floor((centre - low) / max(float((high - low).max()), 1e-300) * (2 ** 21 - 1))
    code = _spread(q[:, 0]) | (_spread(q[:, 1]) << np.uint64(1)) | (_spread(q[:, 2]) << np.uint64(2))
    grade = grades((hi - lo).max(axis=1) if extent is None else extent)
    order = np.lexsort((code, grade))  # stable: by grade, then by code, then as given
    leaves = -(-n // LEAF)
    size = 1 << max(0, int(leaves - 1).bit_length())
    nlo, nhi = node_boxes(order, size, lo, hi)
    return ids[order], nlo, nhi, size


def node_boxes(order: np.ndarray, size: int, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The boxes (lower, upper corners; 2 size × 3, m) of the nodes of a box tree whose items,
    in tree order `order` (indices into lo, hi), have boxes lo..hi: a leaf's LEAF items, a
    node its children's; an empty node's box inverted (+inf..-inf)."""
    n = len(order)
    leaves = -(-n // LEAF)
    nlo = np.full((2 * size, 3), np.inf)
    nhi = np.full((2 * size, 3), -np.inf)
    if n:
        starts = np.arange(0, n, LEAF)
        nlo[size:size + leaves] = np.minimum.reduceat(lo[order], starts, axis=0)
        nhi[size:size + leaves] = np.maximum.reduceat(hi[order], starts, axis=0)
    level = size
    while level > 1:
        parent = np.arange(level // 2, level)
        nlo[parent] = np.minimum(nlo[2 * parent], nlo[2 * parent + 1])
        nhi[parent] = np.maximum(nhi[2 * parent], nhi[2 * parent + 1])
        level //= 2
    return nlo, nhi


@njit(cache=True, error_model="numpy")
def _set_frame(axes, node, ux, uy, uz, vx, vy, vz):
    """A node's oriented axes: the unit u, the unit v square to it, and u × v."""
    axes[node, 0, 0], axes[node, 0, 1], axes[node, 0, 2] = ux, uy, uz
    axes[node, 1, 0], axes[node, 1, 1], axes[node, 1, 2] = vx, vy, vz
    axes[node, 2, 0], axes[node, 2, 1], axes[node, 2, 2] = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


@njit(cache=True, error_model="numpy")
def _widen(axes, ext, node, V, w):
    """A node's extents along its axes (m), stretched to hold vertex w."""
    for a in range(3):
        h = axes[node, a, 0] * V[w, 0] + axes[node, a, 1] * V[w, 1] + axes[node, a, 2] * V[w, 2]
        if h < ext[node, a, 0]:
            ext[node, a, 0] = h
        if h > ext[node, a, 1]:
            ext[node, a, 1] = h


def node_frames(order: np.ndarray, size: int, V: np.ndarray, F: np.ndarray, plane: np.ndarray):
    """Per node of a box tree over triangles (`box_tree`'s order and size): a box oriented by
    its first triangle (axes: that triangle's normal, its longest edge, their cross product;
    the extents of the node's vertices along each), as (nodes × 3 axes × 3) axes and (nodes
    × 3 × 2) extents; an empty node's extents are inverted. A face that holds a long run of
    slivers behind it (a CAD cylinder's side, a flat face's fan) is seen to, where the node's
    axis-aligned box would stick out above its plane."""
    axes = np.zeros((2 * size, 3, 3))
    ext = np.empty((2 * size, 3, 2))
    ext[:, :, 0], ext[:, :, 1] = np.inf, -np.inf
    _fill_frames(np.ascontiguousarray(order, dtype=np.int64), size, V, F, plane, axes, ext)
    return axes, ext


@njit(cache=True, error_model="numpy")
def _fill_frames(order, size, V, F, plane, axes, ext):
    """`node_frames`' work, level by level: each node's items are a run of `order` (the leaves'
    LEAF triangles under it), every vertex of each projected on its first triangle's axes
    (numpy's version, one level at a time over all triangles, took 0.6 s of the 100k CAD
    slivers' 4.5 s load)."""
    n = len(order)
    span = size * LEAF  # items under one node of the level
    level = 1
    while level <= size:
        node = level
        for s in range(0, n, span):
            t = order[s]
            # the first triangle's longest edge (the first of equals), as c1-c0, c2-c1, c0-c2
            best, ex, ey, ez = -1.0, 0.0, 0.0, 0.0
            for e in range(3):
                a, b = V[F[t, e]], V[F[t, (e + 1) % 3]]
                dx, dy, dz = b[0] - a[0], b[1] - a[1], b[2] - a[2]
                d2 = dx * dx + dy * dy + dz * dz
                if d2 > best:
                    best, ex, ey, ez = d2, dx, dy, dz
            length = math.sqrt(best)
            ux, uy, uz = plane[t, 0], plane[t, 1], plane[t, 2]
            vx, vy, vz = ex / length, ey / length, ez / length
            _set_frame(axes, node, ux, uy, uz, vx, vy, vz)
            for j in range(s, min(s + span, n)):
                for k in range(3):
                    _widen(axes, ext, node, V, F[order[j], k])
            node += 1
        level *= 2
        span //= 2


def apex_frames(order: np.ndarray, size: int, V: np.ndarray, F: np.ndarray, frames):
    """Per node of a box tree over triangles, its oriented box (`node_frames`' `frames`),
    and its axis-aligned box, of the node's vertices but its apex: a vertex every triangle
    of the node has (-1: none, and the boxes of all of them). Returns (axes, extents, lower
    corners, upper corners, apex). A node of a fan (a cone's slivers about its tip, a cap's about its
    hub) is a thin wedge whose boxes stick out far beside its tip; its tip apart, they hold
    only the rim's arc, so a face beside the tip sees the node behind its plane from its
    boxes and the tip alone."""
    axes, ext = frames[0], frames[1].copy()
    lo = np.full((2 * size, 3), np.inf)
    hi = np.full((2 * size, 3), -np.inf)
    apex = np.full(2 * size, -1, dtype=np.int64)
    _fill_apex(np.ascontiguousarray(order, dtype=np.int64), size, V, F, axes, ext, lo, hi, apex)
    return axes, ext, lo, hi, apex


@njit(cache=True, error_model="numpy")
def _fill_apex(order, size, V, F, axes, ext, lo, hi, apex):
    """`apex_frames`' work, level by level: each node's apex, and its extents along its axes
    and its box over its vertices but that one (the others keep their extents; their box is
    the node's own, not filled in here)."""
    n = len(order)
    span = size * LEAF
    level = 1
    while level <= size:
        node = level
        for s in range(0, n, span):
            e = min(s + span, n)
            t0 = order[s]
            common = -1
            for c in range(3):
                w = F[t0, c]
                every = True
                for j in range(s + 1, e):
                    t = order[j]
                    if F[t, 0] != w and F[t, 1] != w and F[t, 2] != w:
                        every = False
                        break
                if every:
                    common = w
                    break
            if common >= 0:
                apex[node] = common
                for a in range(3):
                    ext[node, a, 0], ext[node, a, 1] = np.inf, -np.inf
                for j in range(s, e):
                    for k in range(3):
                        w = F[order[j], k]
                        if w == common:
                            continue
                        _widen(axes, ext, node, V, w)
                        for a in range(3):
                            if V[w, a] < lo[node, a]:
                                lo[node, a] = V[w, a]
                            if V[w, a] > hi[node, a]:
                                hi[node, a] = V[w, a]
            node += 1
        level *= 2
        span //= 2


def point_frames(order: np.ndarray, size: int, V: np.ndarray, normal: np.ndarray):
    """Per node of a box tree over vertices (`box_tree`'s order and size): a box oriented by
    its first vertex (axes: that vertex's normal, the chord to the node's last vertex square
    to it, their cross product; the extents of the node's vertices along each), as
    `node_frames` gives for triangles. A run of vertices along a finely divided rim or over
    a smooth patch is thin across, where its axis-aligned box, turned 45° to it, is not."""
    axes = np.zeros((2 * size, 3, 3))
    ext = np.empty((2 * size, 3, 2))
    ext[:, :, 0], ext[:, :, 1] = np.inf, -np.inf
    _fill_point_frames(np.ascontiguousarray(order, dtype=np.int64), size, V, normal, axes, ext)
    return axes, ext


@njit(cache=True, error_model="numpy")
def _fill_point_frames(order, size, V, N, axes, ext):
    """`point_frames`' work, level by level: each node's vertices are a run of `order`."""
    n = len(order)
    span = size * LEAF  # items under one node of the level
    level = 1
    while level <= size:
        node = level
        for s in range(0, n, span):
            e = min(s + span, n)
            w0, w1 = order[s], order[e - 1]
            ux, uy, uz = N[w0, 0], N[w0, 1], N[w0, 2]
            length = math.sqrt(ux * ux + uy * uy + uz * uz)
            if length < 0.5:  # a vertex of no triangle: no normal
                ux, uy, uz = 0.0, 0.0, 1.0
            else:
                ux, uy, uz = ux / length, uy / length, uz / length
            dx, dy, dz = V[w1, 0] - V[w0, 0], V[w1, 1] - V[w0, 1], V[w1, 2] - V[w0, 2]
            along = dx * ux + dy * uy + dz * uz
            dx, dy, dz = dx - along * ux, dy - along * uy, dz - along * uz
            length = math.sqrt(dx * dx + dy * dy + dz * dz)
            if length < 1e-300 or length < 1e-9 * (abs(dx) + abs(dy) + abs(dz) + abs(along)):
                # no chord square to the normal: any direction square to it
                dx, dy, dz = (uz, 0.0, -ux) if abs(ux) > 0.5 or abs(uz) > 0.5 else (0.0, uz, -uy)
                length = math.sqrt(dx * dx + dy * dy + dz * dz)
            vx, vy, vz = dx / length, dy / length, dz / length
            _set_frame(axes, node, ux, uy, uz, vx, vy, vz)
            for j in range(s, e):
                _widen(axes, ext, node, V, order[j])
            node += 1
        level *= 2
        span //= 2


@njit(cache=True, error_model="numpy")
def oriented_heights(axes, ext, node, nx, ny, nz, off):
    """The highest and lowest points (m) over the plane n·x = off of a node's oriented box."""
    top = -off
    bottom = -off
    for a in range(3):
        c = nx * axes[node, a, 0] + ny * axes[node, a, 1] + nz * axes[node, a, 2]
        lo, hi = c * ext[node, a, 0], c * ext[node, a, 1]
        top += max(lo, hi)
        bottom += min(lo, hi)
    return top + 1e-15, bottom - 1e-15


@njit(cache=True, error_model="numpy")
def box_gap2(lo, hi, qlo, qhi):
    """Squared distance (m²) between box lo..hi and box qlo..qhi (a point: qlo = qhi)."""
    g = 0.0
    for k in range(3):
        e = qlo[k] - hi[k] if qlo[k] > hi[k] else lo[k] - qhi[k] if lo[k] > qhi[k] else 0.0
        g += e * e
    return g


@njit(cache=True, error_model="numpy")
def box_heights(lo, hi, nx, ny, nz, off):
    """The highest and lowest points (m) of box lo..hi over the plane n·x = off."""
    top = -off
    bottom = -off
    for k, nk in enumerate((nx, ny, nz)):
        if nk > 0.0:
            top += nk * hi[k]
            bottom += nk * lo[k]
        else:
            top += nk * lo[k]
            bottom += nk * hi[k]
    return top, bottom


@njit(cache=True, error_model="numpy")
def _near_face(t, qlo, qhi, cx, cy, cz, ri, tlo, thi, centre, rho, reach):
    """Whether triangle t may come within reach (m) of a face of box qlo..qhi and bounding
    ball (c, ri): both its box and its ball do."""
    if box_gap2(tlo[t], thi[t], qlo, qhi) > reach * reach:
        return False
    ex, ey, ez = centre[t, 0] - cx, centre[t, 1] - cy, centre[t, 2] - cz
    return math.sqrt(ex * ex + ey * ey + ez * ez) - rho[t] - ri <= reach


@njit(cache=True, error_model="numpy")
def _rise(t, V, F, nx, ny, nz, off, front, back, fj, bj, tstamp, stamp):
    """Record triangle t on the sides of the plane its vertices rise above (by ABOVE_TOL):
    appended to the rows fj (front) and bj (back) while they hold STATIC_ABOVE, else that
    side becomes -1 (a concave patch). Returns the new (front, back)."""
    if tstamp[t] == stamp:
        return front, back
    tstamp[t] = stamp
    h0 = nx * V[F[t, 0], 0] + ny * V[F[t, 0], 1] + nz * V[F[t, 0], 2] - off
    h1 = nx * V[F[t, 1], 0] + ny * V[F[t, 1], 1] + nz * V[F[t, 1], 2] - off
    h2 = nx * V[F[t, 2], 0] + ny * V[F[t, 2], 1] + nz * V[F[t, 2], 2] - off
    if front >= 0 and max(h0, h1, h2) > ABOVE_TOL:
        if front == STATIC_ABOVE:
            front = -1
        else:
            fj[front] = t
            front += 1
    if back >= 0 and min(h0, h1, h2) < -ABOVE_TOL:
        if back == STATIC_ABOVE:
            back = -1
        else:
            bj[back] = t
            back += 1
    return front, back


@njit(cache=True, nogil=True, error_model="numpy")
def face_lists(faces, V, F, plane, tlo, thi, centre, rho, fan_start, fan, vorder, vlo, vhi, vsize, lorder, llo, lhi,
               lsize, reach, long_edge, laxes, lext, alo, ahi, apex, tstamp, stamp0, count, listed):
    """Per face of `faces` (ids) and side (front, back), the triangles within `reach` (m) of it
    (box and bounding ball within reach of its own) that rise above its plane on that side (a
    vertex higher than ABOVE_TOL): their number in count[j, side] and the triangles in
    listed[j, side], or -1 when more than STATIC_ABOVE do (a concave patch) or the walk
    opens more than BUDGET leaves. Short triangles are found through their rising vertices
    within reach + long_edge of the face (the vertex tree vorder/vlo/vhi/vsize), long ones in
    the long tree (lorder/llo/lhi/lsize; `apex_frames` gives its nodes' apex, their oriented
    boxes laxes, lext and boxes alo..ahi but the apex); a walk leaves out boxes beyond reach
    and boxes wholly behind the plane on every side still open (by the box, and for the long
    tree by the apex and the boxes of the rest too: a cone's face sees its ~25,000 slivers
    about the tip within reach, each node a wedge whose boxes rose above its plane beside the
    tip). `tstamp` (one int per triangle) is scratch, stamped from stamp0 + 1 on."""
    stack = np.empty(STACK, np.int64)
    vreach2 = (reach + long_edge) ** 2
    reach2 = reach * reach
    for j in range(len(faces)):
        i = faces[j]
        stamp = stamp0 + 1 + j
        tstamp[i] = stamp  # not its own
        nx, ny, nz, off = plane[i, 0], plane[i, 1], plane[i, 2], plane[i, 3]
        qlo, qhi = tlo[i], thi[i]
        cx, cy, cz, ri = centre[i, 0], centre[i, 1], centre[i, 2], rho[i]
        fj, bj = listed[j, 0], listed[j, 1]
        front, back = 0, 0
        leaves = 0
        for tree in range(2):
            order, nlo, nhi, size = (vorder, vlo, vhi, vsize) if tree == 0 else (lorder, llo, lhi, lsize)
            limit2 = vreach2 if tree == 0 else reach2
            stack[0] = 1
            sp = 1
            while sp > 0 and (front >= 0 or back >= 0):
                sp -= 1
                node = stack[sp]
                lo, hi = nlo[node], nhi[node]
                if lo[0] > hi[0] or box_gap2(lo, hi, qlo, qhi) > limit2:
                    continue
                top, bottom = box_heights(lo, hi, nx, ny, nz, off)
                if tree == 1:
                    t2, b2 = oriented_heights(laxes, lext, node, nx, ny, nz, off)
                    a = apex[node]
                    if a >= 0:  # the rest's boxes, and the apex
                        t3, b3 = box_heights(alo[node], ahi[node], nx, ny, nz, off)
                        h = nx * V[a, 0] + ny * V[a, 1] + nz * V[a, 2] - off
                        t2, b2 = max(min(t2, t3), h), min(max(b2, b3), h)
                    top, bottom = min(top, t2), max(bottom, b2)
                if not ((front >= 0 and top > ABOVE_TOL) or (back >= 0 and bottom < -ABOVE_TOL)):
                    continue
                if node < size:
                    a, b = 2 * node, 2 * node + 1
                    if box_gap2(nlo[a], nhi[a], qlo, qhi) < box_gap2(nlo[b], nhi[b], qlo, qhi):
                        a, b = b, a
                    stack[sp] = a      # the nearer child last: walked first (a concave side ends sooner)
                    stack[sp + 1] = b
                    sp += 2
                    continue
                leaves += 1
                if leaves > BUDGET:
                    front, back = -1, -1
                    break
                first = (node - size) * LEAF
                for item in range(first, min(len(order), first + LEAF)):
                    if tree == 1:
                        t = order[item]
                        if _near_face(t, qlo, qhi, cx, cy, cz, ri, tlo, thi, centre, rho, reach):
                            front, back = _rise(t, V, F, nx, ny, nz, off, front, back, fj, bj, tstamp, stamp)
                        continue
                    w = order[item]
                    h = nx * V[w, 0] + ny * V[w, 1] + nz * V[w, 2] - off
                    if -ABOVE_TOL <= h <= ABOVE_TOL:
                        continue
                    # w's fan is read for the side w rises on, while that side is open: a
                    # triangle of it rising on the other side has a vertex rising there,
                    # read in turn (a cap's hub is not read 25,000 triangles a face)
                    up = h > 0.0
                    if (up and front < 0) or (not up and back < 0):
                        continue
                    g = 0.0
                    for k in range(3):
                        e = V[w, k] - qhi[k] if V[w, k] > qhi[k] else qlo[k] - V[w, k] if V[w, k] < qlo[k] else 0.0
                        g += e * e
                    if g > vreach2:
                        continue
                    for f in range(fan_start[w], fan_start[w + 1]):
                        t = fan[f]
                        if tstamp[t] != stamp and _near_face(t, qlo, qhi, cx, cy, cz, ri, tlo, thi, centre, rho, reach):
                            front, back = _rise(t, V, F, nx, ny, nz, off, front, back, fj, bj, tstamp, stamp)
                            if (up and front < 0) or (not up and back < 0):
                                break
        count[j, 0], count[j, 1] = front, back


@njit(cache=True, error_model="numpy")
def _least_sine(lo, hi, px, py, pz, ax, ay, az, av, rise):
    """The least sin β a point w of box lo..hi can have, -(w - p)·a / |w - p|: its lowest
    numerator (-rise at most: rise, how high another box about the same points rises over
    the plane through p square to a) over the farthest distance when that is >= 0, over the
    nearest when < 0 (-1 when p is in the box), less a rounding's margin."""
    near2 = 0.0
    far2 = 0.0
    top = 0.0
    for k, (pk, ak) in enumerate(((px, ax), (py, ay), (pz, az))):
        e = lo[k] - pk if pk < lo[k] else pk - hi[k] if pk > hi[k] else 0.0
        near2 += e * e
        f = max(pk - lo[k], hi[k] - pk)
        far2 += f * f
        top += ak * hi[k] if ak > 0.0 else ak * lo[k]
    low = max(av - top, -rise)
    if low >= 0.0:
        bound = low / math.sqrt(far2) if far2 > 0.0 else 1.0
    elif near2 > 0.0:
        bound = max(-1.0, low / math.sqrt(near2))
    else:
        bound = -1.0
    return bound - 1e-12


@njit(cache=True, error_model="numpy")
def _sine(w, V, px, py, pz, ax, ay, az):
    """Vertex w's sin β seen from p (axis a), rounded down to 1/SINE_GRID."""
    ux, uy, uz = V[w, 0] - px, V[w, 1] - py, V[w, 2] - pz
    s = -(ux * ax + uy * ay + uz * az) / math.sqrt(ux * ux + uy * uy + uz * uz)
    return math.floor((s + 1.0) * SINE_GRID) / SINE_GRID - 1.0


@njit(cache=True, error_model="numpy")
def _long_near(w, v, p, F, fan_start, fan, longest, long_edge, tlo, thi, centre, rho, reach):
    """Whether vertex w has a long triangle (longest edge over long_edge) in its fan that may
    come within `reach` (m) of point p (box and bounding ball) and is not one of vertex v's
    own; True, unchecked, when w's fan holds more than FAN_CHECK triangles."""
    if fan_start[w + 1] - fan_start[w] > FAN_CHECK:
        return True
    for f in range(fan_start[w], fan_start[w + 1]):
        t = fan[f]
        if longest[t] <= long_edge or F[t, 0] == v or F[t, 1] == v or F[t, 2] == v:
            continue
        if box_gap2(tlo[t], thi[t], p, p) > reach * reach:
            continue
        ex, ey, ez = centre[t, 0] - p[0], centre[t, 1] - p[1], centre[t, 2] - p[2]
        if math.sqrt(ex * ex + ey * ey + ez * ez) - rho[t] <= reach:
            return True
    return False


@njit(cache=True, nogil=True, error_model="numpy")
def vertex_tables(verts, V, F, axis, ring_start, ring_to, tlo, thi, centre, rho, fan_start, fan, longest, vorder,
                  vlo, vhi, rlo, rhi, wlo, whi, vsize, vaxes, vext, reach, long_edge, mark, stamp0, sines, ids, counts):
    """Per vertex v of `verts` (ids): among the vertices w of the triangles within `reach` (m)
    of it but its fan, w other than v and the ends of its edges, the VERTEX_READ + 1 of least
    sin β (β: the angle of w - v below the plane square to v's cone axis), rounded down to
    1/SINE_GRID, ascending: sines[j], ids[j], their number counts[j].

    One walk of a box tree whose items are the vertices' reach boxes (`softproxy.mesh.
    reach_boxes`: a vertex's position grown by long_edge, and by the boxes of its long
    triangles, those whose longest edge (`longest`) is over long_edge, one box per octant
    they lie in), each at its vertex: vorder (the vertex of each item, in tree order), wlo..whi
    (its box), vsize; per node vlo..vhi the box of its items' vertices, vaxes, vext their box
    oriented by the first (`point_frames`), rlo..rhi the box of its items' reach boxes. A
    short triangle within reach has every vertex within reach + long_edge, and every such
    vertex is taken (a superset, which only makes a table more cautious); a vertex farther
    out is taken when one of its long triangles may come within reach (`_long_near`).

    Nearest node first (a heap: a depth-first walk went down a far subtree whose box held v
    and spent its budget there before it reached v's neighbours). Once the table is full, the
    nodes that cannot hold a lower sin β are left out, by their vertices' boxes, axis-aligned
    and oriented: they stay tight where a run of long slivers' boxes, whose near ends lie
    beside v, do not (the triangles' tree walked before opened ~20,000 slivers a vertex on a
    cylinder of 25,000 sections), and the oriented one stays thin along a finely divided rim
    where the axis-aligned one, turned 45° to it, does not. A vertex whose walk opens more
    than BUDGET leaves, or whose full table is all below DEAD_SINE, gets a table that
    certifies nothing (VERTEX_READ + 1 entries at sin β = -1: every query reads past
    VERTEX_READ, and the box tree serves it). `mark` (one int per vertex) is scratch,
    stamped from stamp0 + 1 on."""
    keep = sines.shape[1]
    room = 2 * vsize + 2  # every node waits at most once a walk
    gaps = np.empty(room)
    waiting = np.empty(room, np.int64)
    vreach2 = (reach + long_edge) ** 2
    reach2 = reach * reach
    p = np.empty(3)
    for j in range(len(verts)):
        v = verts[j]
        stamp = stamp0 + 1 + j
        px, py, pz = V[v, 0], V[v, 1], V[v, 2]
        p[0], p[1], p[2] = px, py, pz
        ax, ay, az = axis[v, 0], axis[v, 1], axis[v, 2]
        av = ax * px + ay * py + az * pz
        mark[v] = stamp
        for e in range(ring_start[v], ring_start[v + 1]):
            mark[ring_to[e]] = stamp
        hs, hw = sines[j], ids[j]
        m = 0
        leaves = 0
        # nearest node first (a heap of those waiting, by -gap²): the table fills with the
        # nearest vertices, whose sin β leaves out the rest soonest
        w_count = heap_offer(gaps, waiting, 0, room, -box_gap2(vlo[1], vhi[1], p, p), 1)
        while w_count > 0:
            if m == keep and hs[0] < DEAD_SINE:
                leaves = BUDGET + 1  # already a table no query can pass: stop here
                break
            _, node, w_count = heap_pop(gaps, waiting, w_count)
            lo, hi = vlo[node], vhi[node]
            if lo[0] > hi[0] or box_gap2(rlo[node], rhi[node], p, p) > reach2:
                continue
            if m == keep and _least_sine(lo, hi, px, py, pz, ax, ay, az, av,
                                         oriented_heights(vaxes, vext, node, ax, ay, az, av)[0]) >= hs[0]:
                continue
            if node < vsize:
                for child in range(2 * node, 2 * node + 2):
                    if vlo[child, 0] <= vhi[child, 0] and box_gap2(rlo[child], rhi[child], p, p) <= reach2:
                        w_count = heap_offer(gaps, waiting, w_count, room, -box_gap2(vlo[child], vhi[child], p, p), child)
                continue
            leaves += 1
            if leaves > BUDGET:
                break
            first = (node - vsize) * LEAF
            for item in range(first, min(len(vorder), first + LEAF)):
                w = vorder[item]
                if mark[w] == stamp:
                    continue
                near = box_gap2(V[w], V[w], p, p) <= vreach2
                if not near and box_gap2(wlo[item], whi[item], p, p) > reach2:
                    continue
                s = _sine(w, V, px, py, pz, ax, ay, az)
                if m == keep and s >= hs[0]:
                    continue  # the table keeps lower ones
                if near or _long_near(w, v, p, F, fan_start, fan, longest, long_edge, tlo, thi, centre, rho, reach):
                    mark[w] = stamp
                    m = heap_offer(hs, hw, m, keep, s, w)
        if leaves > BUDGET:
            for c in range(keep):
                hs[c], hw[c] = -1.0, v
            m = keep
        # ascending: sort the heap's m entries (by sin β, then vertex id)
        for a in range(1, m):
            sa, wa = hs[a], hw[a]
            b = a - 1
            while b >= 0 and (hs[b] > sa or (hs[b] == sa and hw[b] > wa)):
                hs[b + 1], hw[b + 1] = hs[b], hw[b]
                b -= 1
            hs[b + 1], hw[b + 1] = sa, wa
        counts[j] = m
