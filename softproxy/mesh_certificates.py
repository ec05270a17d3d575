"""Building a mesh's kept certificates at load: per face its rising triangles, per vertex its table.

The queries that read them are `softproxy.compiled.certificate` (what a certificate proves,
and how a query reads one); `softproxy.mesh.MeshShape` builds them for every face and vertex
at load (and for a larger proxy in `prepare`) with `face_lists` and `vertex_tables`, and
`certificate_tables` packs them into the mesh tables T and C (`softproxy.mesh_tables`).
Compiled (numba): the walks of the box trees (`softproxy.mesh_trees`) run in threads, a
chunk of faces or vertices each. Nothing here runs in the tick.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from softproxy.compiled.certificate import ABOVE_TOL, STATIC_ABOVE
from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (
    T_ADJ, T_BALL, VERTEX_WIDTH, V_AXIS, V_COS, V_FAN, V_RING, V_SINES, V_THRESHOLD, V_X,
)
from softproxy.compiled.tree_walk import LEAF, STACK, heap_offer, heap_pop

MeshArrays = namedtuple("MeshArrays", "V F tri plane tlo thi centre rho fan_start fan")
"""A mesh as the certificates' builders read it (`softproxy.mesh.MeshTables`): its vertices
(m) and faces (vertex ids), its triangles (T's first columns), planes (unit normal, offset),
boxes (lower, upper; m) and bounding balls (centre, radius; m), and per vertex its fan
(fan[fan_start[v]:fan_start[v + 1]]: the triangles around it)."""
FaceWalk = namedtuple("FaceWalk", "vertices long apexes reach long_edge")
"""What `face_lists` walks: the box tree over the short triangles' vertices, the tree of the
long triangles with their nodes' `ApexFrames` (`softproxy.mesh_trees`), the reach (m) the
certificates hold over and the longest edge (m) of a short triangle."""
VertexWalk = namedtuple("VertexWalk", "axis ring_start ring_to longest tree reach_nodes reach_items frames reach "
                                      "long_edge")
"""What `vertex_tables` walks: per vertex its cone (unit axis, cosine) and ring (ring_to:
the vertices its edges lead to), per triangle its longest edge (m); the box tree over the
vertices' reach boxes (`BoxTree`: the vertex of each item, their positions' node boxes), the
nodes' and the items' reach boxes (lower, upper; m), the nodes' `Frames`, the reach (m) and
the longest edge (m) of a short triangle."""


# ---------------------------------------------------------------------------------------
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


def certificate_tables(s, t0: int, c0: int) -> tuple[np.ndarray, np.ndarray, float, float]:
    """The certificates of `softproxy.mesh.MeshTables` s whose triangles are rows t0.. of T and
    whose tables start at C[c0]: (its T_ADJ..T_BALL columns (triangles × 14), its part of C
    (vertex records, then rings, fans, sin β tables, face lists and ball lists), the reach
    (m) they hold over, the radius (m) of the ball certificates' resting ball)."""
    n, nv = s.triangles, len(s.vpos)
    adj = np.where(s.adj >= 0, s.adj + t0, -1).astype(np.float64)
    verts = np.zeros((nv, VERTEX_WIDTH))
    verts[:, V_X:V_X + 3] = s.vpos
    verts[:, V_AXIS:V_COS + 1] = s.vcone
    at = c0 + verts.size
    parts = [verts]
    # per vertex its ring (edge vector (m), a triangle on the edge), then its fan (ascending)
    ring = s.ring.astype(np.float64)
    ring[:, 3] += t0
    verts[:, V_RING] = at + 4 * s.ring_start[:-1]
    verts[:, V_RING + 1] = np.diff(s.ring_start)
    at += ring.size
    parts.append(ring)
    verts[:, V_FAN] = at + s.fan_start[:-1]
    verts[:, V_FAN + 1] = np.diff(s.fan_start)
    at += len(s.fan)
    parts.append(s.fan.astype(np.float64) + t0)
    radius, start, sines, ids = s.vtable
    counts = np.diff(start)
    verts[:, V_SINES] = at + 2 * start[:-1]
    verts[:, V_SINES + 1] = counts
    table = np.empty((len(sines), 2))
    table[:, 0], table[:, 1] = sines, ids
    parts.append(table)
    at += table.size
    # the threshold on c² (c: the cosine of the plane's normal to the cone's axis) above which
    # every triangle near the vertex lies behind the plane by angle alone (2.0: never)
    least = np.ones(nv)
    least[counts > 0] = sines[start[:-1][counts > 0]]
    s0 = least - 1e-12
    verts[:, V_THRESHOLD] = np.where(s0 > 0.0, 1.0 - s0 * s0, 2.0)
    # per face and side, the few triangles rising above its plane (-1: a concave patch)
    clear = np.zeros((n, 4))
    m = s.clear.reshape(-1)                      # face 0 front, face 0 back, face 1 front, ...
    runs = np.maximum(m, 0)
    first = at + np.cumsum(runs) - runs
    clear[:, 0], clear[:, 2] = first[0::2], first[1::2]
    clear[:, 1], clear[:, 3] = m[0::2], m[1::2]
    clear[:, [0, 2]] = np.where(clear[:, [1, 3]] < 0, 0.0, clear[:, [0, 2]])
    flat = s.listed.reshape(-1, s.listed.shape[2])
    parts.append(flat[np.arange(flat.shape[1])[None, :] < runs[:, None]].astype(np.float64) + t0)
    at += int(runs.sum())
    # per face and side, its ball list: the plane list where that holds, else its own (-1: none)
    ball = clear.copy()
    b = s.ball_count.reshape(-1)
    own = (m < 0) & (b >= 0)
    bruns = np.where(own, b, 0)
    sides = ball.reshape(-1, 2)                  # a view: (start, count) per face and side, as m
    sides[own, 0] = (at + np.cumsum(bruns) - bruns)[own]
    sides[own, 1] = b[own]
    bflat = s.ball_listed.reshape(2 * n, s.ball_listed.shape[2])
    parts.append(bflat[np.arange(bflat.shape[1])[None, :] < bruns[:, None]].astype(np.float64) + t0)
    columns = np.column_stack([adj, s.tv.astype(np.float64), clear, ball])
    assert columns.shape[1] == T_BALL + 4 - T_ADJ
    return columns, np.concatenate([p.ravel() for p in parts]), float(s.kept), float(s.ball)


@kernel
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


@kernel
def box_gap2(lo, hi, qlo, qhi):
    """Squared distance (m²) between box lo..hi and box qlo..qhi (a point: qlo = qhi)."""
    g = 0.0
    for k in range(3):
        e = qlo[k] - hi[k] if qlo[k] > hi[k] else lo[k] - qhi[k] if lo[k] > qhi[k] else 0.0
        g += e * e
    return g


@kernel
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


@kernel
def _near_face(t, qlo, qhi, cx, cy, cz, ri, tlo, thi, centre, rho, reach):
    """Whether triangle t may come within reach (m) of a face of box qlo..qhi and bounding
    ball (c, ri): both its box and its ball do."""
    if box_gap2(tlo[t], thi[t], qlo, qhi) > reach * reach:
        return False
    ex, ey, ez = centre[t, 0] - cx, centre[t, 1] - cy, centre[t, 2] - cz
    return math.sqrt(ex * ex + ey * ey + ez * ez) - rho[t] - ri <= reach


@kernel
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


@kernel(nogil=True, entry=True)
def face_lists(faces, mesh, walk, tstamp, stamp0, count, listed):
    """Per face of `faces` (ids) and side (front, back) of `mesh` (MeshArrays), the triangles
    within `walk.reach` (m, a FaceWalk) of it
    (box and bounding ball within reach of its own) that rise above its plane on that side (a
    vertex higher than ABOVE_TOL): their number in count[j, side] and the triangles in
    listed[j, side], or -1 when more than STATIC_ABOVE do (a concave patch) or the walk
    opens more than BUDGET leaves. Short triangles are found through their rising vertices
    within reach + long_edge of the face (the vertex tree), long ones in the long tree (its
    `ApexFrames`: its nodes' apex, their oriented boxes and boxes but the apex); a walk leaves out boxes beyond reach
    and boxes wholly behind the plane on every side still open (by the box, and for the long
    tree by the apex and the boxes of the rest too: a cone's face sees its ~25,000 slivers
    about the tip within reach, each node a wedge whose boxes rose above its plane beside the
    tip). `tstamp` (one int per triangle) is scratch, stamped from stamp0 + 1 on."""
    V, F, plane, tlo, thi, centre, rho, fan_start, fan = (mesh.V, mesh.F, mesh.plane, mesh.tlo, mesh.thi,
                                                          mesh.centre, mesh.rho, mesh.fan_start, mesh.fan)
    vorder, vlo, vhi, vsize = walk.vertices
    lorder, llo, lhi, lsize = walk.long
    laxes, lext, alo, ahi, apex = walk.apexes
    reach, long_edge = walk.reach, walk.long_edge
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


@kernel
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


@kernel
def _sine(w, V, px, py, pz, ax, ay, az):
    """Vertex w's sin β seen from p (axis a), rounded down to 1/SINE_GRID."""
    ux, uy, uz = V[w, 0] - px, V[w, 1] - py, V[w, 2] - pz
    s = -(ux * ax + uy * ay + uz * az) / math.sqrt(ux * ux + uy * uy + uz * uz)
    return math.floor((s + 1.0) * SINE_GRID) / SINE_GRID - 1.0


@kernel
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


@kernel(nogil=True, entry=True)
def vertex_tables(verts, mesh, walk, mark, stamp0, sines, ids, counts):
    """Per vertex v of `verts` (ids) of `mesh` (MeshArrays): among the vertices w of the
    triangles within `walk.reach` (m, a VertexWalk) of it but its fan, w other than v and the ends of its edges, the VERTEX_READ + 1 of least
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
    V, F, tlo, thi, centre, rho, fan_start, fan = (mesh.V, mesh.F, mesh.tlo, mesh.thi, mesh.centre, mesh.rho,
                                                   mesh.fan_start, mesh.fan)
    axis, ring_start, ring_to, longest = walk.axis, walk.ring_start, walk.ring_to, walk.longest
    vorder, vlo, vhi, vsize = walk.tree
    (rlo, rhi), (wlo, whi), (vaxes, vext) = walk.reach_nodes, walk.reach_items, walk.frames
    reach, long_edge = walk.reach, walk.long_edge
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

