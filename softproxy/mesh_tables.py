"""The mesh tables at load: every mesh of a world packed into T and C for the compiled queries.

`mesh_tables` packs, for every mesh a world holds, what `softproxy.mesh.MeshShape` built
into the two arrays the run-time queries read (`softproxy.compiled.mesh`): T, one row per
triangle, and C, per mesh its box tree (`tree_nodes`), its records (each triangle's plane and
the rectangle that holds it, `rectangles`) and its kept certificates
(`softproxy.compiled.certificate`). Plain numpy, once per world.
"""

from __future__ import annotations

import math

import numpy as np

from softproxy.compiled.box_tree import TREE_MARGIN
from softproxy.compiled.layout import (
    C_STAMPS, EDGE_WIDTH, GEOM_MESH, HINT_SLOTS, NODE_WIDTH, N_AXES, N_EXT, N_HI, N_LO, PATCH_WIDTH, P_FULL,
    P_RADIUS, RECORD_WIDTH, R_CENTRE, R_ROW, TREE_NODES, T_COLUMNS, T_N,
)
from softproxy.mesh_certificates import certificate_tables
from softproxy.mesh_trees import node_frames


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
