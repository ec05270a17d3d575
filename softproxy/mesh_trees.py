"""Box trees at load: the trees over a mesh's triangles and vertices, and their nodes' frames.

A complete binary tree over items with boxes (triangles, vertices, a vertex's reach), items
by grade of size then in Morton order, LEAF (`softproxy.compiled.tree_walk`) a leaf
(`box_tree`); per node its box (`node_boxes`) and a box oriented by its first triangle
(`node_frames`), its apex (`apex_frames`) or its first vertex's cone (`point_frames`), tight
about a run of slivers where the axis-aligned box is not. The run-time queries read them
packed in the mesh tables (`softproxy.mesh_tables`, `softproxy.compiled.box_tree`); the
certificates' builders walk them (`softproxy.mesh_certificates`, `softproxy.mesh_balls`).
Compiled (numba) where a loop over nodes is; once per mesh.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from softproxy.compiled.kernel import kernel
from softproxy.compiled.tree_walk import LEAF

BoxTree = namedtuple("BoxTree", "order lo hi size")
"""A box tree (`box_tree`): its items' ids in tree order, its nodes' lower and upper corners
(2 size × 3, m; node 0 unused), its number of leaves."""
Frames = namedtuple("Frames", "axes ext")
"""Per node of a box tree its oriented box (`node_frames`, `point_frames`): three unit axes
(2 size × 3 × 3) and the extents along each (2 size × 3 × 2: lower, upper; m)."""
ApexFrames = namedtuple("ApexFrames", "axes ext lo hi apex")
"""Per node of a tree of long triangles (`apex_frames`): the oriented box and the box of its
triangles but their common apex, and that apex's vertex id (-1: none)."""

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
        return BoxTree(np.zeros(0, dtype=np.int64), np.full((2, 3), np.inf), np.full((2, 3), -np.inf), 1)
    low, high = lo.min(axis=0), hi.max(axis=0)
    centre = 0.5 * (lo + hi)
    q = np.floor((centre - low) / max(float((high - low).max()), 1e-300) * (2 ** 21 - 1))
    code = _spread(q[:, 0]) | (_spread(q[:, 1]) << np.uint64(1)) | (_spread(q[:, 2]) << np.uint64(2))
    grade = grades((hi - lo).max(axis=1) if extent is None else extent)
    order = np.lexsort((code, grade))  # stable: by grade, then by code, then as given
    leaves = -(-n // LEAF)
    size = 1 << max(0, int(leaves - 1).bit_length())
    nlo, nhi = node_boxes(order, size, lo, hi)
    return BoxTree(ids[order], nlo, nhi, size)


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


@kernel
def _set_frame(axes, node, ux, uy, uz, vx, vy, vz):
    """A node's oriented axes: the unit u, the unit v square to it, and u × v."""
    axes[node, 0, 0], axes[node, 0, 1], axes[node, 0, 2] = ux, uy, uz
    axes[node, 1, 0], axes[node, 1, 1], axes[node, 1, 2] = vx, vy, vz
    axes[node, 2, 0], axes[node, 2, 1], axes[node, 2, 2] = uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx


@kernel
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
    return Frames(axes, ext)


@kernel(entry=True)
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
    return ApexFrames(axes, ext, lo, hi, apex)


@kernel(entry=True)
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
    return Frames(axes, ext)


@kernel(entry=True)
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
