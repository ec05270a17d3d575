"""Triangle-mesh contact for the god-object: the mesh's own triangles, not its convex hull.

MuJoCo collides a mesh geom through its convex hull, so a finger pressed into a bowl would
stop on the plane of the rim. These kernels answer the god-object's queries on the triangles
themselves, in the geom frame MuJoCo compiled them into (`model.mesh_vert` is expressed in
the frame of `geom_xpos` / `geom_xmat`), from two arrays that `mesh_tables` packs for every
mesh of a world out of what `softproxy.mesh.MeshShape` built at load: T, one row per
triangle (its corners, edges, plane, the pseudo-normals of its features, its vertex normals,
its neighbours and certificate lists; columns in `layout`), and C (per mesh a box tree over
its triangles, and the kept certificates of `softproxy.compiled.certificate`).

- `mesh_distance`: the exact Euclidean distance to the nearest triangle, so 1-Lipschitz. On
  a watertight mesh it is signed by the angle-weighted pseudo-normal of the nearest feature
  (face, edge or vertex; Bærentzen & Aanæs 2005), which gives the right side wherever the
  nearest point lies. An open mesh (a sheet) has no inside: its distance is unsigned and both
  sides of every triangle are solid.
- `mesh_sweep`: the earliest touch of a sphere (radius r) moving on a segment, each triangle
  inflated by r, which is convex (a slab over the face, a cylinder per edge, a ball per
  vertex): so the first touch is exact on a non-convex mesh, a sphere touching a triangle and
  moving along or away from it never enters it, and no speed carries the sphere through a
  triangle. A touching sphere is stopped only when pressed into a triangle beyond a touch
  (CONTACT_TOL, `_pressed`), so sliding along a tangent plane that a nearly parallel
  neighbour's dips below by a rounding goes on. A point proxy is swept as a 10 nm sphere
  (POINT_RADIUS).

Cost per query is bounded on large meshes:
1. the hint, the triangle touched or nearest last, is read first: pressed into it, a sweep
   ends at once. Its tangent plane at the nearest point is a certificate: a triangle lying
   wholly behind it is at least as far, so a point whose nearest point is there, or a sphere
   sliding on or lifting off it, needs only the few triangles near it that reach above that
   plane (`softproxy.compiled.certificate`): the rising wall inside a bowl, none on a convex
   patch (none of the ~100 thin triangles meeting at a uv-sphere's pole). When the nearest
   point is on an edge, the point may lie over or beyond the neighbour across it, and when it
   is on a vertex, an edge rising above the tangent plane there leads to a nearer triangle:
   the query walks there first (`_walk`), so that the certificate of the face, edge or
   vertex reached holds more often. A point at distance d needs the certificates to hold over a
   reach of 2d, a sphere of radius r sliding by L over 2r + L: they are built at load for a
   5 mm proxy, and for a larger one by `MeshShape.prepare` when a proxy is made;
2. where they do not hold (a concave patch, a reach beyond theirs, no hint yet), the
   query's hint slot keeps a patch: the records of every triangle within a capsule about
   a segment a little (PATCH_MARGIN) wider than the query needs, or of the PATCH_RECORDS
   nearest and a thinner capsule, sorted by distance and gathered from the box tree, so a
   finger pressed into a bowl (ten sweeps a tick about one point) or sliding in it reads
   the few records near its own capsule and walks the tree once per millimetre; a sliding
   finger's capsules are stretched ahead along its slide (PATCH_AHEAD); where even a
   capsule PATCH_KEEP wider than the query's holds more (a dense mesh, a long sweep), the
   box tree (but for a finger held still, whose patch is only PATCH_CLOSE wider than its
   queries), from the cut of nodes noted under that capsule: the tree built at load
   (`softproxy.mesh.MeshTables`: triangles in Morton order, 8 a leaf, per node an
   axis-aligned box and a box oriented by its first triangle, tight about a run of
   slivers): walked nearest node first, leaving out nodes farther than the best distance
   found (distance), or the nodes the segment enters, grown by the reach, before the earliest
   touch found, earliest first (sweep); a leaf's records carry each triangle's plane and
   the rectangle in it that holds it (along its longest edge: a sliver's is as thin as the
   sliver), so most of its triangles are ruled out without opening them. The walk
   reads the nodes near the query, O(log n) of them where the boxes are tight, not a
   region's worth of triangles;
3. the last two distance answers are kept, and a sweep keeps its start point's answer when a
   certificate proved its nearest point (the god-object asks again about the point it holds,
   and about where a sweep left it), keyed by the point in the geom frame, so a new pose
   never returns a stale answer.

A mesh never reports a contact `on_face` (`softproxy.compiled.shapes.shape_on_face`): the
god-object's hold fast path for a flat face does not apply (a triangle's plane runs on past
its edges); a proxy stuck on a static mesh starts the next tick's solve from the planes it
rests on (`softproxy.compiled.godobject._warm_planes`), and a proxy in contact solves its
frictionless proxy on from last tick's (`_free_from_last`), every motion still swept.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np
from numba import njit

from softproxy.compiled.ball import BALL_SLACK
from softproxy.compiled.certificate import (
    ABOVE_TOL, LEAF, face_few, certificate_tables, heap_offer, heap_pop, node_frames, static_clear,
)
from softproxy.compiled.finite import finite
from softproxy.compiled.layout import (
    CUT_NODES, C_FEW, C_STAMP, C_STAMPS, EDGE_AB, EDGE_WIDTH, FACE, GEOM_MESH, HINT_SLOTS, KEPT_DISTANCE,
    KEPT_NORMAL, KEPT_POINT, KEPT_ROW, KEPT_WIDTH, NODE_WIDTH, N_AXES, N_EXT, N_HI, N_LO, PATCH_RECORDS,
    PATCH_WIDTH, P_COUNT, P_CUT, P_END, P_FULL, P_KEYS, P_RADIUS, P_RECORDS, RECORD_WIDTH, R_CENTRE, R_ROW,
    SLOT_AGE, SLOT_HINT, SLOT_KEPT, TREE_NODES, TREE_RECORDS, TREE_SIZE, T_A, T_AA, T_AB, T_ABAC, T_AC, T_ADJ,
    T_BALL, T_CC, T_COLUMNS, T_EDGES, T_INV, T_N, T_PSEUDO, T_TV, T_VN, VERTEX_A, VERTEX_WIDTH, V_AXIS, V_COS,
    V_RING,
)
from softproxy.compiled.tolerances import CONTACT_TOL, GRAZE
from softproxy.compiled.triangle import closest

POINT_RADIUS = 1e-8
"""A point proxy (r = 0) is swept as a sphere this big (m). On an edge or a vertex the direction
from the nearest point to a point lying on it is rounding noise, so whether it moves into the
mesh is not decidable; 10 nm gives it a direction and is far below the 1 µm promise."""
SLOT_NEAR = 0.0005
"""A query within this distance (m) of a hint slot's last query keeps to that slot (`_slot`):
a finger's proxy and its frictionless proxy, a millimetre apart, keep a patch each."""
WALK_STEPS = 8
"""Most steps from a vertex to a nearer triangle around it before a query reads the fan."""


TREE_MARGIN = 1e-12
"""A box tree's boxes are grown by this (m, plus as much per metre of the mesh's bounding
radius) beyond their triangles, so that no rounding of a box test leaves a triangle out."""
STACK = 256
"""Depth of a tree walk's stack (two entries per level: far more than any tree has)."""
FRONTIER = 4096
"""Most nodes a patch's gathering walk keeps waiting, nearest first (`_gather`): no more wait
than were read (each adds two), a few hundred at a million triangles. Past it the patch
holds less, down to the gap of the node it had no room for."""
PATCH_MARGIN = 0.001
"""A slot's patch gathers the triangles this much (m) beyond the capsule the query gathering
it needs, so the next queries of a finger that moved less than that read it again; a
capsule found too full is stretched this far ahead along a sliding finger's way."""
PATCH_KEEP = 1e-4
"""A patch must hold at least this much (m) beyond the capsule of the query gathering it: one
holding less (a million triangles under a 5 mm proxy) would serve next to no other query, and
be gathered again and again as the finger trembles: the box tree answers the queries about it
instead, from the cut under a capsule this much wider than the query, noted too full."""
PATCH_AHEAD = 2e-4
"""A sliding finger's patch is stretched this far (m) ahead along the way its slot has
travelled since the last one (`_ahead`): its queries keep near the line it slides on, so a
strip serves a longer slide than a round capsule holding as many triangles (the 1M scanned
sphere's patches: gathered every ~130 µm of sliding, now every ~270 µm)."""
PATCH_KEEP_AHEAD = 3e-5
"""The least (m) a stretched patch must hold beyond the query's capsule, across the strip: it
serves the slide along its length, so it may be thinner than PATCH_KEEP."""
PATCH_STILL = 2e-6
"""But a query within this (m) of its slot's last, inside a capsule found too full, gathers a
patch only PATCH_CLOSE wider than itself (`_patch`): a finger held still asks about one place
tick after tick (a sliding one's queries move ~10 µm a tick)."""
PATCH_CLOSE = 2e-5
"""How much wider (m) than its query a held-still finger's patch is: at a million triangles
the ~30 within 20 µm of a 5 mm proxy make a patch where the ~300 within 0.1 mm do not (the
tree walk it saves: ~3 µs an update)."""


# ---------------------------------------------------------------------------------------
# Packing (numpy, at load)
# ---------------------------------------------------------------------------------------

def tree_nodes(order, nlo, nhi, size, V, F, plane):
    """The nodes (2 size, NODE_WIDTH; node 0 unused) of a box tree over triangles (`box_tree`'s
    order, node boxes and size over the triangles' boxes; vertices V, faces F, planes): each
    node's axis-aligned box and its box oriented by its first triangle (`node_frames`). An
    empty node's boxes are inverted (+inf..-inf)."""
    axes, ext = node_frames(order, size, V, F, plane)
    out = np.empty((2 * size, NODE_WIDTH))
    out[:, N_LO:N_LO + 3] = nlo
    out[:, N_HI:N_HI + 3] = nhi
    out[:, N_AXES:N_AXES + 9] = axes.reshape(2 * size, 9)
    out[:, N_EXT:N_EXT + 3] = ext[:, :, 0]
    out[:, N_EXT + 3:N_EXT + 6] = ext[:, :, 1]
    return out


def _rectangles(tri: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """The rectangle in each triangle's plane that holds it, as its record's columns
    R_CENTRE..R_ROW: its centre, its axis (the longest edge's direction) and its half-length
    and half-width (m), grown by a part in 10¹² and 1 fm so that rounding never leaves a
    corner out."""
    a, b, c, n = tri[:, 0:3], tri[:, 3:6], tri[:, 6:9], tri[:, T_N:T_N + 3]
    longest = np.argmax(edges[:, :, 6], axis=1)
    u = edges[np.arange(len(tri)), longest, 3:6]
    w = np.cross(n, u)
    su = np.stack([(v * u).sum(1) for v in (a, b, c)], axis=1)
    sw = np.stack([(v * w).sum(1) for v in (a, b, c)], axis=1)
    mu, mw = (su.max(1) + su.min(1)) / 2.0, (sw.max(1) + sw.min(1)) / 2.0
    # the centre: in the plane, at the middle of both spans
    out = np.empty((len(tri), R_ROW - R_CENTRE))
    out[:, 0:3] = a + (mu - su[:, 0])[:, None] * u + (mw - sw[:, 0])[:, None] * w
    out[:, 3:6] = u
    out[:, 6] = (su.max(1) - su.min(1)) / 2.0 * (1.0 + 1e-12) + 1e-15
    out[:, 7] = (sw.max(1) - sw.min(1)) / 2.0 * (1.0 + 1e-12) + 1e-15
    return out


def mesh_tables(shapes, S: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The mesh tables (T, C) of the `softproxy.mesh.MeshShape`s among `shapes`, and their
    rows of the shape table S filled in (where their triangles and box tree live). Geoms of
    one mesh asset (one `MeshTables`) share its rows of T and its part of C; each keeps its
    own pose, hint and kept answers in S. A world with no mesh gets empty tables (the
    kernels' types stay the same)."""
    meshes = [(k, s) for k, s in enumerate(shapes) if s.gtype == GEOM_MESH]
    assets = list({id(s.tables): s.tables for _, s in meshes}.values())
    ntri = sum(a.triangles for a in assets)
    rows, parts, where = [], [], {}
    t0 = 0
    c0 = C_STAMPS + ntri  # the scan counter, the certificates' scratch, a stamp per triangle, then the trees
    for a in assets:
        n = a.triangles
        order, size, nodes = a.tree
        nodes = nodes[1:].copy()  # node 0 is not a node
        grow = TREE_MARGIN * (1.0 + a.rbound)
        nodes[:, N_LO:N_LO + 3] -= grow
        nodes[:, N_HI:N_HI + 3] += grow
        nodes[:, N_EXT:N_EXT + 3] -= grow
        nodes[:, N_EXT + 3:N_EXT + 6] += grow
        first = c0 + TREE_NODES + nodes.size  # where this asset's records begin in C
        records = np.empty((n, RECORD_WIDTH))
        records[:, 0:4] = a.plane[order]
        records[:, R_CENTRE:R_ROW] = _rectangles(a.tri, a.edges)[order]
        records[:, R_ROW] = order + t0
        parts += [np.array([size, first], dtype=np.float64), nodes.ravel(), records.ravel()]
        del records, nodes
        tree = c0
        c0 = first + n * RECORD_WIDTH
        columns, kept, reach, ball = certificate_tables(a, t0, c0)
        rows.append(np.concatenate([a.tri, a.edges.reshape(n, 3 * EDGE_WIDTH), a.pn.reshape(n, 21), a.vn, columns],
                                   axis=1))
        where[id(a)] = (t0, n, tree, c0, reach, ball)
        parts.append(kept)
        c0 += len(kept)
        t0 += n
    for k, s in meshes:
        t0, n, tree, verts, reach, ball = where[id(s.tables)]
        S[k].t0, S[k].nt, S[k].tree = t0, n, tree
        S[k].signed = s.signed
        S[k].shading = s.shading
        S[k].hint = S[k].feature = -1
        S[k].key[:, :] = math.nan  # no hint slot used, none kept
        S[k].verts = verts
        S[k].kept = reach
        S[k].ball = ball
        S[k].patch = c0
        patches = np.zeros((HINT_SLOTS, PATCH_WIDTH))
        patches[:, P_RADIUS] = -1.0  # holds nothing yet
        patches[:, P_FULL + 6] = -1.0  # nor was found too full
        parts.append(patches.ravel())
        c0 += patches.size
    T = np.concatenate(rows) if len(rows) != 1 else rows[0]
    if not rows:
        T = np.zeros((0, T_COLUMNS))
    assert T.shape[1] == T_COLUMNS
    C = np.empty(c0)
    C[:C_STAMPS + ntri] = 0.0
    at = C_STAMPS + ntri
    for g in parts:
        C[at:at + len(g)] = g
        at += len(g)
    assert at == c0 and len(C) < 2 ** 53
    return np.ascontiguousarray(T), C


# ---------------------------------------------------------------------------------------
# One triangle: its features FACE, EDGE_AB/BC/CA, VERTEX_A/B/C (softproxy.compiled.layout)
# ---------------------------------------------------------------------------------------

Sweep = namedtuple("Sweep", "ax ay az ux uy uz r dd graze")
"""A sphere's sweep in a mesh's geom frame: from a (m) by u (m, the whole move), radius r (m),
dd = |u|² (m²) and graze = GRAZE·|u| (m): a touch whose motion into the surface is slower
than that is a graze, not a hit."""

MISS = (-1.0, 0.0, 0.0, 0.0, FACE)
"""A sweep's answer when the sphere does not touch the triangle: lam -1 (no feature)."""

@njit(cache=True, error_model="numpy")
def _pressed(dist, into, r, graze):
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


@njit(cache=True, error_model="numpy")
def _sweep_triangle(T, i, sweep, far2):
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
        # touching now: a hit only if pressed into it (`_pressed`)
        dist = math.sqrt(d2)
        if dist > 1e-12:
            mx, my, mz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
        elif hd != 0.0:  # the centre on the triangle (a point proxy): the side it comes from
            s = -1.0 if hd > 0.0 else 1.0
            mx, my, mz = s * nx, s * ny, s * nz
        else:
            return MISS
        if _pressed(dist, mx * dx + my * dy + mz * dz, r, graze):
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


@njit(cache=True, error_model="numpy")
def _shade(T, i, qx, qy, qz, nx, ny, nz):
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


# ---------------------------------------------------------------------------------------
# The box tree: node j of mesh k at C[S.tree + TREE_NODES + NODE_WIDTH (j - 1)]
# ---------------------------------------------------------------------------------------

@njit(cache=True, error_model="numpy")
def _node_gap2(C, at, x, y, z):
    """A lower bound on the squared distance (m²) from p to any triangle of the node at C[at]:
    the larger of the squared distances to its axis-aligned and to its oriented box (inf for
    an empty node)."""
    ex = C[at + N_LO] - x if x < C[at + N_LO] else x - C[at + N_HI] if x > C[at + N_HI] else 0.0
    ey = C[at + N_LO + 1] - y if y < C[at + N_LO + 1] else y - C[at + N_HI + 1] if y > C[at + N_HI + 1] else 0.0
    ez = C[at + N_LO + 2] - z if z < C[at + N_LO + 2] else z - C[at + N_HI + 2] if z > C[at + N_HI + 2] else 0.0
    box = ex * ex + ey * ey + ez * ez
    oriented = 0.0
    for a in range(3):
        c = at + N_AXES + 3 * a
        p = C[c] * x + C[c + 1] * y + C[c + 2] * z
        lo, hi = C[at + N_EXT + a], C[at + N_EXT + 3 + a]
        e = lo - p if p < lo else p - hi if p > hi else 0.0
        oriented += e * e
    return box if box > oriented else oriented


@njit(cache=True, error_model="numpy")
def _slab_entry(p, u, lo, hi, t0, t1):
    """The part [t0, t1] of the line p + t u (one axis) that lies within lo..hi (t0 > t1: none)."""
    if u == 0.0:
        if p < lo or p > hi:
            return 1.0, 0.0
        return t0, t1
    a, b = (lo - p) / u, (hi - p) / u
    if a > b:
        a, b = b, a
    return (a if a > t0 else t0), (b if b < t1 else t1)


@njit(cache=True, error_model="numpy")
def _span_gap(p0, p1, lo, hi):
    """The gap (m) between the span p0..p1 and lo..hi on one axis (0 where they overlap)."""
    if p0 > p1:
        p0, p1 = p1, p0
    return lo - p1 if p1 < lo else p0 - hi if p0 > hi else 0.0


@njit(cache=True, error_model="numpy")
def _span_gap2(C, at, ax, ay, az, ux, uy, uz, tmax):
    """A lower bound on the squared distance (m²) from the segment a + t u (t in [0, tmax])
    to the node at C[at]'s triangles: over either box, the sum over its axes of the squared
    gap between the segment's span and the box's along the axis (the larger of the two)."""
    ex = _span_gap(ax, ax + tmax * ux, C[at + N_LO], C[at + N_HI])
    ey = _span_gap(ay, ay + tmax * uy, C[at + N_LO + 1], C[at + N_HI + 1])
    ez = _span_gap(az, az + tmax * uz, C[at + N_LO + 2], C[at + N_HI + 2])
    box = ex * ex + ey * ey + ez * ez
    oriented = 0.0
    for a in range(3):
        c = at + N_AXES + 3 * a
        p = C[c] * ax + C[c + 1] * ay + C[c + 2] * az
        v = C[c] * ux + C[c + 1] * uy + C[c + 2] * uz
        e = _span_gap(p, p + tmax * v, C[at + N_EXT + a], C[at + N_EXT + 3 + a])
        oriented += e * e
    return box if box > oriented else oriented


@njit(cache=True, error_model="numpy")
def _stays_above(C, at, ax, ay, az, ux, uy, uz, r, slack, tmax):
    """True when a sphere of radius r (m) on the segment a + t u, t in [0, tmax], stays r
    off the node at C[at]'s oriented box along its first axis (the plane of its first
    face), on one side from start to end (sliding over a flat patch, or lifting off it): it
    never comes nearer than r to the node's triangles, so touches none. The box's extents
    are taken less `slack` (m), what they were grown by at packing: a sphere resting on a
    flat patch is r above it to a rounding."""
    n0 = C[at + N_AXES] * ax + C[at + N_AXES + 1] * ay + C[at + N_AXES + 2] * az
    n1 = n0 + tmax * (C[at + N_AXES] * ux + C[at + N_AXES + 1] * uy + C[at + N_AXES + 2] * uz)
    top, bottom = C[at + N_EXT + 3] - slack, C[at + N_EXT] + slack
    return (n0 - top >= r and n1 - top >= r) or (bottom - n0 >= r and bottom - n1 >= r)


@njit(cache=True, error_model="numpy")
def _node_entry(C, at, ax, ay, az, ux, uy, uz, length, r, grow, slack, tmax):
    """Where (fraction of the segment a + t u, t in [0, tmax], |u| = length (m)) it enters
    the node at C[at]'s boxes, each grown by `grow` (m) on every side; > tmax when it does
    not, or when the boxes lie farther than `grow` plus half its length from its middle, or
    when a sphere of radius r (m) on it stays r above the node's oriented box along its first
    axis (`_stays_above`). A sphere of radius r < grow
    touching a triangle of the node has its centre within r of both boxes, so no touch on
    the segment comes before this, nor before the distance from a to the boxes less `grow`
    is travelled. The second test is what keeps
    a sphere sliding over a surface to the nodes right under it: grown per axis, the boxes
    of every patch within r beside it would hold its centre."""
    # no touch before the distance from a falls to r: the distance moves by `length` at most
    # over the segment (1-Lipschitz)
    g2 = _node_gap2(C, at, ax, ay, az)
    if g2 <= grow * grow:
        # the start lies within `grow` of both boxes, so within them grown on every axis:
        # entered at once (what every test below would find, for less), unless the sphere
        # stays r above the node's plane: sliding over a flat cap of 10⁴ slivers, it is
        # within reach of every one, and clear of all
        if _stays_above(C, at, ax, ay, az, ux, uy, uz, r, slack, tmax):
            return 2.0 * tmax + 1.0
        return 0.0
    lower = (math.sqrt(g2) - grow) / length
    if lower > tmax:
        return 2.0 * tmax + 1.0
    mx, my, mz = ax + 0.5 * tmax * ux, ay + 0.5 * tmax * uy, az + 0.5 * tmax * uz
    ball = grow + 0.5 * tmax * length
    if _node_gap2(C, at, mx, my, mz) > ball * ball:
        return 2.0 * tmax + 1.0
    if _stays_above(C, at, ax, ay, az, ux, uy, uz, r, slack, tmax):
        return 2.0 * tmax + 1.0
    # per axis of either box, the least gap (m) between the segment's span and the box's:
    # together they bound the distance from every point of the segment (a tube about it,
    # where the boxes grown per axis are a square one)
    if _span_gap2(C, at, ax, ay, az, ux, uy, uz, tmax) > grow * grow:
        return 2.0 * tmax + 1.0
    t0, t1 = 0.0, tmax
    t0, t1 = _slab_entry(ax, ux, C[at + N_LO] - grow, C[at + N_HI] + grow, t0, t1)
    t0, t1 = _slab_entry(ay, uy, C[at + N_LO + 1] - grow, C[at + N_HI + 1] + grow, t0, t1)
    t0, t1 = _slab_entry(az, uz, C[at + N_LO + 2] - grow, C[at + N_HI + 2] + grow, t0, t1)
    if t0 > t1:
        return 2.0 * tmax + 1.0
    for a in range(3):
        c = at + N_AXES + 3 * a
        p = C[c] * ax + C[c + 1] * ay + C[c + 2] * az
        v = C[c] * ux + C[c + 1] * uy + C[c + 2] * uz
        t0, t1 = _slab_entry(p, v, C[at + N_EXT + a] - grow, C[at + N_EXT + 3 + a] + grow, t0, t1)
        if t0 > t1:
            return 2.0 * tmax + 1.0
    return t0 if t0 > lower else lower


@njit(cache=True, error_model="numpy")
def _tree(S, C, k):
    """Mesh k's box tree: where it begins in C, its number of leaves, the mesh's number of
    triangles, and `base`, from which node j's record is at base + NODE_WIDTH j."""
    tree = int(S[k].tree)
    return tree, int(C[tree + TREE_SIZE]), int(S[k].nt), tree + TREE_NODES - NODE_WIDTH


@njit(cache=True, error_model="numpy")
def _push_ordered(nodes, keys, top, node, key):
    """Push `node` with `key` onto a walk's stack nodes[:top], keys[:top] kept in descending
    key order, so the least (the nearest, the earliest entered) is read first; returns the
    new top."""
    j = top
    while j > 0 and keys[j - 1] < key:
        nodes[j], keys[j] = nodes[j - 1], keys[j - 1]
        j -= 1
    nodes[j], keys[j] = node, key
    return top + 1


@njit(cache=True, error_model="numpy")
def _leaf_records(C, tree, node, size, n):
    """The records (C[j0:j1]) of the triangles of leaf node `node` of a tree at C[tree]."""
    first = (node - size) * LEAF
    last = min(first + LEAF, n)
    rec = int(C[tree + TREE_RECORDS])
    return rec + first * RECORD_WIDTH, rec + max(last, first) * RECORD_WIDTH


@njit(cache=True, error_model="numpy")
def _walk(S, T, C, k, hint, d2, qx, qy, qz, feature, x, y, z):
    """From the hint's nearest point q to p on an edge or a vertex, step to a nearer triangle:
    across the edge (p may lie over the neighbour's face, or beyond it), or from a vertex to
    a triangle on an edge leaving it that rises above the tangent plane there (it holds a
    nearer point); while there is one, WALK_STEPS at most: the certificate of the face, edge
    or vertex reached then holds more often. Returns (d2, qx, qy, qz, feature, hint)."""
    verts = int(S[k].verts)
    for _ in range(WALK_STEPS):
        if feature == FACE or d2 <= 0.0:
            break
        if feature < VERTEX_A:
            step = int(T[hint, T_ADJ + feature - EDGE_AB])
        else:
            rec = verts + VERTEX_WIDTH * int(T[hint, T_TV + feature - VERTEX_A])
            dist = math.sqrt(d2)
            nx, ny, nz = (x - qx) / dist, (y - qy) / dist, (z - qz) / dist
            if nx * C[rec + V_AXIS] + ny * C[rec + V_AXIS + 1] + nz * C[rec + V_AXIS + 2] >= C[rec + V_COS]:
                break
            step = -1
            r0 = int(C[rec + V_RING])
            for j in range(r0, r0 + 4 * int(C[rec + V_RING + 1]), 4):
                if nx * C[j] + ny * C[j + 1] + nz * C[j + 2] > ABOVE_TOL:
                    step = int(C[j + 3])
                    break
        if step < 0:
            break
        c2, rx, ry, rz, f = closest(T, step, x, y, z)
        if c2 >= d2:
            break
        d2, qx, qy, qz, feature, hint = c2, rx, ry, rz, f, step
    return d2, qx, qy, qz, feature, hint


@njit(cache=True, error_model="numpy")
def _from_hint(S, T, C, k, hint0, x, y, z):
    """The nearest point to p (geom frame) on row hint0, or on the triangle across the edge it
    lies on when that is nearer (p may lie over the neighbour's face), walked on from there
    (`_walk`) when it stepped across or lies on a vertex: (d2, qx, qy, qz, feature, row).
    Every distance query and sweep begins here."""
    hint = hint0
    d2, qx, qy, qz, f = closest(T, hint, x, y, z)
    if EDGE_AB <= f < VERTEX_A:
        other = int(T[hint, T_ADJ + f - EDGE_AB])
        if other >= 0:
            c2, rx, ry, rz, g = closest(T, other, x, y, z)
            if c2 < d2:
                d2, qx, qy, qz, f, hint = c2, rx, ry, rz, g, other
    if (f != FACE and hint != hint0) or f >= VERTEX_A:
        return _walk(S, T, C, k, hint, d2, qx, qy, qz, f, x, y, z)
    return d2, qx, qy, qz, f, hint


@njit(cache=True, error_model="numpy")
def _nearest_run(T, C, j0, j1, x, y, z, best2, qx, qy, qz, bf, bi):
    """The nearest so far to p among the triangles of the records C[j0:j1] and the one found
    before (best2 (m²), q, feature bf, row bi; bi itself is not read again)."""
    best = math.sqrt(best2)
    for j in range(j0, j1, RECORD_WIDTH):
        h = C[j] * x + C[j + 1] * y + C[j + 2] * z - C[j + 3]
        if h >= best or -h >= best:
            continue  # its plane is already farther than the best
        # or the rectangle in its plane that holds it: the height over the plane and how far
        # the foot lies beyond the rectangle bound it
        if h * h + _beyond2(C, j, x - C[j + 4], y - C[j + 5], z - C[j + 6]) >= best2:
            continue
        i = int(C[j + R_ROW])
        if i == bi:
            continue
        d2, rx, ry, rz, f = closest(T, i, x, y, z)
        if d2 < best2:
            best2, qx, qy, qz, bf, bi = d2, rx, ry, rz, f, i
            best = math.sqrt(d2)
    return best2, qx, qy, qz, bf, bi


@njit(cache=True, error_model="numpy")
def _segment_gap(ax, ay, az, bx, by, bz, px, py, pz):
    """The distance (m) from p to the segment a..b."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0 if uu == 0.0 else (wx * ux + wy * uy + wz * uz) / uu
    t = 0.0 if t < 0.0 else 1.0 if t > 1.0 else t
    ex, ey, ez = wx - t * ux, wy - t * uy, wz - t * uz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@njit(cache=True, error_model="numpy")
def _across(C, j):
    """The unit vector across the rectangle of the record at C[j]: its plane's normal × its
    axis."""
    nx, ny, nz = C[j], C[j + 1], C[j + 2]
    ux, uy, uz = C[j + 7], C[j + 8], C[j + 9]
    return ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux


@njit(cache=True, error_model="numpy")
def _beyond2(C, j, ex, ey, ez):
    """How far (m², squared) the foot of a point at e (m) from the centre of the record at
    C[j] lies beyond its rectangle, in the triangle's plane."""
    wx, wy, wz = _across(C, j)
    along = abs(ex * C[j + 7] + ey * C[j + 8] + ez * C[j + 9]) - C[j + 10]
    across = abs(ex * wx + ey * wy + ez * wz) - C[j + 11]
    out = 0.0
    if along > 0.0:
        out += along * along
    if across > 0.0:
        out += across * across
    return out


@njit(cache=True, error_model="numpy")
def _span_beyond(s0, s1, half):
    """How far (m) the span s0..s1 lies from the span -half..half."""
    lo, hi = (s0, s1) if s0 <= s1 else (s1, s0)
    return lo - half if lo > half else -half - hi if hi < -half else 0.0


@njit(cache=True, error_model="numpy")
def _record_gap2(C, j, ax, ay, az, bx, by, bz, ha, hb):
    """A lower bound on the squared distance (m²) from the segment a..b to the triangle of
    the record at C[j], whose plane a and b lie ha and hb (m) over: at every point of the
    segment its height over the plane and how far its foot lies beyond the rectangle that
    holds the triangle, along the rectangle's axis and across it, bound its distance, so
    the least of each along the segment bound them all."""
    low = 0.0 if ha * hb <= 0.0 else min(abs(ha), abs(hb))
    ux, uy, uz = C[j + 7], C[j + 8], C[j + 9]
    wx, wy, wz = _across(C, j)
    ex, ey, ez = ax - C[j + 4], ay - C[j + 5], az - C[j + 6]
    fx, fy, fz = bx - C[j + 4], by - C[j + 5], bz - C[j + 6]
    along = _span_beyond(ex * ux + ey * uy + ez * uz, fx * ux + fy * uy + fz * uz, C[j + 10])
    across = _span_beyond(ex * wx + ey * wy + ez * wz, fx * wx + fy * wy + fz * wz, C[j + 11])
    return low * low + along * along + across * across


@njit(cache=True, error_model="numpy")
def _capsule_gap(C, at, ax, ay, az, bx, by, bz):
    """How far (m) the segment a..b strays from the segment whose ends are at C[at:at + 6]:
    the larger of its ends' distances (the distance to a segment is convex along a segment)."""
    return max(_segment_gap(C[at], C[at + 1], C[at + 2], C[at + 3], C[at + 4], C[at + 5], ax, ay, az),
               _segment_gap(C[at], C[at + 1], C[at + 2], C[at + 3], C[at + 4], C[at + 5], bx, by, bz))


@njit(cache=True, error_model="numpy")
def _patch(S, C, k, sl, ax, ay, az, bx, by, bz, need):
    """Where the patch of mesh k's hint slot sl is in C, and how many of its records (the
    first ones) may lie within `need` (m) of the segment a..b (geom frame; a point when
    a = b), gathered now if its capsule does not hold the query's, and -1; or (-1, 0, cut)
    when so many triangles are there that the box tree serves the query instead, from the
    nodes of the cut at C[cut] (-1: from the root, as when the shape keeps no patches:
    S.patch -1).

    A capsule gathered or found too full where the slot has slid since its last one is
    stretched ahead along that slide (`_ahead`): a finger's queries keep near the line it
    slides on, so a strip a few triangles wide serves as long a slide as a round capsule of
    hundreds (the too-full capsule: PATCH_KEEP beyond the query, stretched PATCH_MARGIN; the
    patch: PATCH_AHEAD)."""
    if S[k].patch < 0:
        return -1, 0, -1
    if not finite(abs(ax) + abs(ay) + abs(az) + abs(bx) + abs(by) + abs(bz) + need):
        # a query off the map (NaN, inf) never becomes a capsule: NaN compares false, and
        # every later query in the slot would take the patch for holding it
        return -1, 0, -1
    at = int(S[k].patch) + PATCH_WIDTH * sl
    gap = _capsule_gap(C, at, ax, ay, az, bx, by, bz)
    if gap + need > C[at + P_RADIUS]:
        f = at + P_FULL
        qx, qy, qz = bx - ax, by - ay, bz - az
        length = math.sqrt(qx * qx + qy * qy + qz * qz)
        inside = _capsule_gap(C, f, ax, ay, az, bx, by, bz) + need <= C[f + 6]
        # inside a capsule found too full, the tree serves the query, unless every query
        # found too full in it was much wider or longer than this one (a long sweep's), as
        # a smaller capsule may not be too full
        close = inside and need + 2.0 * PATCH_KEEP >= C[f + 8] and length + 2.0 * PATCH_KEEP >= C[f + 7]
        if close:
            # a finger held still asks about one place tick after tick (its frictionless
            # proxy's sweep along the planes it is pressed into): a patch only PATCH_CLOSE
            # wider than its queries, gathered once, serves them, unless even that is too full
            # (a fan of slivers). A sliding finger asks twice about one place at the turn of a
            # tick, and outgrows such a patch a tick later: where it has moved on from the
            # last one, the patch is stretched ahead along the slide
            key = S[k].key
            ex, ey, ez = ax - key[sl, 0], ay - key[sl, 1], az - key[sl, 2]  # from its last query
            if C[f + 9] != 0.0 or length > PATCH_STILL or ex * ex + ey * ey + ez * ez > PATCH_STILL * PATCH_STILL:
                return -1, 0, at + P_CUT
        # a patch gathered now is stretched ahead along the slot's slide; the query's end
        # strays `gap` off it
        cx, cy, cz, gap = _ahead(C, at, C[at + P_RADIUS] > 0.0, ax, ay, az, bx, by, bz, PATCH_AHEAD)
        if close:
            if not _gather(S, C, k, at, ax, ay, az, cx, cy, cz, need + gap + PATCH_CLOSE,
                           need + gap + 0.5 * PATCH_CLOSE):
                C[f + 9] = 1.0  # too full even that close: no more tries in this capsule
                return -1, 0, at + P_CUT
            return _read(C, at, gap, need)
        keep = PATCH_KEEP_AHEAD if cx != bx or cy != by or cz != bz else PATCH_KEEP
        if _gather(S, C, k, at, ax, ay, az, cx, cy, cz, need + gap + PATCH_MARGIN, need + gap + keep):
            return _read(C, at, gap, need)
        if inside:  # noted in it (its cut holds this capsule's triangles too)
            C[f + 7], C[f + 8] = min(C[f + 7], length), min(C[f + 8], need)
        else:
            # the capsule found too full, PATCH_KEEP beyond the query and stretched
            # PATCH_MARGIN ahead: its cut lies deeper in the tree than a round one's of
            # PATCH_MARGIN, and serves as long a slide
            cx, cy, cz, off = _ahead(C, f, C[f + 6] > 0.0, ax, ay, az, bx, by, bz, PATCH_MARGIN)
            C[f], C[f + 1], C[f + 2], C[f + 3], C[f + 4], C[f + 5] = ax, ay, az, cx, cy, cz
            C[f + 6], C[f + 7], C[f + 8], C[f + 9] = need + off + PATCH_KEEP, length, need, 0.0
            _cut(S, C, k, at + P_CUT, ax, ay, az, cx, cy, cz, need + off + PATCH_KEEP)
        return -1, 0, at + P_CUT
    return _read(C, at, gap, need)


@njit(cache=True, error_model="numpy")
def _read(C, at, gap, need):
    """(at, how many of the patch's first records to read, -1) for a query `need` (m) wide
    whose segment strays `gap` (m) from the patch's at C[at]."""
    m = int(C[at + P_COUNT])
    # a triangle within `need` of the query's segment is within gap + need of the patch's, so
    # its key is no more: the keys ascend, the first ones up to that are read
    limit = (gap + need) * (gap + need)
    lo, hi = 0, m
    while lo < hi:
        mid = (lo + hi) // 2
        if C[at + P_KEYS + mid] <= limit:
            lo = mid + 1
        else:
            hi = mid
    return at, lo, -1


@njit(cache=True, error_model="numpy")
def _ahead(C, at, kept, ax, ay, az, bx, by, bz, ahead):
    """The far end c of a capsule for the query a..b stretched `ahead` (m) along the way its
    slot travelled since the capsule at C[at] began (when `kept`, and it is 1 µm to 4 mm
    back: a finger sliding, not one held still or a slot taken over elsewhere), and how far
    (m) b lies off a..c; (b, 0) when not stretched."""
    tx, ty, tz = ax - C[at], ay - C[at + 1], az - C[at + 2]
    tt = math.sqrt(tx * tx + ty * ty + tz * tz)
    if not kept or not 1e-6 < tt < 4e-3:
        return bx, by, bz, 0.0
    s = ahead / tt
    cx, cy, cz = bx + s * tx, by + s * ty, bz + s * tz
    return cx, cy, cz, _segment_gap(ax, ay, az, cx, cy, cz, bx, by, bz)


@njit(cache=True, error_model="numpy")
def _cut(S, C, k, at, ax, ay, az, bx, by, bz, radius):
    """Fill the cut at C[at] with the nodes of mesh k's box tree, at the deepest level where at
    most CUT_NODES come within `radius` (m) of the segment a..b (geom frame; a leaf counted
    at every level below its own): every triangle within the capsule lies in one of them, so
    a walk for a query inside it starts there, not at the root (a million triangles make
    seventeen levels, and the sphere lies within reach of two or three nodes of each)."""
    tree, size, n, base = _tree(S, C, k)
    ux, uy, uz = bx - ax, by - ay, bz - az
    r2 = radius * radius
    level = np.empty(CUT_NODES, dtype=np.int64)
    below = np.empty(CUT_NODES, dtype=np.int64)
    level[0] = 1
    m = 1
    while True:
        q = 0
        deeper = True
        split = False
        for i in range(m):
            node = level[i]
            if node >= size:
                if q == CUT_NODES:
                    deeper = False
                    break
                below[q] = node
                q += 1
                continue
            for child in range(2 * node, 2 * node + 2):
                if _span_gap2(C, base + NODE_WIDTH * child, ax, ay, az, ux, uy, uz, 1.0) <= r2:
                    if q == CUT_NODES:
                        deeper = False
                        break
                    below[q] = child
                    q += 1
            split = True
            if not deeper:
                break
        if not deeper or not split or q == 0:
            break
        level, below = below, level
        m = q
    C[at] = m
    for i in range(m):
        C[at + 1 + i] = level[i]


@njit(cache=True, error_model="numpy")
def _gather(S, C, k, at, ax, ay, az, bx, by, bz, radius, least, room=FRONTIER):
    """Fill the patch at C[at] with the records of mesh k's triangles nearest the segment a..b
    (geom frame), out to `radius` (m) from it, or to less where more than PATCH_RECORDS lie
    that near: then those whose lower bound on the distance is least are kept, and the
    capsule's radius becomes the least bound of those left out, so the patch holds every
    triangle within it. Where that radius falls below `least` (m), the walk stops and the
    patch is left as it was: returns whether the patch was gathered.

    A walk of the box tree nearest node first (a heap of the nodes waiting, by their gap to
    the segment), leaving out the nodes and records whose bounds lie beyond the radius found
    so far: the first records kept are the nearest, the radius shrinks to theirs at once, and
    the walk ends at the first node beyond it (depth first, a walk that found the place too
    full read on until the radius came down: the 1M grid's slowest sliding ticks spent 119 µs
    gathering, now 75). At most `room` nodes wait (FRONTIER); one it has no room for bounds
    the radius."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    r2 = radius * radius
    tree, size, n, base = _tree(S, C, k)
    # a max-heap on minus the nodes' gaps (m²): the nearest on top
    waiting = np.empty(room)
    nodes = np.empty(room, dtype=np.int64)
    w = heap_offer(waiting, nodes, 0, room, -_span_gap2(C, base + NODE_WIDTH, ax, ay, az, ux, uy, uz, 1.0), 1)
    # a max-heap of the kept records' bounds (m²) and their rows in `kept`
    keys = np.empty(PATCH_RECORDS)
    rows = np.empty(PATCH_RECORDS, dtype=np.int64)
    kept = np.empty((PATCH_RECORDS, RECORD_WIDTH))
    m = 0
    while w > 0:
        gap, node, w = heap_pop(waiting, nodes, w)
        if -gap > r2:
            break  # every node waiting lies at least as far
        if node < size:
            for child in range(2 * node, 2 * node + 2):
                g2 = _span_gap2(C, base + NODE_WIDTH * child, ax, ay, az, ux, uy, uz, 1.0)
                if g2 > r2:
                    continue
                if w == room:
                    # no room to keep it waiting: the patch holds only what lies nearer
                    r2 = g2
                    if r2 < least * least:
                        return False
                    continue
                w = heap_offer(waiting, nodes, w, room, -g2, child)
            continue
        j0, j1 = _leaf_records(C, tree, node, size, n)
        for j in range(j0, j1, RECORD_WIDTH):
            ha = C[j] * ax + C[j + 1] * ay + C[j + 2] * az - C[j + 3]
            hb = C[j] * bx + C[j + 1] * by + C[j + 2] * bz - C[j + 3]
            if ha * ha > r2 and hb * hb > r2 and ha * hb > 0.0:
                continue
            g2 = _record_gap2(C, j, ax, ay, az, bx, by, bz, ha, hb)
            if g2 > r2:
                continue
            if m == PATCH_RECORDS:
                # full: the farthest kept (or this one) is left out, and the patch holds only
                # what lies nearer than it (a node it had no room for may have said less)
                out = g2 if g2 >= keys[0] else keys[0]
                if out < r2:
                    r2 = out
                if r2 < least * least:
                    return False
                if g2 >= keys[0]:
                    continue
            row = m if m < PATCH_RECORDS else rows[0]  # the row of the one it displaces
            m = heap_offer(keys, rows, m, PATCH_RECORDS, g2, row)
            for c in range(RECORD_WIDTH):
                kept[row, c] = C[j + c]
    order = np.argsort(keys[:m])
    for q in range(m):
        h = order[q]
        C[at + P_KEYS + q] = keys[h]
        o = at + P_RECORDS + RECORD_WIDTH * q
        for c in range(RECORD_WIDTH):
            C[o + c] = kept[rows[h], c]
    C[at], C[at + 1], C[at + 2] = ax, ay, az
    C[at + P_END], C[at + P_END + 1], C[at + P_END + 2] = bx, by, bz
    # just under the least bound left out, so that a triangle at exactly that bound is not
    # taken for held
    C[at + P_RADIUS] = math.sqrt(r2) * (1.0 - 1e-12) if m == PATCH_RECORDS or r2 < radius * radius else radius
    C[at + P_COUNT] = m
    return True


@njit(cache=True, error_model="numpy")
def _ball_holds(T, i, sx, sy, sz, radius, cx, cy, cz, rho):
    """Whether the ball of radius rho (m) about c lies inside a ball of `radius` (m) resting on
    row i's face on the side of unit normal s: c is within radius - rho of the face lifted
    by radius (`softproxy.compiled.ball`)."""
    room = radius - rho + BALL_SLACK
    if room < 0.0:
        return False
    return closest(T, i, cx - radius * sx, cy - radius * sy, cz - radius * sz)[0] <= room * room


@njit(cache=True, error_model="numpy")
def _ball_few(S, T, C, k, i, cx, cy, cz, rho):
    """The ball certificate of row i at c: how many triangles (listed in C[C_FEW:]) besides
    row i may come within rho (m) of c, and the unit normal of the side of row i that c is
    on; -1 when the ball of radius rho about c is not inside a ball resting on row i on that
    side, or the face has no ball list there."""
    radius = S[k].ball
    if radius <= 0.0:  # none built: the mesh is coarse enough for its patches
        return -1, 0.0, 0.0, 0.0
    side = 1.0
    nx, ny, nz = T[i, T_N], T[i, T_N + 1], T[i, T_N + 2]
    if nx * (cx - T[i, 0]) + ny * (cy - T[i, 1]) + nz * (cz - T[i, 2]) < 0.0:
        nx, ny, nz, side = -nx, -ny, -nz, -1.0
    m = face_few(T, C, i, side, 0, T_BALL)
    if m < 0 or not _ball_holds(T, i, nx, ny, nz, radius, cx, cy, cz, rho):
        return -1, nx, ny, nz
    return m, nx, ny, nz


@njit(cache=True, error_model="numpy")
def _nearest(S, T, C, k, sl, x, y, z):
    """(distance, qx, qy, qz, feature, row of T) of mesh k's triangle nearest p (geom frame),
    for a query of hint slot sl.

    From the hint (`_from_hint`): when the kept certificates hold at its nearest point (the
    tangent plane's, or a ball resting on the hint's face holding the ball of the hint's
    distance), the few triangles they name (none on a convex patch) are all that may be
    nearer; else the slot's patch when it holds the ball of the hint's distance, or the box
    tree walked nearest node first, leaving out every node farther than the best found (the
    hint's, to begin with)."""
    best2 = math.inf
    qx = qy = qz = 0.0
    bf = 0
    bi = int(S[k].hint)
    cut = -1
    if bi >= 0:
        best2, qx, qy, qz, bf, bi = _from_hint(S, T, C, k, bi, x, y, z)
        if best2 > 0.0:
            best = math.sqrt(best2)
            m = static_clear(S, T, C, k, bi, bf, (x - qx) / best, (y - qy) / best, (z - qz) / best, 2.0 * best)
            if m < 0:
                m = _ball_few(S, T, C, k, bi, x, y, z, best)[0]
            if m >= 0:
                hint = bi
                for j in range(m):
                    i = int(C[C_FEW + j])
                    if i != hint:
                        d2, rx, ry, rz, f = closest(T, i, x, y, z)
                        if d2 < best2:
                            best2, qx, qy, qz, bf, bi = d2, rx, ry, rz, f, i
                S[k].hint = bi
                return math.sqrt(best2), qx, qy, qz, bf, bi
        at, m, cut = _patch(S, C, k, sl, x, y, z, x, y, z, math.sqrt(best2))
        if at >= 0:
            j0 = at + P_RECORDS
            best2, qx, qy, qz, bf, bi = _nearest_run(T, C, j0, j0 + m * RECORD_WIDTH, x, y, z,
                                                     best2, qx, qy, qz, bf, bi)
            S[k].hint = bi
            return math.sqrt(best2), qx, qy, qz, bf, bi
    # the box tree, nearest node first; a node whose boxes lie farther than the best found
    # holds nothing nearer
    tree, size, n, base = _tree(S, C, k)
    nodes = np.empty(STACK, dtype=np.int64)
    gaps = np.empty(STACK)
    if cut >= 0:
        # from the cut, the nearest node on top
        top = 0
        for i in range(int(C[cut])):
            node = int(C[cut + 1 + i])
            g = _node_gap2(C, base + NODE_WIDTH * node, x, y, z)
            if g <= best2:
                top = _push_ordered(nodes, gaps, top, node, g)
    else:
        nodes[0], gaps[0] = 1, _node_gap2(C, base + NODE_WIDTH, x, y, z)
        top = 1
    while top > 0:
        top -= 1
        node, gap = nodes[top], gaps[top]
        if gap > best2:
            continue
        if node >= size:
            j0, j1 = _leaf_records(C, tree, node, size, n)
            best2, qx, qy, qz, bf, bi = _nearest_run(T, C, j0, j1, x, y, z, best2, qx, qy, qz, bf, bi)
            continue
        g0 = _node_gap2(C, base + NODE_WIDTH * 2 * node, x, y, z)
        g1 = _node_gap2(C, base + NODE_WIDTH * (2 * node + 1), x, y, z)
        # the nearer child on top of the stack, read first
        if g0 <= g1:
            if g1 <= best2:
                nodes[top], gaps[top] = 2 * node + 1, g1
                top += 1
            if g0 <= best2:
                nodes[top], gaps[top] = 2 * node, g0
                top += 1
        else:
            if g0 <= best2:
                nodes[top], gaps[top] = 2 * node, g0
                top += 1
            if g1 <= best2:
                nodes[top], gaps[top] = 2 * node + 1, g1
                top += 1
    S[k].hint = bi
    return math.sqrt(best2), qx, qy, qz, bf, bi


@njit(cache=True, error_model="numpy")
def _answer(S, T, k, x, y, z, best, qx, qy, qz, feature, i):
    """The signed distance (m) and outward normal at p (geom frame) from its nearest point q
    (at distance `best`) on `feature` of row i: negative behind the feature's pseudo-normal
    on a watertight mesh (the normal still points out), the pseudo-normal itself on the
    surface, shaded when asked."""
    ex, ey, ez = x - qx, y - qy, z - qz
    length = math.sqrt(ex * ex + ey * ey + ez * ez)
    # by its own length, not by `best`: within ~1 nm of the surface p - q carries the rounding
    # of p's coordinates (~1e-18 m), which would leave |n| off 1 by ~1e-9
    if best > 0.0 and length > 0.0:
        nx, ny, nz = ex / length, ey / length, ez / length
    else:
        nx, ny, nz = T[i, T_N], T[i, T_N + 1], T[i, T_N + 2]
    sign = 1.0
    if S[k].signed:
        c = T_PSEUDO + 3 * feature
        px, py, pz = T[i, c], T[i, c + 1], T[i, c + 2]
        if (x - qx) * px + (y - qy) * py + (z - qz) * pz < 0.0:
            sign = -1.0  # behind the nearest feature: inside; the normal still points out
            nx, ny, nz = -nx, -ny, -nz
        elif best == 0.0:
            n = math.sqrt(px * px + py * py + pz * pz)
            nx, ny, nz = px / n, py / n, pz / n
    if S[k].shading and feature < VERTEX_A:
        nx, ny, nz = _shade(T, i, qx, qy, qz, nx, ny, nz)
    return sign * best, nx, ny, nz


@njit(cache=True, error_model="numpy")
def _local_distance(S, T, C, k, sl, x, y, z):
    """Signed distance (m) and outward normal at p, geom frame, for a query of hint slot sl."""
    best, qx, qy, qz, feature, i = _nearest(S, T, C, k, sl, x, y, z)
    return _answer(S, T, k, x, y, z, best, qx, qy, qz, feature, i)


@njit(cache=True, error_model="numpy")
def _keep(S, k, sl, x, y, z, d, nx, ny, nz, row):
    """Keep the answer (signed distance (m), outward normal, row of T of the nearest point)
    at p (geom frame) as the newest of the two of mesh k's hint slot sl, the older dropped."""
    key = S[k].key
    for c in range(KEPT_WIDTH):
        key[sl, SLOT_KEPT + KEPT_WIDTH + c] = key[sl, SLOT_KEPT + c]
    c = SLOT_KEPT + KEPT_POINT
    key[sl, c], key[sl, c + 1], key[sl, c + 2] = x, y, z
    c = SLOT_KEPT + KEPT_NORMAL
    key[sl, c], key[sl, c + 1], key[sl, c + 2] = nx, ny, nz
    key[sl, SLOT_KEPT + KEPT_DISTANCE], key[sl, SLOT_KEPT + KEPT_ROW] = d, row


@njit(cache=True, error_model="numpy")
def _slot(S, k, x, y, z):
    """The hint slot of mesh k a query at p (geom frame) keeps its state in, and the hint it
    starts from: the slot whose last query was nearest p, if within SLOT_NEAR, else the one
    used longest ago; the hint of the nearest slot (a finger's own, when each finger keeps to
    its part of the mesh), or the mesh's last hint when no slot holds one. So fingers on one
    mesh do not take each other's hints and kept answers."""
    key = S[k].key
    best, best2 = -1, math.inf
    old, oldest = 0, math.inf
    for s in range(HINT_SLOTS):
        age = key[s, SLOT_AGE]
        if not age >= 0.0:
            age = -1.0  # never used
        if age < oldest:
            old, oldest = s, age
        ex, ey, ez = x - key[s, 0], y - key[s, 1], z - key[s, 2]
        d2 = ex * ex + ey * ey + ez * ez
        if d2 < best2 and key[s, SLOT_HINT] >= 0.0:
            best, best2 = s, d2
    if best < 0:
        return old, int(S[k].hint)
    hint = int(key[best, SLOT_HINT])
    return (best if best2 <= SLOT_NEAR * SLOT_NEAR else old), hint


@njit(cache=True, error_model="numpy")
def _touch(S, k, sl, x, y, z, hint):
    """Slot sl of mesh k was used last, by a query at p (geom frame) that ended on row `hint`."""
    key = S[k].key
    newest = 0.0
    for s in range(HINT_SLOTS):
        if key[s, SLOT_AGE] > newest:
            newest = key[s, SLOT_AGE]
    key[sl, 0], key[sl, 1], key[sl, 2] = x, y, z
    key[sl, SLOT_HINT] = hint
    key[sl, SLOT_AGE] = newest + 1.0


@njit(cache=True, error_model="numpy")
def _to_geom(xmat, g, x, y, z):
    """The world vector (x, y, z) in geom g's frame (MuJoCo's geom_xmat, row-major)."""
    return (xmat[g, 0] * x + xmat[g, 3] * y + xmat[g, 6] * z,
            xmat[g, 1] * x + xmat[g, 4] * y + xmat[g, 7] * z,
            xmat[g, 2] * x + xmat[g, 5] * y + xmat[g, 8] * z)


@njit(cache=True, error_model="numpy")
def _to_world(xmat, g, x, y, z):
    """The geom-frame vector (x, y, z) of geom g in the world frame."""
    return (xmat[g, 0] * x + xmat[g, 1] * y + xmat[g, 2] * z,
            xmat[g, 3] * x + xmat[g, 4] * y + xmat[g, 5] * z,
            xmat[g, 6] * x + xmat[g, 7] * y + xmat[g, 8] * z)


@njit(cache=True, error_model="numpy")
def mesh_distance(S, T, C, xpos, xmat, k, x, y, z):
    """Signed distance (m, < 0 inside; unsigned on an open mesh) from mesh k's triangles and
    the outward unit normal, world frame; S[k].feature is then the row of T of the nearest
    point. Each hint slot (`_slot`) keeps its last two answers, keyed by the point in the
    geom frame, where the triangles never move (the god-object asks again about the point it
    holds, about the point it moved to, and about a sweep's start whose nearest point the
    sweep proved)."""
    g = int(S[k].geom)
    lx, ly, lz = _to_geom(xmat, g, x - xpos[g, 0], y - xpos[g, 1], z - xpos[g, 2])
    sl, hint = _slot(S, k, lx, ly, lz)
    key = S[k].key
    a, b = SLOT_KEPT, SLOT_KEPT + KEPT_WIDTH
    if not (lx == key[sl, a] and ly == key[sl, a + 1] and lz == key[sl, a + 2]):
        if lx == key[sl, b] and ly == key[sl, b + 1] and lz == key[sl, b + 2]:
            for c in range(KEPT_WIDTH):  # the older one: swap the two
                key[sl, a + c], key[sl, b + c] = key[sl, b + c], key[sl, a + c]
        else:
            S[k].hint = hint
            d, nx, ny, nz = _local_distance(S, T, C, k, sl, lx, ly, lz)
            _keep(S, k, sl, lx, ly, lz, d, nx, ny, nz, S[k].hint)
            _touch(S, k, sl, lx, ly, lz, S[k].hint)
    S[k].feature = int(key[sl, a + KEPT_ROW])
    n = a + KEPT_NORMAL
    nx, ny, nz = _to_world(xmat, g, key[sl, n], key[sl, n + 1], key[sl, n + 2])
    return key[sl, a + KEPT_DISTANCE], nx, ny, nz


@njit(cache=True, error_model="numpy")
def mesh_triangle_distance(T, xpos, xmat, g, row, x, y, z):
    """Unsigned distance (m) from the world point p to one triangle (row of T) of the mesh of
    geom g, and the unit direction (world) from its nearest point to p: whether the feature
    a constraint plane came from is still under the proxy, and its tangent plane there."""
    lx, ly, lz = _to_geom(xmat, g, x - xpos[g, 0], y - xpos[g, 1], z - xpos[g, 2])
    d2, qx, qy, qz, _ = closest(T, row, lx, ly, lz)
    d = math.sqrt(d2)
    if d == 0.0:  # on the triangle: its normal
        nx, ny, nz = T[row, T_N], T[row, T_N + 1], T[row, T_N + 2]
    else:
        nx, ny, nz = (lx - qx) / d, (ly - qy) / d, (lz - qz) / d
    nx, ny, nz = _to_world(xmat, g, nx, ny, nz)
    return d, nx, ny, nz


@njit(cache=True, error_model="numpy")
def mesh_walk_distance(S, T, C, xpos, xmat, k, row, x, y, z):
    """Distance (m, unsigned) and normal (world, from the triangle toward p) at the world
    point p from the triangle nearest p found by walking from triangle `row` (`_from_hint`:
    across an edge, round a vertex), and that triangle's row: the mesh's distance as seen
    from one place on it, no certificate, patch or tree (at a million triangles each of
    those is a walk of the tree). Whether a plane's surface goes on past its own triangle
    (`_move_once`): a sweep still guards whatever plane the answer makes.

    Unsigned: a walk may end on a nearest triangle of its own across the mesh, and p behind
    that one is not inside (a point proxy 4 cm from a sphere's far side was taken for
    resting on it, and floated 4 mm off the sphere with the device inside)."""
    g = int(S[k].geom)
    lx, ly, lz = _to_geom(xmat, g, x - xpos[g, 0], y - xpos[g, 1], z - xpos[g, 2])
    d2, qx, qy, qz, f, i = _from_hint(S, T, C, k, row, lx, ly, lz)
    d, nx, ny, nz = _answer(S, T, k, lx, ly, lz, math.sqrt(d2), qx, qy, qz, f, i)
    if d < 0.0:
        d, nx, ny, nz = -d, -nx, -ny, -nz
    nx, ny, nz = _to_world(xmat, g, nx, ny, nz)
    return d, nx, ny, nz, i


@njit(cache=True, error_model="numpy")
def _record_top(C, j, nx, ny, nz):
    """The highest point (m, along unit n) of the rectangle of the record at C[j]."""
    ux, uy, uz = C[j + 7], C[j + 8], C[j + 9]
    wx, wy, wz = _across(C, j)
    return (nx * C[j + 4] + ny * C[j + 5] + nz * C[j + 6] + C[j + 10] * abs(nx * ux + ny * uy + nz * uz)
            + C[j + 11] * abs(nx * wx + ny * wy + nz * wz))


@njit(cache=True, error_model="numpy")
def _node_top(C, at, nx, ny, nz):
    """The highest point (m, along unit n) of the oriented box of the node at C[at]."""
    top = 0.0
    for a in range(3):
        c = at + N_AXES + 3 * a
        k = nx * C[c] + ny * C[c + 1] + nz * C[c + 2]
        top += max(k * C[at + N_EXT + a], k * C[at + N_EXT + 3 + a])
    return top


@njit(cache=True, error_model="numpy")
def _sweep_run(T, C, j0, j1, stamp, sweep, slab, reach, length,
               best_lam, bnx, bny, bnz, bi, far2, cull, pnx, pny, pnz, poff):
    """Sweep the sphere against the triangles of the records C[j0:j1] not read yet this scan;
    returns the earliest hit so far (lam, normal, row of T; -1 for none) and the new far².
    Only the part of the segment before the earliest hit so far (lam < best_lam) is tested;
    when `cull`, not the triangles whose rectangle lies wholly behind the plane p·x = poff
    (a tangent plane the sphere stays r above all the way)."""
    ax, ay, az, ux, uy, uz, r, _, _ = sweep
    bx, by, bz = ax + best_lam * ux, ay + best_lam * uy, az + best_lam * uz  # where that part ends
    for j in range(j0, j1, RECORD_WIDTH):
        # a segment that stays more than r off the plane, on one side, never reaches it
        h0 = C[j] * ax + C[j + 1] * ay + C[j + 2] * az - C[j + 3]
        hd = C[j] * ux + C[j + 1] * uy + C[j + 2] * uz
        h1 = h0 + best_lam * hd
        if (h0 > slab and h1 > slab) or (h0 < -slab and h1 < -slab):
            continue
        # nor one that stays r off it and does not touch the triangle at the start (sliding
        # over a flat patch): the rectangle in its plane that holds it bounds its distance
        if (h0 >= r and h1 >= r) or (h0 <= -r and h1 <= -r):
            beyond2 = _beyond2(C, j, ax - C[j + 4], ay - C[j + 5], az - C[j + 6])
            if beyond2 > 0.0 and h0 * h0 + beyond2 > slab * slab:
                continue
        # nor one that stays more than r off the rectangle in its plane that holds it along
        # the part of the segment before the earliest touch found
        if _record_gap2(C, j, ax, ay, az, bx, by, bz, h0, h1) > slab * slab:
            continue
        if cull and _record_top(C, j, pnx, pny, pnz) <= poff:
            continue
        i = int(C[j + R_ROW])
        if C[C_STAMPS + i] == stamp:
            continue
        C[C_STAMPS + i] = stamp
        lam, mx, my, mz, _ = _sweep_triangle(T, i, sweep, far2)
        if lam >= 0.0 and lam < best_lam:
            best_lam, bnx, bny, bnz, bi = lam, mx, my, mz, i
            far = reach + best_lam * length  # only the segment before this hit matters now
            far2 = far * far
            bx, by, bz = ax + best_lam * ux, ay + best_lam * uy, az + best_lam * uz
    return best_lam, bnx, bny, bnz, bi, far2


@njit(cache=True, error_model="numpy")
def _hit(S, T, k, xmat, g, tri, lam, nx, ny, nz, sweep):
    """The touch of row `tri` at fraction lam: its normal (geom frame) shaded when asked (while
    the shaded one still opposes the motion) and turned into the world frame; the triangle
    becomes the hint and the answer's feature."""
    ax, ay, az, ux, uy, uz, r, _, graze = sweep
    S[k].hint = S[k].feature = tri
    if S[k].shading:
        qx, qy, qz = ax + lam * ux - r * nx, ay + lam * uy - r * ny, az + lam * uz - r * nz
        sx, sy, sz = _shade(T, tri, qx, qy, qz, nx, ny, nz)
        if sx * ux + sy * uy + sz * uz < -graze:  # still against the motion: use it
            nx, ny, nz = sx, sy, sz
    nx, ny, nz = _to_world(xmat, g, nx, ny, nz)
    return lam, nx, ny, nz


@njit(cache=True, error_model="numpy")
def _few_run(T, C, m, hint, sd2, sqx, sqy, sqz, sf, sweep, far2, lam, mx, my, mz):
    """The earliest touch (lam, normal, row; row -1 for none) among the m triangles in
    C[C_FEW:] and the hint's own (lam < 0: none); when sd2 >= 0, also the start's nearest
    point among them and the hint's (sd2, q, feature sf): (…, sd2, q, sf, its row)."""
    ax, ay, az, ux, uy, uz, r, _, _ = sweep
    best_lam, bi = (lam, hint) if lam >= 0.0 else (1.0, -1)
    si = hint
    slab = r + CONTACT_TOL + 1e-12
    for j in range(m):
        i = int(C[C_FEW + j])
        if i == hint:
            continue
        if sd2 >= 0.0:  # before the slab test: a triangle the segment never reaches may still be nearest
            d2, qx, qy, qz, f = closest(T, i, ax, ay, az)
            if d2 < sd2:
                sd2, sqx, sqy, sqz, sf, si = d2, qx, qy, qz, f, i
        nx, ny, nz = T[i, T_N], T[i, T_N + 1], T[i, T_N + 2]
        h0 = nx * (ax - T[i, 0]) + ny * (ay - T[i, 1]) + nz * (az - T[i, 2])
        h1 = h0 + nx * ux + ny * uy + nz * uz
        if (h0 > slab and h1 > slab) or (h0 < -slab and h1 < -slab):
            continue
        hit, hx, hy, hz, _ = _sweep_triangle(T, i, sweep, far2)
        if hit >= 0.0 and hit < best_lam:
            best_lam, mx, my, mz, bi = hit, hx, hy, hz, i
    return best_lam, mx, my, mz, bi, sd2, sqx, sqy, sqz, sf, si


@njit(cache=True, error_model="numpy")
def _few_answer(S, T, k, xmat, sl, g, best_lam, mx, my, mz, bi, sd2, sqx, sqy, sqz, sf, si, sweep):
    """`mesh_sweep`'s answer from `_few_run`'s: the touch (`_hit`), and the start's nearest
    point kept for `mesh_distance` when it was asked for (sd2 >= 0)."""
    ax, ay, az = sweep.ax, sweep.ay, sweep.az
    if sd2 >= 0.0:
        d, nx, ny, nz = _answer(S, T, k, ax, ay, az, math.sqrt(sd2), sqx, sqy, sqz, sf, si)
        _keep(S, k, sl, ax, ay, az, d, nx, ny, nz, si)
        S[k].hint = si
    if bi < 0:
        return (-1.0, 0.0, 0.0, 0.0)
    return _hit(S, T, k, xmat, g, bi, best_lam, mx, my, mz, sweep)


@njit(cache=True, error_model="numpy")
def _sweep_few(S, T, C, xmat, k, sl, g, m, hint, sd2, sqx, sqy, sqz, sf, sweep, far2, lam, mx, my, mz):
    """The end of `mesh_sweep` when a certificate left the m triangles in C[C_FEW:] to read
    besides the hint: the earliest touch among them and the hint's own (lam < 0: none). When
    sd2 >= 0 the start's nearest point is the hint's (sd2, q, feature sf) or one of theirs,
    and its answer is kept for `mesh_distance`."""
    out = _few_run(T, C, m, hint, sd2, sqx, sqy, sqz, sf, sweep, far2, lam, mx, my, mz)
    return _few_answer(S, T, k, xmat, sl, g, *out, sweep)


@njit(cache=True, error_model="numpy")
def _sweep_ball(S, T, C, xmat, k, sl, g, hint, d2, qx, qy, qz, feature, sweep, far2):
    """`mesh_sweep` by the ball certificate of the start's nearest row `hint` (at d2, q,
    `feature`), for a sweep not moving into it: the earliest touch among its ball list, when
    the sphere (and the start's ball of radius its distance) lies inside a ball resting on
    the hint's face at the start and at that touch (or the end), and so all the way (the
    test is convex along the segment). (True, answer) or (False, …) when it does not hold."""
    ax, ay, az, ux, uy, uz, r, _, _ = sweep
    reach = r + CONTACT_TOL
    m, sx, sy, sz = _ball_few(S, T, C, k, hint, ax, ay, az, max(reach, math.sqrt(d2)))
    if m < 0:
        return False, (-1.0, 0.0, 0.0, 0.0)
    out = _few_run(T, C, m, hint, d2, qx, qy, qz, feature, sweep, far2,
                   -1.0, 0.0, 0.0, 0.0)
    lam = out[0] if out[4] >= 0 else 1.0
    if not _ball_holds(T, hint, sx, sy, sz, S[k].ball, ax + lam * ux, ay + lam * uy, az + lam * uz, reach):
        return False, (-1.0, 0.0, 0.0, 0.0)
    return True, _few_answer(S, T, k, xmat, sl, g, *out, sweep)


@njit(cache=True, error_model="numpy")
def _sweep_certified(S, T, C, xmat, k, sl, g, hint, d2, qx, qy, qz, feature, nx, ny, nz, span, sweep, far2):
    """`mesh_sweep` of a sphere staying r above the tangent plane (normal n) at the start's
    nearest point q on row `hint` (at d2, `feature`), by the kept certificates: the triangles
    rising above that plane within `span` (m), or where too many do, a ball resting on the
    hint's face that holds the sphere all the way (a concave patch finer than the proxy: only
    the neighbours rising into that ball). (True, answer) or (False, …) when neither holds."""
    m = static_clear(S, T, C, k, hint, feature, nx, ny, nz, span)
    if m >= 0:
        return True, _sweep_few(S, T, C, xmat, k, sl, g, m, hint, d2, qx, qy, qz, feature, sweep, far2, -1.0, 0.0, 0.0, 0.0)
    return _sweep_ball(S, T, C, xmat, k, sl, g, hint, d2, qx, qy, qz, feature, sweep, far2)


@njit(cache=True, error_model="numpy")
def mesh_sweep(S, T, C, xpos, xmat, k, x0, y0, z0, dx, dy, dz, r):
    """First touch (fraction in [0, 1), world normal) of a sphere of radius r (m) moving from
    x0 by d (m) into mesh k's triangles; (-1.0, 0.0, 0.0, 0.0) when none (`_sweep`), from
    and into the hint slot of its start (`_slot`). After a touch S[k].feature is the row of T
    touched (`_hit`)."""
    g = int(S[k].geom)
    ax, ay, az = _to_geom(xmat, g, x0 - xpos[g, 0], y0 - xpos[g, 1], z0 - xpos[g, 2])
    sl, hint = _slot(S, k, ax, ay, az)
    S[k].hint = hint
    out = _sweep(S, T, C, xmat, k, sl, ax, ay, az, dx, dy, dz, r)
    _touch(S, k, sl, ax, ay, az, S[k].hint)
    return out


@njit(cache=True, error_model="numpy")
def _sweep(S, T, C, xmat, k, sl, ax, ay, az, dx, dy, dz, r):
    """First touch (fraction in [0, 1), world normal) of a sphere of radius r (m) moving from
    a (geom frame) by d (m, world) into mesh k's triangles; (-1.0, 0.0, 0.0, 0.0) when none.

    From the hint (`_from_hint`): touching it and pressed into it, the
    touch is at once; touching it and moving along or away, or touching it on the way, or
    near it and staying above its tangent plane, the kept certificates may leave only a few
    triangles to sweep (and prove the start's nearest point, kept for `mesh_distance`): the
    tangent plane's, or where too many rise above it, a ball resting on the hint's face that
    holds the sphere from start to touch (`_sweep_certified`); else the box tree is walked:
    the nodes whose boxes, grown by the reach, the segment enters before the earliest touch
    found, earliest first (and, when it stays r above the hint's tangent plane but too many
    triangles rise above that plane for a certificate to list, not the nodes and records
    wholly behind it)."""
    dd = dx * dx + dy * dy + dz * dz
    if dd == 0.0:
        return (-1.0, 0.0, 0.0, 0.0)
    if r < POINT_RADIUS:
        r = POINT_RADIUS
    length = math.sqrt(dd)
    graze = GRAZE * length
    reach = r + CONTACT_TOL
    far = reach + length
    far2 = far * far
    g = int(S[k].geom)
    ux, uy, uz = _to_geom(xmat, g, dx, dy, dz)
    sweep = Sweep(ax, ay, az, ux, uy, uz, r, dd, graze)
    best_lam, bnx, bny, bnz, bi = 1.0, 0.0, 0.0, 0.0, -1
    cull, pnx, pny, pnz, poff = False, 0.0, 0.0, 0.0, 0.0
    hint0 = int(S[k].hint)
    if hint0 >= 0:
        d2, qx, qy, qz, feature, hint = _from_hint(S, T, C, k, hint0, ax, ay, az)
        if d2 <= reach * reach and d2 > 1e-24:
            dist = math.sqrt(d2)
            nx, ny, nz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
            into = nx * ux + ny * uy + nz * uz
            if _pressed(dist, into, r, graze):  # pressed into the one it touches: nothing comes earlier
                return _hit(S, T, k, xmat, g, hint, 0.0, nx, ny, nz, sweep)
            if dist >= r - CONTACT_TOL and dist + into >= r - CONTACT_TOL:
                # moving along or away, r above the hint's tangent plane from start to end (a
                # sphere that dips below it may overlap a triangle behind it): only the
                # triangles reaching above it can be touched
                held, out = _sweep_certified(S, T, C, xmat, k, sl, g, hint, d2, qx, qy, qz, feature, nx, ny, nz,
                                             2.0 * reach + length, sweep, far2)
                if held:
                    return out
                # too many reach above it to list (a neighbour's wall): the walk below still
                # leaves out what lies wholly behind it (a convex rim of 10⁴ slivers)
                cull = True
                pnx, pny, pnz, poff = nx, ny, nz, nx * qx + ny * qy + nz * qz + ABOVE_TOL
        else:
            lam, mx, my, mz, f = _sweep_triangle(T, hint, sweep, far2)
            if lam >= 0.0 and EDGE_AB <= f < VERTEX_A:
                # touched on an edge: the neighbour across it may be touched first
                other = int(T[hint, T_ADJ + f - EDGE_AB])
                if other >= 0:
                    lam2, nx, ny, nz, f2 = _sweep_triangle(T, other, sweep, far2)
                    if lam2 >= 0.0 and lam2 < lam:
                        lam, mx, my, mz, f, hint = lam2, nx, ny, nz, f2, other
            elif lam > 0.0 and f >= VERTEX_A:
                # touched on a vertex: a fan triangle on an edge rising above the tangent
                # plane there holds a nearer point, so it was touched first
                sx, sy, sz = ax + lam * ux, ay + lam * uy, az + lam * uz
                c2, cx, cy, cz, cf = closest(T, hint, sx, sy, sz)
                if cf >= VERTEX_A:
                    walked = _walk(S, T, C, k, hint, c2, cx, cy, cz, cf, sx, sy, sz)[5]
                    if walked != hint:
                        lam2, nx, ny, nz, f2 = _sweep_triangle(T, walked, sweep, far2)
                        if lam2 >= 0.0 and lam2 < lam:
                            lam, mx, my, mz, f, hint = lam2, nx, ny, nz, f2, walked
            if lam >= 0.0:
                if lam == 0.0:
                    return _hit(S, T, k, xmat, g, hint, 0.0, mx, my, mz, sweep)
                # up to the touch the sphere stays r above the tangent plane there
                m = static_clear(S, T, C, k, hint, f, mx, my, mz, 2.0 * reach + lam * length)
                if m >= 0:
                    return _sweep_few(S, T, C, xmat, k, sl, g, m, hint, -1.0, 0.0, 0.0, 0.0, 0, sweep, far2, lam, mx, my, mz)
                best_lam, bnx, bny, bnz, bi = lam, mx, my, mz, hint
                far = reach + lam * length  # only the segment before this touch matters now
                far2 = far * far
            elif d2 > 1e-24 and d2 <= far2:
                # near the hint, not touching it and not moving into it (lifted off a curved
                # mesh): staying r above the tangent plane at q, only the few can be touched
                dist = math.sqrt(d2)
                nx, ny, nz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
                if dist + nx * ux + ny * uy + nz * uz >= r - CONTACT_TOL:
                    held, out = _sweep_certified(S, T, C, xmat, k, sl, g, hint, d2, qx, qy, qz, feature, nx, ny, nz,
                                                 dist + reach + length, sweep, far2)
                    if held:
                        return out
    slab = reach + 1e-12
    C[C_STAMP] += 1.0
    stamp = C[C_STAMP]
    if bi >= 0:
        C[C_STAMPS + bi] = stamp
    # the slot's patch, when it holds every triangle within the slab of the segment before
    # the earliest touch found (a finger pressed into a concave patch sweeps ten times a tick
    # about one point)
    at, m, cut = _patch(S, C, k, sl, ax, ay, az, ax + best_lam * ux, ay + best_lam * uy, az + best_lam * uz, slab)
    if at >= 0:
        j0 = at + P_RECORDS
        best_lam, bnx, bny, bnz, bi, far2 = _sweep_run(
            T, C, j0, j0 + m * RECORD_WIDTH, stamp, sweep, slab,
            reach, length, best_lam, bnx, bny, bnz, bi, far2, cull, pnx, pny, pnz, poff)
        if bi < 0:
            return (-1.0, 0.0, 0.0, 0.0)
        return _hit(S, T, k, xmat, g, bi, best_lam, bnx, bny, bnz, sweep)
    # the box tree: the nodes the segment enters, grown by the reach, earliest entry first;
    # a node entered after the earliest touch found holds no earlier one
    slack = 2.0 * TREE_MARGIN * (1.0 + S[k].rbound)
    tree, size, n, base = _tree(S, C, k)
    nodes = np.empty(STACK, dtype=np.int64)
    entries = np.empty(STACK)
    asked = np.empty(STACK)  # the earliest touch when the node's entry was found
    if cut >= 0:
        # from the cut, the earliest entered on top
        top = 0
        for i in range(int(C[cut])):
            node = int(C[cut + 1 + i])
            e = _node_entry(C, base + NODE_WIDTH * node, ax, ay, az, ux, uy, uz, length, r, slab, slack, best_lam)
            if e <= best_lam:
                top = _push_ordered(nodes, entries, top, node, e)
        asked[:top] = best_lam
    else:
        nodes[0] = 1
        entries[0] = _node_entry(C, base + NODE_WIDTH, ax, ay, az, ux, uy, uz, length, r, slab, slack, best_lam)
        asked[0] = best_lam
        top = 1
    while top > 0:
        top -= 1
        node, entry = nodes[top], entries[top]
        if entry > best_lam:
            continue
        if best_lam < asked[top]:  # a touch found since: the segment before it is shorter
            again = _node_entry(C, base + NODE_WIDTH * node, ax, ay, az, ux, uy, uz, length, r, slab, slack, best_lam)
            if again > best_lam:
                continue
        if cull and _node_top(C, base + NODE_WIDTH * node, pnx, pny, pnz) <= poff:
            continue
        if node >= size:
            j0, j1 = _leaf_records(C, tree, node, size, n)
            best_lam, bnx, bny, bnz, bi, far2 = _sweep_run(
                T, C, j0, j1, stamp, sweep, slab, reach, length,
                best_lam, bnx, bny, bnz, bi, far2, cull, pnx, pny, pnz, poff)
            continue
        at = base + NODE_WIDTH * 2 * node
        e0 = _node_entry(C, at, ax, ay, az, ux, uy, uz, length, r, slab, slack, best_lam)
        e1 = _node_entry(C, at + NODE_WIDTH, ax, ay, az, ux, uy, uz, length, r, slab, slack, best_lam)
        if e0 <= e1:  # the earlier entered on top of the stack, read first
            if e1 <= best_lam:
                nodes[top], entries[top], asked[top] = 2 * node + 1, e1, best_lam
                top += 1
            if e0 <= best_lam:
                nodes[top], entries[top], asked[top] = 2 * node, e0, best_lam
                top += 1
        else:
            if e0 <= best_lam:
                nodes[top], entries[top], asked[top] = 2 * node, e0, best_lam
                top += 1
            if e1 <= best_lam:
                nodes[top], entries[top], asked[top] = 2 * node + 1, e1, best_lam
                top += 1
    if bi < 0:
        return (-1.0, 0.0, 0.0, 0.0)
    return _hit(S, T, k, xmat, g, bi, best_lam, bnx, bny, bnz, sweep)
