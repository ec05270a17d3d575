"""The mesh tables at load: every mesh of a world packed into T and C for the compiled queries.

`mesh_tables` packs, for every mesh a world holds, what `softproxy.mesh.MeshShape` built
into the arrays the run-time queries read (`softproxy.compiled.mesh`): T and TI, one row per
triangle (floats, indices), and C and CI, per mesh its box tree (`tree_nodes`), its records
(each triangle's plane and the rectangle that holds it, `rectangles`) and its kept
certificates (`softproxy.compiled.certificate`; floats, indices): the model, constant for a
run. `mesh_query_data` makes
what the queries keep between ticks: the hint slots' patches P and the scans' marks.
Plain numpy, once per world.
"""

from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from softproxy.compiled.box_tree import TREE_MARGIN
from softproxy.compiled.layout import (
    EDGE_WIDTH, GEOM_MESH, HINT_SLOTS, NODE_WIDTH, N_AXES, N_EXT, N_HI, N_LO, PATCH_WIDTH, P_FULL,
    P_RADIUS, RECORD_WIDTH, R_CENTRE, R_ROW, SCAN_STAMPS, TI_COLUMNS, T_COLUMNS, T_N,
)
from softproxy.mesh_certificates import certificate_tables
from softproxy.mesh_trees import node_frames

MeshTableArrays = namedtuple("MeshTableArrays", "T TI C CI")
"""A world's mesh tables: the triangles' floats (T) and indices (TI), the box trees' and
certificates' floats (C) and indices (CI) (`softproxy.compiled.layout`)."""


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


def mesh_tables(shapes, S: np.ndarray) -> MeshTableArrays:
    """The mesh tables (T, TI, C, CI) of the `softproxy.mesh.MeshShape`s among `shapes`, and
    their rows of the shape table S filled in (where their triangles, box tree, certificates
    and patches live). Geoms of one mesh asset (one `MeshTables`) share its rows of T and TI
    and its parts of C and CI; each keeps its own pose, and its hint, kept answers and patches
    in the data. A world with no mesh gets empty tables (the kernels' types stay the same)."""
    meshes = [(k, s) for k, s in enumerate(shapes) if s.gtype == GEOM_MESH]
    assets = list({id(s.tables): s.tables for _, s in meshes}.values())
    rows, index_rows, floats, ints, where = [], [], [], [], {}
    t0 = c0 = i0 = 0
    for a in assets:
        n = a.triangles
        order, size, nodes = a.tree
        nodes = nodes[1:].copy()  # node 0 is not a node
        grow = TREE_MARGIN * (1.0 + a.rbound)
        nodes[:, N_LO:N_LO + 3] -= grow
        nodes[:, N_HI:N_HI + 3] += grow
        nodes[:, N_EXT:N_EXT + 3] -= grow
        nodes[:, N_EXT + 3:N_EXT + 6] += grow
        records = np.empty((n, RECORD_WIDTH))
        records[:, 0:4] = a.plane[order]
        records[:, R_CENTRE:R_ROW] = _rectangles(a.tri, a.edges)[order]
        records[:, R_ROW] = order + t0
        bvh, rec = c0, c0 + nodes.size
        floats += [nodes.ravel(), records.ravel()]
        c0 = rec + records.size
        del records, nodes
        columns, kept, kept_ints, reach, ball = certificate_tables(a, t0, c0, i0)
        rows.append(np.concatenate([a.tri, a.edges.reshape(n, 3 * EDGE_WIDTH), a.pn.reshape(n, 21), a.vn], axis=1))
        index_rows.append(columns)
        where[id(a)] = (t0, n, bvh, size, rec, c0, i0, reach, ball)
        floats.append(kept)
        ints.append(kept_ints)
        c0 += len(kept)
        i0 += len(kept_ints)
        t0 += n
    for j, (k, s) in enumerate(meshes):
        t0, n, bvh, size, rec, verts, iverts, reach, ball = where[id(s.tables)]
        S[k].faceadr, S[k].facenum = t0, n
        S[k].bvhadr, S[k].bvhleaves, S[k].recadr = bvh, size, rec
        S[k].vertadr, S[k].vertiadr = verts, iverts
        S[k].patchadr = j * HINT_SLOTS * PATCH_WIDTH
        S[k].signed = s.signed
        S[k].shading = s.shading
        S[k].kept = reach
        S[k].ball = ball
    T = np.concatenate(rows) if rows else np.zeros((0, T_COLUMNS))
    TI = np.concatenate(index_rows) if index_rows else np.zeros((0, TI_COLUMNS), dtype=np.int64)
    assert T.shape[1] == T_COLUMNS and TI.shape[1] == TI_COLUMNS
    C = np.concatenate(floats) if floats else np.zeros(0)
    CI = np.concatenate(ints) if ints else np.zeros(0, dtype=np.int64)
    assert len(C) == c0 and len(CI) == i0 and len(T) < 2 ** 53
    return MeshTableArrays(np.ascontiguousarray(T), np.ascontiguousarray(TI), C, CI)


def mesh_query_data(S: np.ndarray, SD: np.ndarray, T: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """What the mesh queries keep, as loaded: each mesh shape's data (`SD`) with no hint and no
    hint slot used, its patches (P) holding nothing and none found too full, and the scans'
    marks (int64: the scan count, a certificate's list, a mark per row of T) all zero."""
    meshes = S.type == GEOM_MESH
    SD.hint[meshes] = SD.feature[meshes] = -1
    SD.key[meshes] = math.nan  # no hint slot used, none kept
    patches = np.zeros((int(meshes.sum()) * HINT_SLOTS, PATCH_WIDTH))
    patches[:, P_RADIUS] = -1.0  # holds nothing yet
    patches[:, P_FULL + 6] = -1.0  # nor was found too full
    return patches.ravel(), np.zeros(SCAN_STAMPS + len(T), dtype=np.int64)
