"""A mesh geom for the god-object: its own triangles, checked, and the tables the engine reads.

MuJoCo collides a mesh geom through its convex hull, so a finger pressed into a bowl would
stop on the plane of the rim. The engine's mesh queries (`softproxy.compiled.mesh`: exact
distance, sweep of the proxy's sphere) answer on the triangles themselves; this module gets
those triangles ready, once, when a world is loaded (numpy; nothing here runs in the tick):

- `validate_mesh` checks and repairs the triangles MuJoCo compiled (`model.mesh_vert`, in
  the frame of `data.geom_xpos` / `geom_xmat`): coincident vertices welded, degenerate and
  duplicate triangles dropped, winding made consistent, inverted normals flipped, open and
  non-manifold meshes reported, each defect a `MeshWarning` naming geom, mesh and file.
- `MeshShape`, the `Shape` of a mesh geom, builds what `softproxy.mesh_tables.mesh_tables`
  and `softproxy.mesh_certificates.certificate_tables` pack into the tables T and C. Per
  triangle: its corners, edges, plane, the angle-weighted pseudo-normals of its face, edges
  and vertices (they sign the distance on a watertight mesh; Bærentzen & Aanæs 2005), its
  vertex normals (force shading) and the triangles across its edges. Per vertex: its fan,
  the edges leaving it and the cone of tangent planes that hold its fan behind them. And
  the kept certificates: per face and side the few triangles near it rising above its plane
  (`softproxy.mesh_certificates.face_lists`), per vertex the vertices near it by how far
  below its cone they lie (`vertex_tables`), built for every face and vertex at once over the reach of a
  KEPT_RADIUS proxy at load, and of a larger one by `prepare`; on a mesh too dense for a
  patch to hold a resting proxy (`dense`), per face and side where the plane's list fails,
  the few triangles a ball of the proxy's radius resting on the face reaches
  (`softproxy.mesh_balls`). And the box tree the queries walk where no certificate
  holds (`softproxy.mesh_trees`, `softproxy.mesh_tables.tree_nodes`).
A watertight mesh has an inside (signed distance); an open or non-manifold one is a
two-sided sheet (unsigned distance, both sides solid).
"""

from __future__ import annotations

import copy
import hashlib
import os
import sys
import threading
import warnings
import weakref
from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor, as_completed

import mujoco
import numpy as np
import trimesh
from tqdm import tqdm

from softproxy.compiled.certificate import STATIC_ABOVE, VERTEX_READ
from softproxy.compiled.layout import GEOM_MESH, PATCH_RECORDS, T_INV
from softproxy.compiled.patch import PATCH_KEEP
from softproxy.compiled.tolerances import CONTACT_TOL
from softproxy.geometry import Shape
from softproxy.mesh_balls import BALL_ABOVE, BALL_LIFT, BallWalk, ball_lists
from softproxy.mesh_certificates import FaceWalk, MeshArrays, VertexWalk, face_lists, vertex_tables
from softproxy.mesh_tables import tree_nodes
from softproxy.mesh_trees import BoxTree, apex_frames, box_tree, node_boxes, node_frames, point_frames

KEPT_RADIUS = 0.005
"""Proxy radius (m) the kept certificates are built for at load, for every face and vertex at
once; `prepare` builds them for a larger proxy (a query beyond their reach walks the box tree)."""
KEPT_STEP = 0.002
"""How far (m) a sweep may move and still be covered by the certificates built for its radius."""
DEGENERATE = 1e-6
"""A triangle whose area is below this fraction of its longest edge squared is degenerate
(zero-area: coincident or collinear vertices, within float32 rounding)."""


class MeshWarning(UserWarning):
    """A defect found (and repaired or worked around) in a mesh loaded for haptic contact.
    Raised by a mesh shape it names `mesh` (the asset), `geoms` (the geoms using it, by name),
    `file` (or None) and `defect`, so that a world whose geoms share one asset is told of
    each defect once (`of`; `softproxy.geometry.shapes_of` merges them)."""

    mesh: str | None = None
    geoms: tuple = ()
    file: str | None = None
    defect: str = ""

    @classmethod
    def of(cls, mesh: str, geoms, file: str | None, defect: str) -> "MeshWarning":
        """The warning of `defect` in asset `mesh` used by `geoms`: "mesh 'm' (geom 'g', file
        'f'): defect", or for several geoms "(geoms 'a', 'b', 'c' and 9 more, file 'f')"."""
        geoms = tuple(geoms)
        named = ", ".join(repr(g) for g in geoms[:3]) + (f" and {len(geoms) - 3} more" if len(geoms) > 3 else "")
        parts = [("geom " if len(geoms) == 1 else "geoms ") + named] + ([f"file {file!r}"] if file else [])
        w = cls(f"mesh {mesh!r} ({', '.join(parts)}): {defect}")
        w.mesh, w.geoms, w.file, w.defect = mesh, geoms, file, defect
        return w


# ---------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------

def _clean(vertices, faces, name: str, warn: bool):
    """`validate_mesh` plus whether the result is watertight (closed, manifold)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces).reshape(-1, 3).astype(np.int64)
    if f.size and (f.min() < 0 or f.max() >= len(v)):
        raise ValueError(f"mesh {name}: face indices out of range (0..{len(v) - 1})")
    defects = []
    bad_vertex = ~np.isfinite(v).all(axis=1)
    if bad_vertex.any():
        keep = ~bad_vertex[f].any(axis=1)
        defects.append(f"{int((~keep).sum())} triangles with non-finite vertices dropped")
        f = f[keep]
    # weld exactly coincident vertices (STL stores each triangle's own copies): the geometry is
    # unchanged, and edges shared by two triangles become shared in the index too
    v, inverse = np.unique(np.where(bad_vertex[:, None], 0.0, v), axis=0, return_inverse=True)
    f = inverse.reshape(-1)[f]

    # degenerate: an index repeated, or an area that is rounding noise for the triangle's size
    p0, p1, p2 = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    area2 = np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    longest2 = np.max([((p1 - p0) ** 2).sum(1), ((p2 - p1) ** 2).sum(1), ((p0 - p2) ** 2).sum(1)], axis=0)
    repeated = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 2] == f[:, 0])
    degenerate = repeated | (area2 <= DEGENERATE * longest2)
    if degenerate.any():
        defects.append(f"{int(degenerate.sum())} degenerate (zero-area) triangles dropped")
        f = f[~degenerate]

    # duplicates: the same three vertices, in either winding
    _, first = np.unique(np.sort(f, axis=1), axis=0, return_index=True)
    if len(first) < len(f):
        defects.append(f"{len(f) - len(first)} duplicate triangles dropped")
        f = f[np.sort(first)]
    if len(f) == 0:
        raise ValueError(f"mesh {name}: no usable triangles ({'; '.join(defects) or 'empty'})")

    tm = trimesh.Trimesh(v, f, process=False)
    if not tm.is_winding_consistent:
        before = f.copy()
        trimesh.repair.fix_winding(tm)
        f = np.asarray(tm.faces, dtype=np.int64)
        flipped = int((before != f).any(axis=1).sum())
        defects.append(f"inconsistent winding: {flipped} triangles flipped to agree with their neighbours")
    edges = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    open_edges = int((counts == 1).sum())
    shared = int((counts > 2).sum())
    closed = open_edges == 0 and shared == 0
    if open_edges:
        defects.append(f"open mesh ({open_edges} boundary edges, not watertight): "
                       "treated as a two-sided sheet, distance unsigned")
    if shared:
        defects.append(f"{shared} non-manifold edges (shared by more than two triangles): "
                       "treated as a two-sided sheet, distance unsigned")
    if closed and trimesh.Trimesh(v, f, process=False).volume < 0.0:
        f = f[:, ::-1].copy()
        defects.append("inverted normals (negative volume on a watertight mesh): all triangles flipped")
    if warn:
        for d in defects:
            warnings.warn(f"mesh {name}: {d}", MeshWarning, stacklevel=3)
    return v, f, defects, closed


def validate_mesh(vertices, faces, name: str, warn: bool = True) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Check and repair a triangle mesh for haptic contact; returns (vertices, faces, defects).

    Exactly coincident vertices are welded. Degenerate (zero-area) and duplicate triangles are
    dropped; an open or non-manifold mesh is kept (a bowl may be a sheet) and reported;
    inconsistent winding is made consistent, and a watertight mesh with negative volume
    (inverted normals) is flipped. Each defect is a sentence in `defects` and, when `warn`,
    a `MeshWarning` naming the mesh. Raises ValueError when nothing usable is left.
    """
    v, f, defects, _ = _clean(vertices, faces, name, warn)
    return v, f, defects


# ---------------------------------------------------------------------------------------
# One mesh asset's tables, built once and shared
# ---------------------------------------------------------------------------------------

class MeshTables:
    """The load-time tables of one set of triangles (geom frame, m), shared by every geom
    that uses it (`tables_of`): the per-triangle and per-vertex tables, the box tree
    (`tree`: triangle order, leaves, nodes) and the kept certificates (`reaching` a larger proxy's reach makes new ones). Arrays only (CSR runs for the
    per-vertex lists), so that a million triangles build in numpy and compiled loops."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, defects: list[str], signed: bool, key: bytes) -> None:
        self.defects, self.signed, self.key = defects, signed, key
        self.triangles = len(faces)
        used = vertices[np.unique(faces)]
        self.rbound = float(np.sqrt((used * used).sum(1)).max()) * (1.0 + 1e-12) + 1e-12
        self._build(vertices, faces)
        self.kept = 0.0        # the reach (m) every face's and vertex's certificate holds over
        self.clear = None      # per face and side: how many triangles rise above it (-1: concave)
        self.listed = None     # ... and which (faces × 2 sides × STATIC_ABOVE)
        self.vtable = None     # per vertex: (reach, start, sin β, vertex id), the last two flat
        self.ball = 0.0        # the radius (m) of the ball certificates' resting ball (0: none built)
        self.ball_count = None  # per face and side without a plane certificate: how many a resting ball reaches (-1: none)
        self.ball_listed = None  # ... and which (faces × 2 sides × BALL_ABOVE)
        self._certify(reach(KEPT_RADIUS))

    def _build(self, v: np.ndarray, f: np.ndarray) -> None:
        """The per-triangle and per-vertex tables of vertices v and faces f (validated)."""
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        ab, ac = b - a, c - a
        cross = np.cross(ab, ac)
        n = cross / np.linalg.norm(cross, axis=1)[:, None]
        aa, abac, cc = (ab * ab).sum(1), (ab * ac).sum(1), (ac * ac).sum(1)
        inv = 1.0 / (aa * cc - abac * abac)
        # A, B, C, AB, AC, unit normal N, AB·AB, AB·AC, AC·AC, 1 / (AB·AB AC·AC - (AB·AC)²)
        # (the columns of T that `layout` names T_A .. T_INV)
        self.tri = np.column_stack([a, b, c, ab, ac, n, aa, abac, cc, inv])
        self.plane = np.column_stack([n, (n * a).sum(1)])  # unit normal, offset n·A (m)
        # edges AB, BC, CA as (start, unit direction, length): the swept cylinders
        starts = np.stack([a, b, c], axis=1)
        vecs = np.stack([b - a, c - b, a - c], axis=1)
        del ab, ac, cross
        lengths = np.linalg.norm(vecs, axis=2)
        self.edges = np.concatenate([starts, vecs / lengths[..., None], lengths[..., None]], axis=2)
        del starts, vecs
        # each triangle's box and bounding ball about its centre (the certificates' reach tests)
        self.tlo = np.minimum(np.minimum(a, b), c)
        self.thi = np.maximum(np.maximum(a, b), c)
        centre = (a + b + c) / 3.0
        self.centre = centre
        self.rhos = np.sqrt(np.max([((a - centre) ** 2).sum(1), ((b - centre) ** 2).sum(1),
                                    ((c - centre) ** 2).sum(1)], axis=0))

        # pseudo-normals: an edge's is the sum of its two faces' normals, a vertex's the sum
        # of its faces' normals weighted by the face angle at the vertex
        angles = np.empty((len(f), 3))
        for k in range(3):
            e1 = v[f[:, (k + 1) % 3]] - v[f[:, k]]
            e2 = v[f[:, (k + 2) % 3]] - v[f[:, k]]
            cosang = (e1 * e2).sum(1) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
            angles[:, k] = np.arccos(np.clip(cosang, -1.0, 1.0))
        vnormal = np.zeros((len(v), 3))
        for k in range(3):
            np.add.at(vnormal, f[:, k], n * angles[:, k:k + 1])
        vnormal /= np.maximum(np.linalg.norm(vnormal, axis=1), 1e-300)[:, None]
        nv = len(v)
        key = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        ukeys, inverse = np.unique(key[:, 0] * nv + key[:, 1], return_inverse=True)
        inverse = inverse.reshape(-1)
        enormal = np.zeros((len(ukeys), 3))
        np.add.at(enormal, inverse, np.repeat(n, 3, axis=0))
        enormal = enormal[inverse.reshape(-1, 3)]  # (faces, 3 edges, 3)
        # across each edge (AB, BC, CA), the other triangle of a manifold edge, else -1
        slots = np.argsort(inverse, kind="stable")
        counts = np.bincount(inverse)
        first = np.concatenate([[0], np.cumsum(counts)[:-1]])
        adj = np.full(3 * len(f), -1, dtype=np.int64)
        pair = np.flatnonzero(counts == 2)
        one, two = slots[first[pair]], slots[first[pair] + 1]
        adj[one], adj[two] = two // 3, one // 3
        self.adj = adj.reshape(-1, 3)
        fv = vnormal[f]                            # (faces, 3 vertices, 3)
        self.pn = np.concatenate([n[:, None, :], enormal, fv], axis=1)  # face, edges AB BC CA, vertices A B C
        self.vn = fv.reshape(-1, 9)                # the vertex normals at A, B, C (force shading)
        del enormal, fv

        # vertex fans, for the certificate of a nearest point on a vertex: each triangle's
        # three vertex ids; per vertex its triangles (ascending), the edges to its ring of
        # neighbours (from the vertex, each with a triangle on it), and a circular cone (axis,
        # cosine) of directions n that see every edge going away (n·e <= 0): inside it, the
        # whole fan lies behind the tangent plane of normal n at the vertex
        self.tv = f
        order = np.argsort(f.reshape(-1), kind="stable")
        self.fan_start = np.searchsorted(f.reshape(-1)[order], np.arange(nv + 1))
        self.fan = order // 3                      # ascending per vertex (a stable sort)
        # directed edges v -> w, sorted by (v, w), with the first triangle (in face order) on each
        at = np.unique(inverse, return_index=True)[1] // 3
        lo, hi = ukeys // nv, ukeys % nv
        src = np.concatenate([lo, hi])
        dst = np.concatenate([hi, lo])
        tri = np.concatenate([at, at])
        order = np.lexsort((dst, src))
        src, dst, tri = src[order], dst[order], tri[order]
        self.ring_start = np.searchsorted(src, np.arange(nv + 1))
        self.ring_to = dst
        evec = v[dst] - v[src]
        self.ring = np.column_stack([evec, tri])   # per edge leaving a vertex: its vector (m), a triangle on it
        # the largest cone about the vertex normal inside {n: n·e <= 0 for every edge e}
        cones = np.empty((nv, 4))
        cones[:, :3] = vnormal
        cones[:, 3] = 2.0  # no cone: a vertex without edges
        if len(src):
            sdown = -((evec / np.linalg.norm(evec, axis=1)[:, None]) * vnormal[src]).sum(1)
            has = np.flatnonzero(np.diff(self.ring_start) > 0)
            smin = np.minimum.reduceat(sdown, self.ring_start[has])
            cos = np.where(smin > 0.0, np.sqrt(np.maximum(0.0, 1.0 - smin * smin)) + 1e-12, 2.0)
            cones[has, 3] = cos
        self.vcone = cones
        self.vpos = v
        # the box tree the queries fall back on where no certificate holds: triangles in
        # Morton order, LEAF a leaf; per node its axis-aligned box and a box oriented by its
        # first triangle (tight about a run of slivers, which an axis-aligned box is not)
        order, nlo, nhi, size = box_tree(self.tlo, self.thi)
        self.tree = (order, size, tree_nodes(order, nlo, nhi, size, v, f, self.plane))

    def reaching(self, kept: float) -> "MeshTables":
        """These tables with certificates over `kept` (m) at least: themselves, or the tables
        of the same triangles built for that reach (the per-triangle and per-vertex arrays
        shared, the certificates built once per reach and shared like the rest)."""
        if kept <= self.kept:
            return self
        grown = _TABLES.get((self.key, kept))
        if grown is None:
            grown = copy.copy(self)
            grown._certify(kept)
            _TABLES[(self.key, kept)] = grown
        return grown

    def _certify(self, kept: float) -> None:
        """Build the kept certificates of every face and vertex over `kept` (m): per face and
        side the triangles within it rising above the face's plane (`face_lists`), per vertex
        its sin β table (`vertex_tables`), each a walk of a box tree over the triangles."""
        n, nv = self.triangles, len(self.vpos)
        # short triangles are found through their vertices, long ones in a tree of their own;
        # so are the triangles of a hub (a vertex of more than HUB_FAN: a cap's fan of
        # slivers), whose fan a face's walk would otherwise read whole for each face near it
        edge = self.edges[:, :, 6].max(axis=1)
        long_edge = min(LONG_EDGES * float(np.median(edge)), 0.5 * kept)
        hub = np.diff(self.fan_start) > HUB_FAN
        is_long = (edge > long_edge) | hub[self.tv].any(axis=1)
        long = np.flatnonzero(is_long)
        long_tree = box_tree(self.tlo[long], self.thi[long], long)
        # a face's walk finds the short triangles through their vertices and the long ones in
        # their own tree, so it needs only the short triangles' vertices (a CAD part of
        # slivers has none: its faces walked every vertex within 18 mm for nothing)
        short = np.unique(self.tv[~is_long])
        short_tree = box_tree(self.vpos[short], self.vpos[short], short)
        frames = node_frames(long_tree.order, long_tree.size, self.vpos, self.tv, self.plane)
        apexes = apex_frames(long_tree.order, long_tree.size, self.vpos, self.tv, frames)
        # a vertex's walk: one tree over every vertex, each with its reach boxes
        item_vertex, wlo, whi = reach_boxes(self.vpos, self.tv, self.tlo, self.thi, self.centre, edge, long_edge)
        at = self.vpos[item_vertex]
        order, vlo, vhi, vsize = box_tree(at, at, extent=(whi - wlo).max(axis=1))
        vorder, wlo, whi = item_vertex[order], wlo[order], whi[order]
        rlo, rhi = node_boxes(np.arange(len(order)), vsize, wlo, whi)
        vframes = point_frames(vorder, vsize, self.vpos, self.vcone[:, :3])
        clear = np.empty((n, 2), dtype=np.int64)
        listed = np.full((n, 2, STATIC_ABOVE), -1, dtype=np.int64)
        keep = VERTEX_READ + 1
        sines = np.empty((nv, keep))
        ids = np.empty((nv, keep), dtype=np.int64)
        counts = np.empty(nv, dtype=np.int64)
        mesh = MeshArrays(self.vpos, self.tv, self.tri, self.plane, self.tlo, self.thi, self.centre, self.rhos,
                          self.fan_start, self.fan)
        vertex_walk = VertexWalk(self.vcone, self.ring_start, self.ring_to, edge, BoxTree(vorder, vlo, vhi, vsize),
                                 (rlo, rhi), (wlo, whi), vframes, kept, long_edge)
        face_walk = FaceWalk(short_tree, long_tree, apexes, kept, long_edge)
        scratch = threading.local()  # per worker: a stamp per triangle and one per vertex

        def worker():
            if not hasattr(scratch, "tstamp"):
                scratch.tstamp, scratch.mark = np.zeros(n, dtype=np.int64), np.zeros(nv, dtype=np.int64)
            return scratch

        def faces(s: int, e: int) -> int:
            face_lists(np.arange(s, e), mesh, face_walk, worker().tstamp, s, clear[s:e], listed[s:e])
            return e - s

        def vertices(s: int, e: int) -> int:
            vertex_tables(np.arange(s, e), mesh, vertex_walk, worker().mark, s, sines[s:e], ids[s:e], counts[s:e])
            return e - s

        # the ball certificates, once the plane's are known, where those do not hold: on the
        # short triangles of a mesh too dense for a patch to hold a resting proxy's contact
        radius = ball_radius(kept)
        fine = ~is_long & dense(self.tri, radius)
        built = bool(fine.any())
        bcount = np.full((n, 2), -1, dtype=np.int64)
        blisted = np.full((n, 2, BALL_ABOVE if built else 0), -1, dtype=np.int64)
        if built:
            held = np.flatnonzero(fine)
            short_triangles = box_tree(self.tlo[held], self.thi[held], held)
            short_frames = node_frames(short_triangles.order, short_triangles.size, self.vpos, self.tv, self.plane)
            ball_walk = BallWalk(short_triangles, short_frames, long_tree, frames, radius)

        def balls(s: int, e: int) -> int:
            wanted = (clear[s:e] < 0) & fine[s:e, None]  # the face lists are done by now
            ball_lists(np.arange(s, e), wanted, mesh, ball_walk, worker().tstamp, n + 2 * s, bcount[s:e], blisted[s:e])
            return e - s

        jobs = [(faces, s, min(n, s + BUILD_CHUNK)) for s in range(0, n, BUILD_CHUNK)]
        jobs += [(vertices, s, min(nv, s + BUILD_CHUNK)) for s in range(0, nv, BUILD_CHUNK)]
        later = [(balls, s, min(n, s + BUILD_CHUNK)) for s in range(0, n, BUILD_CHUNK) if fine[s:s + BUILD_CHUNK].any()]
        with _progress(n + nv + sum(e - s for _, s, e in later), f"mesh certificates ({n} triangles)") as bar, \
                ThreadPoolExecutor(max_workers=min(len(jobs), os.cpu_count() or 1, BUILD_THREADS)) as pool:
            for done in as_completed([pool.submit(*job) for job in jobs]):
                bar.update(done.result())
            for done in as_completed([pool.submit(*job) for job in later]):
                bar.update(done.result())
        head = np.arange(keep)[None, :] < counts[:, None]
        self.clear, self.listed = clear, listed
        self.ball, self.ball_count, self.ball_listed = (radius if built else 0.0), bcount, blisted
        self.vtable = (kept, np.concatenate([[0], np.cumsum(counts)]), sines[head], ids[head])
        self.kept = kept


def reach_boxes(vpos, tv, tlo, thi, centre, edge, long_edge):
    """The reach boxes of the vertices (`vertex_tables`): per vertex, its position grown by
    long_edge (m), and, one box per octant of the directions from it to the centres of its
    long triangles (longest edge `edge` over long_edge), grown by the boxes of those: a
    height field's bottom corner, with a wall going up and a fan sliver going 10 m under
    the field, has two boxes, not one that holds a quarter of the field's surface. Returns
    (the vertex of each box, lower corners, upper corners), every vertex at least once."""
    nv = len(vpos)
    stretched = np.flatnonzero(edge > long_edge)
    corner = tv[stretched].reshape(-1)
    triangle = np.repeat(stretched, 3)
    d = centre[triangle] - vpos[corner]
    key = corner * 8 + (d[:, 0] < 0.0) + 2 * (d[:, 1] < 0.0) + 4 * (d[:, 2] < 0.0)
    order = np.argsort(key, kind="stable")
    key, triangle = key[order], triangle[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]]) if len(key) else np.zeros(0, dtype=np.int64)
    plain = np.ones(nv, dtype=bool)
    plain[key[starts] // 8] = False
    vertex = np.concatenate([key[starts] // 8, np.flatnonzero(plain)]).astype(np.int64)
    lo = np.concatenate([np.minimum.reduceat(tlo[triangle], starts, axis=0) if len(starts) else np.zeros((0, 3)),
                         vpos[plain]])
    hi = np.concatenate([np.maximum.reduceat(thi[triangle], starts, axis=0) if len(starts) else np.zeros((0, 3)),
                         vpos[plain]])
    return vertex, np.minimum(lo, vpos[vertex] - long_edge), np.maximum(hi, vpos[vertex] + long_edge)


def dense(tri: np.ndarray, radius: float) -> bool:
    """Whether a mesh (rows of T: `tri`) is too dense for the patches to hold a resting
    proxy of `radius` (m): the band within PATCH_KEEP of it on a flat surface, 2π radius
    PATCH_KEEP, holds more than PATCH_RECORDS triangles of the median area. Only such a mesh
    gets ball certificates (`softproxy.mesh_balls`): elsewhere a patch answers as fast
    and the lists would only lengthen the load."""
    area = 0.5 / np.sqrt(tri[:, T_INV])  # T_INV = 1 / |AB × AC|²
    return bool(float(np.median(area)) * PATCH_RECORDS < 2.0 * np.pi * radius * PATCH_KEEP)


def ball_radius(kept: float) -> float:
    """The radius (m) of the ball certificates' resting ball for certificates over `kept` (m):
    the radius of the proxy they were built for (`reach`), plus BALL_LIFT."""
    return 0.5 * (kept - KEPT_STEP) - CONTACT_TOL + BALL_LIFT


def reach(radius: float) -> float:
    """The reach (m) the kept certificates need for a proxy of `radius` (m) sweeping up to KEPT_STEP."""
    return 2.0 * (radius + CONTACT_TOL) + KEPT_STEP


LONG_EDGES = 4.0
"""A triangle whose longest edge is over this many times the mesh's median (or half the
certificates' reach) is long: the certificates find it in a tree of long triangles, the
others through their vertices."""
HUB_FAN = 64
"""A vertex of more triangles than this is a hub (a cap's or a pole's fan): its triangles are
found by the certificates in the tree of long triangles, not through its fan."""
BUILD_CHUNK = 4096
"""Faces or vertices per compiled call while building certificates (the progress bar's step)."""
BUILD_THREADS = 8
"""Most threads building certificates at once (the compiled calls release the GIL)."""

_TABLES: weakref.WeakValueDictionary = weakref.WeakValueDictionary()
"""Every MeshTables alive, by (a digest of the triangles it was built from, its reach (m))."""


def tables_of(vertices, faces, mesh: str, geom: str, file: str | None = None) -> MeshTables:
    """The MeshTables of triangles (vertices (n, 3), faces (m, 3); geom frame, m), built the
    first time these exact triangles are seen and shared while any shape holds them; each call
    warns (`MeshWarning` naming the asset `mesh`, its `geom` and `file`) of what validation
    repaired or reported."""
    vertices = np.ascontiguousarray(vertices, dtype=np.float64).reshape(-1, 3)
    faces = np.ascontiguousarray(faces, dtype=np.int64).reshape(-1, 3)
    h = hashlib.blake2b(digest_size=20)
    h.update(np.array(vertices.shape + faces.shape, dtype=np.int64).tobytes())
    h.update(vertices.tobytes())
    h.update(faces.tobytes())
    key = h.digest()
    tables = _TABLES.get((key, reach(KEPT_RADIUS)))
    if tables is None:
        v, f, defects, closed = _clean(vertices, faces, mesh, warn=False)
        tables = MeshTables(v, f, defects, closed, key)
        _TABLES[(key, tables.kept)] = tables
    for d in tables.defects:
        warnings.warn(MeshWarning.of(mesh, [geom], file, d), stacklevel=3)
    return tables


def _progress(total: int, what: str):
    """A progress bar on stderr when it is a terminal and the work takes over a second."""
    return tqdm(total=total, desc=what, unit="", delay=1.0, leave=False,
                disable=not (hasattr(sys.stderr, "isatty") and sys.stderr.isatty()))


class _FaceLists(Mapping):
    """The kept face certificates read as a mapping: face i (or -1 - i, its back) -> (reach
    (m), the triangles rising above its plane), or (-1.0, None) for a concave patch."""

    def __init__(self, tables: MeshTables) -> None:
        self._t = tables

    def __getitem__(self, key):
        t = self._t
        i, side = (key, 0) if key >= 0 else (-1 - key, 1)
        if not 0 <= i < t.triangles:
            raise KeyError(key)
        m = int(t.clear[i, side])
        return (-1.0, None) if m < 0 else (t.kept, tuple(t.listed[i, side, :m].tolist()))

    def __iter__(self):
        for i in range(self._t.triangles):
            yield i
            yield -1 - i

    def __len__(self):
        return 2 * self._t.triangles


# ---------------------------------------------------------------------------------------
# The shape
# ---------------------------------------------------------------------------------------

class MeshShape(Shape):
    """A mesh geom's triangles, repaired, and the tables the engine's mesh queries read.

    `MeshShape(model, data, geom, static)` like the primitives, on the triangles of the geom's
    mesh asset; `triangles=(vertices (n, 3), faces (m, 3))` gives them instead (geom frame, m;
    any geom: a height field's surface, a mesh's convex hull). `shading=True` asks the
    queries for the normal interpolated from the vertex normals over a face (force shading)
    instead of the faceted one; the sweep still stops on the true triangles. `World` uses it
    for every mesh geom; pass `mesh_shape=MeshShape` to `shapes_of` (`functools.partial(
    MeshShape, shading=True)` for shading). `defects`: what `validate_mesh` repaired or
    reported; `signed`: watertight (an inside, signed distance) or a two-sided sheet.
    The tables (`tables`, a `MeshTables`) are built once per set of triangles and shared by
    every geom using the same asset. Arrays in the geom frame (m); a triangle's features are
    0 its face, 1-3 its edges AB, BC, CA, 4-6 its vertices A, B, C.
    """

    gtype = GEOM_MESH
    __slots__ = ("shading", "tables")

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, geom: int, static: bool,
                 shading: bool = False, triangles=None) -> None:
        super().__init__(model, data, geom, static)
        if triangles is None:
            mesh = int(model.geom_dataid[geom])
            if int(model.geom_type[geom]) != int(mujoco.mjtGeom.mjGEOM_MESH) or mesh < 0:
                raise ValueError(f"geom {self.name!r} is not a mesh geom: give its triangles=(vertices, faces)")
            va, vn = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
            fa, fn = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
            vertices = model.mesh_vert[va:va + vn]
            faces = model.mesh_face[fa:fa + fn]
            asset, file = _asset(model, mesh)
        else:
            vertices, faces = _explicit(triangles, self.name)
            asset, file = "triangles", None
        self.tables = tables_of(vertices, faces, asset, self.name, file)
        self.shading = bool(shading)
        # the bounding sphere about the geom origin that the god-object's broad phase uses
        self.rbound = self.tables.rbound

    def prepare(self, radius: float) -> bool:
        """Get the kept certificates for a proxy of `radius` (m) (`MeshTables.reaching`: built
        once per reach, shared by every geom of this asset). True when the engine's tables must
        be rebuilt."""
        grown = self.tables.reaching(reach(radius))
        if grown is self.tables:
            return False
        self.tables = grown
        return True

    # what the tables say, under the names the tests and the packing read
    signed = property(lambda self: self.tables.signed)
    defects = property(lambda self: self.tables.defects)
    triangles = property(lambda self: self.tables.triangles)
    _vpos = property(lambda self: self.tables.vpos)
    _kept = property(lambda self: self.tables.kept)
    _vtable = property(lambda self: self.tables.vtable)
    _clear = property(lambda self: _FaceLists(self.tables))


def _explicit(triangles, geom_name: str) -> tuple[np.ndarray, np.ndarray]:
    """`MeshShape(..., triangles=(vertices, faces))` read as (n, 3) float and (m, 3) int arrays."""
    try:
        vertices, faces = triangles
        vertices = np.array(vertices, dtype=np.float64).reshape(-1, 3)
        faces = np.array(faces).reshape(-1, 3)
    except (TypeError, ValueError):
        raise ValueError(f"geom {geom_name!r}: triangles must be (vertices (n, 3) in m, faces (m, 3) "
                         "vertex indices)") from None
    if faces.size and not np.issubdtype(faces.dtype, np.integer):
        if not np.array_equal(faces, np.round(faces)):
            raise ValueError(f"geom {geom_name!r}: triangles' faces must be integer vertex indices")
    return vertices, faces.astype(np.int64)


def _asset(model: mujoco.MjModel, mesh: int) -> tuple[str, str | None]:
    """How warnings name a mesh asset: its name (or #id) and its file when known."""
    name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, mesh) or f"#{mesh}"
    adr = int(model.mesh_pathadr[mesh])
    path = bytes(model.paths[adr:]).split(b"\0", 1)[0].decode(errors="replace") if adr >= 0 else ""
    return name, path or None
