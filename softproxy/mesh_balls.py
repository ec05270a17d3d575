"""The ball certificate of a mesh face: the few triangles a ball resting on it can reach.

Where more triangles rise above a face's plane than the kept plane certificate lists
(`softproxy.compiled.certificate`, `softproxy.mesh_certificates`: a concave patch, a saddle, a fine mesh curving within a
proxy's reach), fewer may reach into a ball of radius R resting on the face: tangent to its
plane on one side, at a point of the face. A sphere of radius r whose centre c lies within
R - r of the face lifted by R along its normal (dist(c - R n, face) <= R - r) lies inside
such a ball, so no other triangle comes within r of it; and along a segment that distance
is convex, so a sweep whose two ends pass the test stays inside all the way. On a surface
curving more gently than R the list is the face's neighbours rising above it: 8-12 a face on
the million-triangle near-flat grid, whose plane certificates hold nowhere concave.

`ball_lists` builds the lists at load for the faces and sides whose plane certificate does
not hold (a face whose plane list holds uses that list: every triangle a resting ball reaches
rises above the plane and lies within the plane certificate's reach). R is the proxy's
radius built for plus BALL_LIFT, so that a proxy resting on the face, or floating up to
2 BALL_LIFT above it, passes the test. The queries are in `softproxy.compiled.mesh`
(`_ball_few`, `_ball_holds`), allowing BALL_SLACK (`softproxy.compiled.certificate`).
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from softproxy.compiled.certificate import ABOVE_TOL, BALL_SLACK
from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import FEW_SLOTS
from softproxy.compiled.tree_walk import LEAF, STACK
from softproxy.compiled.triangle import closest, segments_gap2
from softproxy.mesh_certificates import box_gap2, box_heights, oriented_heights

BallWalk = namedtuple("BallWalk", "short short_frames long long_frames radius")
"""What `ball_lists` walks: the box trees over the short and the long triangles with their
nodes' `Frames` (`softproxy.mesh_trees`), and the resting ball's radius (m)."""
BALL_LIFT = 1e-5
"""How much larger (m) the resting ball is than the proxy it was built for: a proxy of that
radius whose centre floats up to twice this above the face is still inside it (a proxy held
a lift tolerance off its surface, a sphere sliding on a facet's tangent plane)."""
BALL_ABOVE = FEW_SLOTS
"""Most triangles a ball list holds (a query copies it to the certificates' scratch run);
more, and the face has no ball certificate on that side: its queries walk the box tree."""
BALL_BUDGET = 64
"""Most tree leaves one face's ball walk may open; beyond, no ball certificate there (beside
a wall of slivers, whose boxes the walk cannot tell from the few it reaches)."""


@kernel
def _reaches(tri, V, F, t, i, lx, ly, lz, sx, sy, sz, off, radius, reach2):
    """Whether triangle t comes within sqrt(reach2) (m) of face i lifted by l = radius s (s
    its unit normal on the side asked, off = s · a vertex of i): the least of the distances
    between each triangle's vertices and the other and between their edges, which is their
    distance unless they cross; and when t crosses the lifted plane, of its segment there
    (its ends, and it against the lifted edges), which is 0 when they do."""
    h = np.empty(3)
    for v in range(3):
        w = F[t, v]
        h[v] = sx * V[w, 0] + sy * V[w, 1] + sz * V[w, 2] - off
    if max(h[0], h[1], h[2]) <= ABOVE_TOL:
        return False  # behind the plane: no ball resting on the face reaches it
    for v in range(3):
        w = F[t, v]
        if closest(tri, i, V[w, 0] - lx, V[w, 1] - ly, V[w, 2] - lz)[0] <= reach2:
            return True
        w = F[i, v]
        if closest(tri, t, V[w, 0] + lx, V[w, 1] + ly, V[w, 2] + lz)[0] <= reach2:
            return True
    for e in range(3):
        p, q = F[t, e], F[t, (e + 1) % 3]
        for k in range(3):
            a, b = F[i, k], F[i, (k + 1) % 3]
            if segments_gap2(V[p, 0], V[p, 1], V[p, 2], V[q, 0], V[q, 1], V[q, 2],
                              V[a, 0] + lx, V[a, 1] + ly, V[a, 2] + lz,
                              V[b, 0] + lx, V[b, 1] + ly, V[b, 2] + lz) <= reach2:
                return True
    if min(h[0], h[1], h[2]) >= radius or max(h[0], h[1], h[2]) <= radius:
        return False
    # t crosses the lifted plane: the ends of its segment there, on the two edges that cross
    ends = np.empty((2, 3))
    m = 0
    for e in range(3):
        a, b = e, (e + 1) % 3
        if (h[a] - radius) * (h[b] - radius) < 0.0:
            f = (radius - h[a]) / (h[b] - h[a])
            pa, pb = F[t, a], F[t, b]
            for c in range(3):
                ends[m, c] = V[pa, c] + f * (V[pb, c] - V[pa, c])
            m += 1
            if m == 2:
                break
    if m < 2:
        return True  # through a vertex on the plane: counted as reaching (rare, and a superset is safe)
    for v in range(2):
        if closest(tri, i, ends[v, 0] - lx, ends[v, 1] - ly, ends[v, 2] - lz)[0] <= reach2:
            return True
    for k in range(3):
        a, b = F[i, k], F[i, (k + 1) % 3]
        if segments_gap2(ends[0, 0], ends[0, 1], ends[0, 2], ends[1, 0], ends[1, 1], ends[1, 2],
                          V[a, 0] + lx, V[a, 1] + ly, V[a, 2] + lz, V[b, 0] + lx, V[b, 1] + ly, V[b, 2] + lz) <= reach2:
            return True
    return False


@kernel
def _bound_beyond(tri, V, F, t, i, sx, sy, sz, off, radius, spare):
    """Whether no ball of `radius` resting on face i (side s) reaches triangle t, by a lower
    bound: x is reached when φ(x) = dist(x, face)² - 2 radius z(x) <= spare (z the height over
    the plane, spare = reach² - radius²); φ is convex, so over t it is at least its tangent
    plane at t's centre at the lowest of t's vertices."""
    cx = (V[F[t, 0], 0] + V[F[t, 1], 0] + V[F[t, 2], 0]) / 3.0
    cy = (V[F[t, 0], 1] + V[F[t, 1], 1] + V[F[t, 2], 1]) / 3.0
    cz = (V[F[t, 0], 2] + V[F[t, 1], 2] + V[F[t, 2], 2]) / 3.0
    d2, qx, qy, qz, _ = closest(tri, i, cx, cy, cz)
    phi = d2 - 2.0 * radius * (sx * cx + sy * cy + sz * cz - off)
    gx, gy, gz = 2.0 * (cx - qx) - 2.0 * radius * sx, 2.0 * (cy - qy) - 2.0 * radius * sy, 2.0 * (cz - qz) - 2.0 * radius * sz
    least = 0.0
    for v in range(3):
        w = F[t, v]
        least = min(least, gx * (V[w, 0] - cx) + gy * (V[w, 1] - cy) + gz * (V[w, 2] - cz))
    return phi + least > spare * (1.0 + 1e-9) + 1e-18


@kernel
def _may_reach(lo, hi, top, flo, fhi, ulo, uhi, radius, spare):
    """Whether a box lo..hi may hold a point x that a ball of `radius` resting on the face of
    box flo..fhi (lifted by radius along the side's normal s: ulo..uhi) reaches: such a point
    lies within reach of the lifted face, and within sqrt(2 radius z + spare) (m) of the face,
    z its height over the face's plane (top: the box's highest), since for q on the face
    |x - (q + radius s)|² = |x - q|² - 2 radius z + radius²; spare = reach² - radius²."""
    return (top > ABOVE_TOL and box_gap2(lo, hi, flo, fhi) <= 2.0 * radius * top + spare
            and box_gap2(lo, hi, ulo, uhi) <= radius * radius + spare)


@kernel(nogil=True, entry=True)
def ball_lists(faces, wanted, mesh, walk, tstamp, stamp0, count, listed):
    """Per face of `faces` (ids) of `mesh` (`softproxy.mesh_certificates.MeshArrays`) and side
    (front, back) where wanted[j, side], the triangles that a ball of `walk.radius` (m, a
    BallWalk) resting on that side of the face reaches (within radius +
    BALL_SLACK of the face lifted by radius, `_reaches`): their number in count[j, side] and
    the triangles in listed[j, side], or -1 when more than BALL_ABOVE do or the walk opens
    more than BALL_BUDGET leaves. Two box trees over the triangles, the short ones
    (sorder..ssize) and the long ones (lorder..lsize), so that a sliver's box does not widen
    its neighbours' nodes, each node with its box oriented by its first triangle
    (`node_frames`: saxes, sext; laxes, lext), whose height over a face's plane stays small
    on a smooth tilted patch where the axis-aligned box's does not; a walk leaves out the
    boxes no resting ball reaches (`_may_reach`: near the face only as far as they rise above
    its plane). `tstamp` (one int per triangle) is scratch, stamped from stamp0 + 2 j + side
    + 1 on."""
    V, F, tri, plane, tlo, thi = mesh.V, mesh.F, mesh.tri, mesh.plane, mesh.tlo, mesh.thi
    sorder, slo, shi, ssize = walk.short
    saxes, sext = walk.short_frames
    lorder, llo, lhi, lsize = walk.long
    laxes, lext = walk.long_frames
    radius = walk.radius
    stack = np.empty(STACK, np.int64)
    reach = radius + BALL_SLACK
    reach2 = reach * reach
    spare = reach2 - radius * radius
    ulo = np.empty(3)  # the face's box lifted by the radius
    uhi = np.empty(3)
    for j in range(len(faces)):
        i = faces[j]
        flo, fhi = tlo[i], thi[i]
        for side in range(2):
            count[j, side] = -1
            if not wanted[j, side]:
                continue
            stamp = stamp0 + 2 * j + side + 1
            tstamp[i] = stamp  # not its own
            sign = 1.0 if side == 0 else -1.0
            sx, sy, sz, off = sign * plane[i, 0], sign * plane[i, 1], sign * plane[i, 2], sign * plane[i, 3]
            lx, ly, lz = radius * sx, radius * sy, radius * sz
            ulo[0], ulo[1], ulo[2] = flo[0] + lx, flo[1] + ly, flo[2] + lz
            uhi[0], uhi[1], uhi[2] = fhi[0] + lx, fhi[1] + ly, fhi[2] + lz
            row = listed[j, side]
            m = 0
            leaves = 0
            for tree in range(2):
                order, nlo, nhi, size = (sorder, slo, shi, ssize) if tree == 0 else (lorder, llo, lhi, lsize)
                axes, ext = (saxes, sext) if tree == 0 else (laxes, lext)
                stack[0] = 1
                sp = 1
                while sp > 0 and m >= 0:
                    sp -= 1
                    node = stack[sp]
                    lo, hi = nlo[node], nhi[node]
                    if lo[0] > hi[0]:
                        continue
                    top = min(box_heights(lo, hi, sx, sy, sz, off)[0], oriented_heights(axes, ext, node, sx, sy, sz, off)[0])
                    if not _may_reach(lo, hi, top, flo, fhi, ulo, uhi, radius, spare):
                        continue
                    if node < size:
                        stack[sp] = 2 * node
                        stack[sp + 1] = 2 * node + 1
                        sp += 2
                        continue
                    leaves += 1
                    if leaves > BALL_BUDGET:
                        m = -1
                        break
                    first = (node - size) * LEAF
                    for item in range(first, min(len(order), first + LEAF)):
                        t = order[item]
                        if tstamp[t] == stamp:
                            continue
                        top = -math.inf
                        for v in range(3):
                            w = F[t, v]
                            top = max(top, sx * V[w, 0] + sy * V[w, 1] + sz * V[w, 2] - off)
                        if not _may_reach(tlo[t], thi[t], top, flo, fhi, ulo, uhi, radius, spare):
                            continue
                        tstamp[t] = stamp
                        if _bound_beyond(tri, V, F, t, i, sx, sy, sz, off, radius, spare):
                            continue
                        if not _reaches(tri, V, F, t, i, lx, ly, lz, sx, sy, sz, off, radius, reach2):
                            continue
                        if m == BALL_ABOVE:
                            m = -1
                            break
                        row[m] = t
                        m += 1
            count[j, side] = m
