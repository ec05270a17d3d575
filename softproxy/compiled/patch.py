"""A hint slot's patch: the records of every triangle near a finger's recent queries.

A finger pressed into a bowl sweeps ten times a tick about one point, and a sliding one
moves ~10 µm a tick: each hint slot keeps the records within a capsule a little wider than
its query needs (PATCH_MARGIN), gathered nearest first from the box tree, so its next
queries read those few records instead of walking the tree (`softproxy.compiled.mesh`).
Where even a capsule PATCH_KEEP wider holds too many, the cut of tree nodes under it is
noted instead, and the walk starts there.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from softproxy.compiled.box_tree import capsule_gap, leaf_records, record_gap2, segment_gap, span_gap2, tree_of
from softproxy.compiled.finite import finite
from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (
    CUT_NODES, NODE_WIDTH, PATCH_RECORDS, PATCH_WIDTH, P_COUNT, P_CUT, P_END, P_FULL, P_KEYS, P_RADIUS, P_RECORDS,
    RECORD_WIDTH,
)
from softproxy.compiled.tree_walk import FROM_ROOT, best_first, best_scratch, best_so_far, heap_offer


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
patch only PATCH_CLOSE wider than itself (`slot_patch`): a finger held still asks about one place
tick after tick (a sliding one's queries move ~10 µm a tick)."""
PATCH_CLOSE = 2e-5
"""How much wider (m) than its query a held-still finger's patch is: at a million triangles
the ~30 within 20 µm of a 5 mm proxy make a patch where the ~300 within 0.1 mm do not (the
tree walk it saves: ~3 µs an update)."""


@kernel
def slot_patch(S, C, k, sl, ax, ay, az, bx, by, bz, need):
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
    gap = capsule_gap(C, at, ax, ay, az, bx, by, bz)
    if gap + need > C[at + P_RADIUS]:
        f = at + P_FULL
        qx, qy, qz = bx - ax, by - ay, bz - az
        length = math.sqrt(qx * qx + qy * qy + qz * qz)
        inside = capsule_gap(C, f, ax, ay, az, bx, by, bz) + need <= C[f + 6]
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


@kernel
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


@kernel
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
    return cx, cy, cz, segment_gap(ax, ay, az, cx, cy, cz, bx, by, bz)


@kernel
def _cut(S, C, k, at, ax, ay, az, bx, by, bz, radius):
    """Fill the cut at C[at] with the nodes of mesh k's box tree, at the deepest level where at
    most CUT_NODES come within `radius` (m) of the segment a..b (geom frame; a leaf counted
    at every level below its own): every triangle within the capsule lies in one of them, so
    a walk for a query inside it starts there, not at the root (a million triangles make
    seventeen levels, and the sphere lies within reach of two or three nodes of each)."""
    tree, size, n, base = tree_of(S, C, k)
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
                if span_gap2(C, base + NODE_WIDTH * child, ax, ay, az, ux, uy, uz, 1.0) <= r2:
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


Gathering = namedtuple("Gathering", "C tree n base ax ay az bx by bz ux uy uz least keys rows kept")
"""A patch's gathering on the mesh grids C: mesh k's tree (`tree_of`), the segment a..b (geom
frame, m; u = b - a), the least radius (m) worth a patch, and the scratch of the records kept:
a max-heap of their bounds (m²) and their rows in `kept`. Its walk's state: (r2, the radius²
(m²) gathered out to so far; how many records are kept; whether it gave up: the radius fell
below `least`)."""


@kernel(inline="always")
def _gather_bound(q, s, node):
    """A node's bound: the squared gap (m²) between the segment and its boxes."""
    return span_gap2(q.C, q.base + NODE_WIDTH * node, q.ax, q.ay, q.az, q.ux, q.uy, q.uz, 1.0)


@kernel(inline="always")
def _gather_done(q, s):
    """Given up: the patch would hold less than `least`."""
    return s[2]


@kernel(inline="always")
def _gather_overflow(q, s, g2):
    """A node with no room to wait: the patch holds only what lies nearer (g2, m²)."""
    _, m, given_up = s
    return g2, m, given_up or g2 < q.least * q.least


@kernel(inline="always")
def _gather_leaf(q, s, leaf):
    """Keep the records of a leaf that lie within the radius, the nearest PATCH_RECORDS of
    all kept so far; when full, the radius shrinks to the least bound left out."""
    C, ax, ay, az, bx, by, bz, keys, rows, kept = q.C, q.ax, q.ay, q.az, q.bx, q.by, q.bz, q.keys, q.rows, q.kept
    r2, m, _ = s
    j0, j1 = leaf_records(C, q.tree, leaf, q.n)
    for j in range(j0, j1, RECORD_WIDTH):
        ha = C[j] * ax + C[j + 1] * ay + C[j + 2] * az - C[j + 3]
        hb = C[j] * bx + C[j + 1] * by + C[j + 2] * bz - C[j + 3]
        if ha * ha > r2 and hb * hb > r2 and ha * hb > 0.0:
            continue
        g2 = record_gap2(C, j, ax, ay, az, bx, by, bz, ha, hb)
        if g2 > r2:
            continue
        if m == PATCH_RECORDS:
            # full: the farthest kept (or this one) is left out, and the patch holds only
            # what lies nearer than it (a node it had no room for may have said less)
            out = g2 if g2 >= keys[0] else keys[0]
            if out < r2:
                r2 = out
            if r2 < q.least * q.least:
                return r2, m, True
            if g2 >= keys[0]:
                continue
        row = m if m < PATCH_RECORDS else rows[0]  # the row of the one it displaces
        m = heap_offer(keys, rows, m, PATCH_RECORDS, g2, row)
        for c in range(RECORD_WIDTH):
            kept[row, c] = C[j + c]
    return r2, m, False


_gather_walk = best_first(_gather_bound, _gather_leaf, limit=best_so_far, done=_gather_done,
                          overflow=_gather_overflow)
"""The box tree walked nearest node first, out to the radius gathered so far."""


@kernel
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
    tree, size, n, base = tree_of(S, C, k)
    # a max-heap of the kept records' bounds (m²) and their rows in `kept`
    keys = np.empty(PATCH_RECORDS)
    rows = np.empty(PATCH_RECORDS, dtype=np.int64)
    kept = np.empty((PATCH_RECORDS, RECORD_WIDTH))
    q = Gathering(C, tree, n, base, ax, ay, az, bx, by, bz, bx - ax, by - ay, bz - az, least, keys, rows, kept)
    (r2, m, given_up), _ = _gather_walk(size, FROM_ROOT, q, (radius * radius, 0, False), best_scratch(room))
    if given_up:
        return False
    order = np.argsort(keys[:m])
    for i in range(m):
        h = order[i]
        C[at + P_KEYS + i] = keys[h]
        o = at + P_RECORDS + RECORD_WIDTH * i
        for c in range(RECORD_WIDTH):
            C[o + c] = kept[rows[h], c]
    C[at], C[at + 1], C[at + 2] = ax, ay, az
    C[at + P_END], C[at + P_END + 1], C[at + P_END + 2] = bx, by, bz
    # just under the least bound left out, so that a triangle at exactly that bound is not
    # taken for held
    C[at + P_RADIUS] = math.sqrt(r2) * (1.0 - 1e-12) if m == PATCH_RECORDS or r2 < radius * radius else radius
    C[at + P_COUNT] = m
    return True
