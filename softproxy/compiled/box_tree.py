"""A mesh's box tree at run time: the bounds of its nodes and records.

Node j of mesh k lives at C[S.tree + TREE_NODES + NODE_WIDTH (j - 1)] (`softproxy.compiled.layout`):
its axis-aligned box and its box oriented by its first triangle; a leaf's records carry each
triangle's plane and the rectangle in that plane that holds it. Here: the gap (m) from a
point or a segment to a node or a record, the fraction at which a sphere's segment enters a
node grown by its reach, whether a segment stays above a plane over a node: the bounds the
walks of `softproxy.compiled.mesh` and `patch` prune by (the walk itself is
`softproxy.compiled.tree_walk`).
"""

from __future__ import annotations

import math

from softproxy.compiled.kernel import kernel
from softproxy.compiled.layout import (
    NODE_WIDTH, N_AXES, N_EXT, N_HI, N_LO, RECORD_WIDTH, TREE_NODES, TREE_RECORDS, TREE_SIZE,
)
from softproxy.compiled.tree_walk import LEAF


TREE_MARGIN = 1e-12
"""A box tree's boxes are grown by this (m, plus as much per metre of the mesh's bounding
radius) beyond their triangles, so that no rounding of a box test leaves a triangle out."""


@kernel
def node_gap2(C, at, x, y, z):
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


@kernel
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


@kernel
def _span_gap(p0, p1, lo, hi):
    """The gap (m) between the span p0..p1 and lo..hi on one axis (0 where they overlap)."""
    if p0 > p1:
        p0, p1 = p1, p0
    return lo - p1 if p1 < lo else p0 - hi if p0 > hi else 0.0


@kernel
def span_gap2(C, at, ax, ay, az, ux, uy, uz, tmax):
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


@kernel
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


@kernel
def node_entry(C, at, ax, ay, az, ux, uy, uz, length, r, grow, slack, tmax):
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
    g2 = node_gap2(C, at, ax, ay, az)
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
    if node_gap2(C, at, mx, my, mz) > ball * ball:
        return 2.0 * tmax + 1.0
    if _stays_above(C, at, ax, ay, az, ux, uy, uz, r, slack, tmax):
        return 2.0 * tmax + 1.0
    # per axis of either box, the least gap (m) between the segment's span and the box's:
    # together they bound the distance from every point of the segment (a tube about it,
    # where the boxes grown per axis are a square one)
    if span_gap2(C, at, ax, ay, az, ux, uy, uz, tmax) > grow * grow:
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


@kernel
def tree_of(S, C, k):
    """Mesh k's box tree: where it begins in C, its number of leaves, the mesh's number of
    triangles, and `base`, from which node j's record is at base + NODE_WIDTH j."""
    tree = int(S[k].tree)
    return tree, int(C[tree + TREE_SIZE]), int(S[k].nt), tree + TREE_NODES - NODE_WIDTH


@kernel
def leaf_records(C, tree, leaf, n):
    """The records (C[j0:j1]) of the triangles of leaf number `leaf` (node size + leaf) of a
    tree of n triangles at C[tree]."""
    first = leaf * LEAF
    last = min(first + LEAF, n)
    rec = int(C[tree + TREE_RECORDS])
    return rec + first * RECORD_WIDTH, rec + max(last, first) * RECORD_WIDTH


@kernel
def segment_gap(ax, ay, az, bx, by, bz, px, py, pz):
    """The distance (m) from p to the segment a..b."""
    ux, uy, uz = bx - ax, by - ay, bz - az
    wx, wy, wz = px - ax, py - ay, pz - az
    uu = ux * ux + uy * uy + uz * uz
    t = 0.0 if uu == 0.0 else (wx * ux + wy * uy + wz * uz) / uu
    t = 0.0 if t < 0.0 else 1.0 if t > 1.0 else t
    ex, ey, ez = wx - t * ux, wy - t * uy, wz - t * uz
    return math.sqrt(ex * ex + ey * ey + ez * ez)


@kernel
def _across(C, j):
    """The unit vector across the rectangle of the record at C[j]: its plane's normal × its
    axis."""
    nx, ny, nz = C[j], C[j + 1], C[j + 2]
    ux, uy, uz = C[j + 7], C[j + 8], C[j + 9]
    return ny * uz - nz * uy, nz * ux - nx * uz, nx * uy - ny * ux


@kernel
def record_beyond2(C, j, ex, ey, ez):
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


@kernel
def _span_beyond(s0, s1, half):
    """How far (m) the span s0..s1 lies from the span -half..half."""
    lo, hi = (s0, s1) if s0 <= s1 else (s1, s0)
    return lo - half if lo > half else -half - hi if hi < -half else 0.0


@kernel
def record_gap2(C, j, ax, ay, az, bx, by, bz, ha, hb):
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


@kernel
def capsule_gap(C, at, ax, ay, az, bx, by, bz):
    """How far (m) the segment a..b strays from the segment whose ends are at C[at:at + 6]:
    the larger of its ends' distances (the distance to a segment is convex along a segment)."""
    return max(segment_gap(C[at], C[at + 1], C[at + 2], C[at + 3], C[at + 4], C[at + 5], ax, ay, az),
               segment_gap(C[at], C[at + 1], C[at + 2], C[at + 3], C[at + 4], C[at + 5], bx, by, bz))


@kernel
def record_top(C, j, nx, ny, nz):
    """The highest point (m, along unit n) of the rectangle of the record at C[j]."""
    ux, uy, uz = C[j + 7], C[j + 8], C[j + 9]
    wx, wy, wz = _across(C, j)
    return (nx * C[j + 4] + ny * C[j + 5] + nz * C[j + 6] + C[j + 10] * abs(nx * ux + ny * uy + nz * uz)
            + C[j + 11] * abs(nx * wx + ny * wy + nz * wz))


@kernel
def node_top(C, at, nx, ny, nz):
    """The highest point (m, along unit n) of the oriented box of the node at C[at]."""
    top = 0.0
    for a in range(3):
        c = at + N_AXES + 3 * a
        k = nx * C[c] + ny * C[c + 1] + nz * C[c + 2]
        top += max(k * C[at + N_EXT + a], k * C[at + N_EXT + 3 + a])
    return top
