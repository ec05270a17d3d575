"""Triangle-mesh contact for the god-object: the mesh's own triangles, not its convex hull.

MuJoCo collides a mesh geom through its convex hull, so a finger pressed into a bowl would
stop on the plane of the rim. These kernels answer the god-object's queries on the triangles
themselves, in the geom frame MuJoCo compiled them into (`model.mesh_vert` is expressed in
the frame of `geom_xpos` / `geom_xmat`), from two arrays that `mesh_tables` packs for every
mesh of a world out of what `softproxy.mesh.MeshShape` built at load (`softproxy.mesh_tables`): T, one row per
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
  (CONTACT_TOL, `pressed`), so sliding along a tangent plane that a nearly parallel
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


from softproxy.compiled.box_tree import (
    TREE_MARGIN, leaf_records, node_entry, node_gap2, node_top, record_beyond2, record_gap2, record_top, tree_of,
)
from softproxy.compiled.certificate import ABOVE_TOL, BALL_SLACK, face_few, static_clear
from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (
    C_FEW, C_STAMP, C_STAMPS, EDGE_AB, FACE, HINT_SLOTS, KEPT_DISTANCE, KEPT_NORMAL, KEPT_POINT, KEPT_ROW,
    KEPT_WIDTH, NODE_WIDTH, P_RECORDS, RECORD_WIDTH, R_ROW, SLOT_AGE, SLOT_HINT, SLOT_KEPT, T_ADJ, T_BALL, T_N,
    T_PSEUDO, T_TV, VERTEX_A, VERTEX_WIDTH, V_AXIS, V_COS, V_RING,
)
from softproxy.compiled.patch import slot_patch
from softproxy.compiled.tolerances import CONTACT_TOL, GRAZE
from softproxy.compiled.tree_walk import best_so_far, depth_first, depth_scratch
from softproxy.compiled.triangle import Sweep, closest, pressed, shade, sweep_triangle
from softproxy.compiled.vector import point_in_geom_frame, to_geom_frame, to_world_frame

POINT_RADIUS = 1e-8
"""A point proxy (r = 0) is swept as a sphere this big (m). On an edge or a vertex the direction
from the nearest point to a point lying on it is rounding noise, so whether it moves into the
mesh is not decidable; 10 nm gives it a direction and is far below the 1 µm promise."""
SLOT_NEAR = 0.0005
"""A query within this distance (m) of a hint slot's last query keeps to that slot (`_slot`):
a finger's proxy and its frictionless proxy, a millimetre apart, keep a patch each."""
WALK_STEPS = 8
"""Most steps from a vertex to a nearer triangle around it before a query reads the fan."""


@kernel
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


@kernel
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


Nearest = namedtuple("Nearest", "T C tree n base x y z")
"""A nearest-triangle query on mesh tables T, C: mesh k's tree (`tree_of`: where it begins in
C, its number of triangles, its nodes' base) and the point p (geom frame, m). Its walk's
state: (best2 (m²), q, feature, row of T) of the nearest found so far."""


@kernel
def _nearest_run(q, j0, j1, s):
    """The nearest so far to p among the triangles of the records C[j0:j1] and the one found
    before (the state s: best2 (m²), q, feature bf, row bi; bi itself is not read again)."""
    T, C, x, y, z = q.T, q.C, q.x, q.y, q.z
    best2, qx, qy, qz, bf, bi = s
    best = math.sqrt(best2)
    for j in range(j0, j1, RECORD_WIDTH):
        h = C[j] * x + C[j + 1] * y + C[j + 2] * z - C[j + 3]
        if h >= best or -h >= best:
            continue  # its plane is already farther than the best
        # or the rectangle in its plane that holds it: the height over the plane and how far
        # the foot lies beyond the rectangle bound it
        if h * h + record_beyond2(C, j, x - C[j + 4], y - C[j + 5], z - C[j + 6]) >= best2:
            continue
        i = int(C[j + R_ROW])
        if i == bi:
            continue
        d2, rx, ry, rz, f = closest(T, i, x, y, z)
        if d2 < best2:
            best2, qx, qy, qz, bf, bi = d2, rx, ry, rz, f, i
            best = math.sqrt(d2)
    return best2, qx, qy, qz, bf, bi


@kernel(inline="always")
def _nearest_bound(q, s, node):
    """A node's bound: the squared gap (m²) from p to its boxes."""
    return node_gap2(q.C, q.base + NODE_WIDTH * node, q.x, q.y, q.z)


@kernel(inline="always")
def _nearest_leaf(q, s, leaf):
    """The nearest so far after the triangles of a leaf."""
    j0, j1 = leaf_records(q.C, q.tree, leaf, q.n)
    return _nearest_run(q, j0, j1, s)


_nearest_walk = depth_first(_nearest_bound, _nearest_leaf, limit=best_so_far)
"""The box tree walked nearest node first, leaving out every node farther than the best found."""


@kernel
def _ball_holds(T, i, sx, sy, sz, radius, cx, cy, cz, rho):
    """Whether the ball of radius rho (m) about c lies inside a ball of `radius` (m) resting on
    row i's face on the side of unit normal s: c is within radius - rho of the face lifted
    by radius (`softproxy.mesh_balls`)."""
    room = radius - rho + BALL_SLACK
    if room < 0.0:
        return False
    return closest(T, i, cx - radius * sx, cy - radius * sy, cz - radius * sz)[0] <= room * room


@kernel
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


@kernel
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
    at, m, cut = -1, 0, -1
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
        at, m, cut = slot_patch(S, C, k, sl, x, y, z, x, y, z, math.sqrt(best2))
    tree, size, n, base = tree_of(S, C, k)
    q = Nearest(T, C, tree, n, base, x, y, z)
    if at >= 0:
        j0 = at + P_RECORDS
        best2, qx, qy, qz, bf, bi = _nearest_run(q, j0, j0 + m * RECORD_WIDTH, (best2, qx, qy, qz, bf, bi))
        S[k].hint = bi
        return math.sqrt(best2), qx, qy, qz, bf, bi
    # the box tree, nearest node first (from the cut, when the slot noted one); a node whose
    # boxes lie farther than the best found holds nothing nearer
    s, _ = _nearest_walk(size, C[cut:] if cut >= 0 else C[:0], q, (best2, qx, qy, qz, bf, bi), depth_scratch())
    best2, qx, qy, qz, bf, bi = s
    S[k].hint = bi
    return math.sqrt(best2), qx, qy, qz, bf, bi


@kernel
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
        nx, ny, nz = shade(T, i, qx, qy, qz, nx, ny, nz)
    return sign * best, nx, ny, nz


@kernel
def _local_distance(S, T, C, k, sl, x, y, z):
    """Signed distance (m) and outward normal at p, geom frame, for a query of hint slot sl."""
    best, qx, qy, qz, feature, i = _nearest(S, T, C, k, sl, x, y, z)
    return _answer(S, T, k, x, y, z, best, qx, qy, qz, feature, i)


@kernel
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


@kernel
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


@kernel
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


@kernel
def mesh_distance(sh, k, x, y, z):
    """Signed distance (m, < 0 inside; unsigned on an open mesh) from mesh k's triangles and
    the outward unit normal, world frame; S[k].feature is then the row of T of the nearest
    point. Each hint slot (`_slot`) keeps its last two answers, keyed by the point in the
    geom frame, where the triangles never move (the god-object asks again about the point it
    holds, about the point it moved to, and about a sweep's start whose nearest point the
    sweep proved)."""
    S, T, C, xpos, xmat = sh.S, sh.T, sh.C, sh.xpos, sh.xmat
    g = int(S[k].geom)
    lx, ly, lz = point_in_geom_frame(xpos, xmat, g, x, y, z)
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
    nx, ny, nz = to_world_frame(xmat, g, key[sl, n], key[sl, n + 1], key[sl, n + 2])
    return key[sl, a + KEPT_DISTANCE], nx, ny, nz


@kernel
def mesh_triangle_distance(T, xpos, xmat, g, row, x, y, z):
    """Unsigned distance (m) from the world point p to one triangle (row of T) of the mesh of
    geom g, and the unit direction (world) from its nearest point to p: whether the feature
    a constraint plane came from is still under the proxy, and its tangent plane there."""
    lx, ly, lz = point_in_geom_frame(xpos, xmat, g, x, y, z)
    d2, qx, qy, qz, _ = closest(T, row, lx, ly, lz)
    d = math.sqrt(d2)
    if d == 0.0:  # on the triangle: its normal
        nx, ny, nz = T[row, T_N], T[row, T_N + 1], T[row, T_N + 2]
    else:
        nx, ny, nz = (lx - qx) / d, (ly - qy) / d, (lz - qz) / d
    nx, ny, nz = to_world_frame(xmat, g, nx, ny, nz)
    return d, nx, ny, nz


@kernel
def mesh_walk_distance(sh, k, row, x, y, z):
    """Distance (m, unsigned) and normal (world, from the triangle toward p) at the world
    point p from the triangle nearest p found by walking from triangle `row` (`_from_hint`:
    across an edge, round a vertex), and that triangle's row: the mesh's distance as seen
    from one place on it, no certificate, patch or tree (at a million triangles each of
    those is a walk of the tree). Whether a plane's surface goes on past its own triangle
    (`_move_once`): a sweep still guards whatever plane the answer makes.

    Unsigned: a walk may end on a nearest triangle of its own across the mesh, and p behind
    that one is not inside (a point proxy 4 cm from a sphere's far side was taken for
    resting on it, and floated 4 mm off the sphere with the device inside)."""
    S, T, C, xpos, xmat = sh.S, sh.T, sh.C, sh.xpos, sh.xmat
    g = int(S[k].geom)
    lx, ly, lz = point_in_geom_frame(xpos, xmat, g, x, y, z)
    d2, qx, qy, qz, f, i = _from_hint(S, T, C, k, row, lx, ly, lz)
    d, nx, ny, nz = _answer(S, T, k, lx, ly, lz, math.sqrt(d2), qx, qy, qz, f, i)
    if d < 0.0:
        d, nx, ny, nz = -d, -nx, -ny, -nz
    nx, ny, nz = to_world_frame(xmat, g, nx, ny, nz)
    return d, nx, ny, nz, i


Sweeping = namedtuple("Sweeping", "T C tree n base stamp sweep slab reach length slack cull pnx pny pnz poff")
"""A sweep's tree walk on mesh tables T, C: mesh k's tree (`tree_of`), the scan's stamp, the
sweep, how near (m) a triangle must come to it (`slab`), its reach and length (m), what its
nodes' boxes were grown by (`slack`, m), and when `cull`, the plane p·x = poff it stays r
above. Its walk's state: the earliest touch so far (lam, normal, row of T; -1 for none) and
far² (m², how far a triangle may lie from the start and be touched before it)."""


@kernel
def _sweep_run(q, j0, j1, s):
    """Sweep the sphere against the triangles of the records C[j0:j1] not read yet this scan;
    returns the state: the earliest hit so far (lam, normal, row of T; -1 for none) and the
    new far². Only the part of the segment before the earliest hit so far (lam < best_lam) is
    tested; when `cull`, not the triangles whose rectangle lies wholly behind the plane p·x =
    poff (a tangent plane the sphere stays r above all the way)."""
    T, C, stamp, sweep, slab, reach, length = q.T, q.C, q.stamp, q.sweep, q.slab, q.reach, q.length
    best_lam, bnx, bny, bnz, bi, far2 = s
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
            beyond2 = record_beyond2(C, j, ax - C[j + 4], ay - C[j + 5], az - C[j + 6])
            if beyond2 > 0.0 and h0 * h0 + beyond2 > slab * slab:
                continue
        # nor one that stays more than r off the rectangle in its plane that holds it along
        # the part of the segment before the earliest touch found
        if record_gap2(C, j, ax, ay, az, bx, by, bz, h0, h1) > slab * slab:
            continue
        if q.cull and record_top(C, j, q.pnx, q.pny, q.pnz) <= q.poff:
            continue
        i = int(C[j + R_ROW])
        if C[C_STAMPS + i] == stamp:
            continue
        C[C_STAMPS + i] = stamp
        lam, mx, my, mz, _ = sweep_triangle(T, i, sweep, far2)
        if lam >= 0.0 and lam < best_lam:
            best_lam, bnx, bny, bnz, bi = lam, mx, my, mz, i
            far = reach + best_lam * length  # only the segment before this hit matters now
            far2 = far * far
            bx, by, bz = ax + best_lam * ux, ay + best_lam * uy, az + best_lam * uz
    return best_lam, bnx, bny, bnz, bi, far2


@kernel(inline="always")
def _sweep_bound(q, s, node):
    """A node's bound: where (fraction of the segment) the sweep enters its boxes grown by
    the reach, before the earliest touch so far (`node_entry`; beyond it when not)."""
    w = q.sweep
    return node_entry(q.C, q.base + NODE_WIDTH * node, w.ax, w.ay, w.az, w.ux, w.uy, w.uz, q.length, w.r, q.slab,
                      q.slack, s[0])


@kernel(inline="always")
def _sweep_opened(q, s, node):
    """Not a node wholly behind the cull plane."""
    return not (q.cull and node_top(q.C, q.base + NODE_WIDTH * node, q.pnx, q.pny, q.pnz) <= q.poff)


@kernel(inline="always")
def _sweep_leaf(q, s, leaf):
    """The earliest touch so far after the triangles of a leaf."""
    j0, j1 = leaf_records(q.C, q.tree, leaf, q.n)
    return _sweep_run(q, j0, j1, s)


_sweep_walk = depth_first(_sweep_bound, _sweep_leaf, limit=best_so_far, opened=_sweep_opened, rebound=True)
"""The box tree walked earliest entry first: the nodes the segment enters, grown by the
reach, before the earliest touch found (a node taken up after a touch was found since its
entry was is entered again up to that touch)."""


@kernel
def _hit(S, T, k, xmat, g, tri, lam, nx, ny, nz, sweep):
    """The touch of row `tri` at fraction lam: its normal (geom frame) shaded when asked (while
    the shaded one still opposes the motion) and turned into the world frame; the triangle
    becomes the hint and the answer's feature."""
    ax, ay, az, ux, uy, uz, r, _, graze = sweep
    S[k].hint = S[k].feature = tri
    if S[k].shading:
        qx, qy, qz = ax + lam * ux - r * nx, ay + lam * uy - r * ny, az + lam * uz - r * nz
        sx, sy, sz = shade(T, tri, qx, qy, qz, nx, ny, nz)
        if sx * ux + sy * uy + sz * uz < -graze:  # still against the motion: use it
            nx, ny, nz = sx, sy, sz
    nx, ny, nz = to_world_frame(xmat, g, nx, ny, nz)
    return lam, nx, ny, nz


@kernel
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
        hit, hx, hy, hz, _ = sweep_triangle(T, i, sweep, far2)
        if hit >= 0.0 and hit < best_lam:
            best_lam, mx, my, mz, bi = hit, hx, hy, hz, i
    return best_lam, mx, my, mz, bi, sd2, sqx, sqy, sqz, sf, si


@kernel
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


@kernel
def _sweep_few(S, T, C, xmat, k, sl, g, m, hint, sd2, sqx, sqy, sqz, sf, sweep, far2, lam, mx, my, mz):
    """The end of `mesh_sweep` when a certificate left the m triangles in C[C_FEW:] to read
    besides the hint: the earliest touch among them and the hint's own (lam < 0: none). When
    sd2 >= 0 the start's nearest point is the hint's (sd2, q, feature sf) or one of theirs,
    and its answer is kept for `mesh_distance`."""
    out = _few_run(T, C, m, hint, sd2, sqx, sqy, sqz, sf, sweep, far2, lam, mx, my, mz)
    return _few_answer(S, T, k, xmat, sl, g, *out, sweep)


@kernel
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


@kernel
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


@kernel
def mesh_sweep(sh, k, x0, y0, z0, dx, dy, dz, r):
    """First touch (fraction in [0, 1), world normal) of a sphere of radius r (m) moving from
    x0 by d (m) into mesh k's triangles; (-1.0, 0.0, 0.0, 0.0) when none (`_sweep`), from
    and into the hint slot of its start (`_slot`). After a touch S[k].feature is the row of T
    touched (`_hit`)."""
    S, T, C, xpos, xmat = sh.S, sh.T, sh.C, sh.xpos, sh.xmat
    g = int(S[k].geom)
    ax, ay, az = point_in_geom_frame(xpos, xmat, g, x0, y0, z0)
    sl, hint = _slot(S, k, ax, ay, az)
    S[k].hint = hint
    out = _sweep(S, T, C, xmat, k, sl, ax, ay, az, dx, dy, dz, r)
    _touch(S, k, sl, ax, ay, az, S[k].hint)
    return out


@kernel
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
    ux, uy, uz = to_geom_frame(xmat, g, dx, dy, dz)
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
            if pressed(dist, into, r, graze):  # pressed into the one it touches: nothing comes earlier
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
            lam, mx, my, mz, f = sweep_triangle(T, hint, sweep, far2)
            if lam >= 0.0 and EDGE_AB <= f < VERTEX_A:
                # touched on an edge: the neighbour across it may be touched first
                other = int(T[hint, T_ADJ + f - EDGE_AB])
                if other >= 0:
                    lam2, nx, ny, nz, f2 = sweep_triangle(T, other, sweep, far2)
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
                        lam2, nx, ny, nz, f2 = sweep_triangle(T, walked, sweep, far2)
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
    at, m, cut = slot_patch(S, C, k, sl, ax, ay, az, ax + best_lam * ux, ay + best_lam * uy, az + best_lam * uz, slab)
    tree, size, n, base = tree_of(S, C, k)
    slack = 2.0 * TREE_MARGIN * (1.0 + S[k].rbound)
    q = Sweeping(T, C, tree, n, base, stamp, sweep, slab, reach, length, slack, cull, pnx, pny, pnz, poff)
    s = (best_lam, bnx, bny, bnz, bi, far2)
    if at >= 0:
        j0 = at + P_RECORDS
        s = _sweep_run(q, j0, j0 + m * RECORD_WIDTH, s)
    else:
        # the box tree (from the cut, when the slot noted one): the nodes the segment
        # enters, grown by the reach, earliest entry first; a node entered after the
        # earliest touch found holds no earlier one
        s, _ = _sweep_walk(size, C[cut:] if cut >= 0 else C[:0], q, s, depth_scratch())
    best_lam, bnx, bny, bnz, bi, far2 = s
    if bi < 0:
        return (-1.0, 0.0, 0.0, 0.0)
    return _hit(S, T, k, xmat, g, bi, best_lam, bnx, bny, bnz, sweep)
