"""Triangle-mesh contact for the god-object: the mesh's own triangles, not its convex hull.

MuJoCo collides a mesh geom through its convex hull, so a finger pressed into a bowl would
stop on the plane of the rim. `MeshShape` answers the god-object's queries
(`softproxy.geometry.Shape`) on the triangles themselves, in the geom frame MuJoCo compiled
them into (`model.mesh_vert` is expressed in the frame of `data.geom_xpos/geom_xmat`):

- `distance`: exact Euclidean distance to the nearest triangle, so 1-Lipschitz. On a
  watertight mesh it is signed by the angle-weighted pseudo-normal of the nearest feature
  (face, edge or vertex; Bærentzen & Aanæs 2005), which gives the right side wherever the
  nearest point lies. An open mesh (a sheet) has no inside: its distance is unsigned and
  both sides of every triangle are solid.
- `sweep`: a sphere of radius r against each triangle inflated by r, which is convex (a slab
  over the face, a cylinder per edge, a ball per vertex), so the first touch is exact on a
  non-convex mesh, a sphere touching a triangle and moving along or away from it never
  enters it, and no speed carries the sphere through a triangle.

A point proxy is swept as a 10 nm sphere (see POINT_RADIUS).

Cost per query is bounded on large meshes (all in the geom frame; numpy only to rebuild):
1. a static uniform grid of triangle centres, built once with numpy at load;
2. a neighbourhood: every triangle within R of a centre c, from the grid, sorted by a lower
   bound on its distance from c (one matrix product: the plane and edge lines, and the
   triangle's bounding sphere, tight where a thin triangle points at c). A query within e
   of c reads only the triangles whose bound minus e is within its reach, a short prefix;
   the neighbourhood is rebuilt when a query leaves it, or drifted far enough that its
   prefix grew long once the scans since the last rebuild have read about a rebuild's worth
   of triangles (REBUILD_WORK); re-centred inside the old ball, from the old one's triangles;
3. the hint, the triangle touched or nearest last, is tested first: pressed into it, the
   sweep ends at once. Its tangent plane at the nearest point is a certificate: a triangle
   lying wholly behind the hint's plane (behind both faces' planes at a convex edge) is at
   least as far as that tangent plane, so a sphere sliding on it, or a point whose nearest
   point is there, needs only the triangles reaching above those planes: none on a convex
   patch, the rising wall in a bowl. When the nearest point is a vertex, the vertex's own fan
   lies behind the tangent plane whenever every edge leaving the vertex does (one dot
   product against a precomputed cone, else one per edge): a proxy held on the pole of a
   uv-sphere, where ~100 thin triangles meet, reads none of them. A triangle off the fan is
   behind it too when its far vertices lie far enough below the cone's axis (a per-vertex
   table sorted by that angle, one bisection per query), so on a convex patch none is read
   whatever the triangles' shape. When an edge rises above that plane, a triangle on it
   holds a nearer point, and when the nearest point is on an edge the point may lie over or
   beyond the neighbour across it: the query walks there first (WALK_STEPS at most; the
   face's or edge's certificate then holds). Scalar Python over the few triangles that remain.
   The same certificates are also kept for the mesh's lifetime, independent of any
   neighbourhood, and built at load for every face and vertex at once (numpy, from the
   vertices near each, found with a k-d tree), over the reach of a KEPT_RADIUS proxy sweeping
   up to KEPT_STEP; `prepare(radius)` builds them for a larger proxy: per face and side, the
   few triangles (STATIC_ABOVE at most, e.g. a vertex a rounding above a coplanar neighbour
   brings its fan) within that reach that rise above its plane, and per vertex the sin β
   table of the vertices near it (VERTEX_READ + 1 at most, read into Python lists on first
   touch, a few µs). A query beyond that reach builds its face's or vertex's table alone, in
   the tick, over twice its reach. When they hold (a convex patch), a distance query or a
   sweep reads the hint, its neighbour across an edge and those few, and no neighbourhood:
   sliding over a convex mesh rarely rebuilds one and builds nothing. A point at distance d
   needs a reach of 2d, a sphere of radius r sliding by L one of 2r + L. On a concave patch
   (inside a bowl) they do not hold, and the neighbourhood serves the query: its certificate
   lists (the rising triangles by position, the sin β tables) are built as scans read it.
4. the last distance answer is kept (the god-object asks again about the point it holds),
   and so is a sweep's start point whose nearest point the hint's certificate proved (the
   proxy that slid or pressed from there is asked about again), both keyed by the point in
   the geom frame, so a new pose never returns a stale answer; and
   `on_face` names a face two sweeps stopped on at the same point, so a proxy held in a
   concave corner of the mesh warm-starts from its planes instead of sweeping into each.
"""

from __future__ import annotations

import math
import warnings

import mujoco
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from softproxy.compiled.certificate import ABOVE_TOL, STATIC_ABOVE, VERTEX_READ
from softproxy.compiled.layout import GEOM_MESH
from softproxy.compiled.tolerances import CONTACT_TOL
from softproxy.geometry import Shape

NEIGHBOURHOOD_RADIUS = 0.006
"""Radius (m) a neighbourhood holds beyond the reach of the sweep that builds it: sorted, the
extra triangles cost nothing to scan, and they keep the next queries valid as the proxy moves."""
NEIGHBOURHOOD_SLACK = 0.0005
"""A query this far (m) from the neighbourhood's centre re-centres it when its scan would read
more than DRIFT_SCAN triangles (the lower bounds loosen by the drift)."""
DRIFT_SCAN = 24
REBUILD_WORK = 400
"""A drifted neighbourhood is re-centred only once the scans since it was built have read more
positions than this (in all): a rebuild costs about as much as that many scalar reads, so
re-centring then at most doubles the work, and a slow drift with short scans never pays it."""
BATCH_MIN = 32
"""A certificate's table is extended over more new neighbourhood positions than this in one
batched numpy pass rather than in scalar Python (after a rebuild it may be asked for hundreds)."""
KEPT_RADIUS = 0.005
"""Proxy radius (m) the kept certificates (`_face_clear`, `_vertex_clear`) are built for at
load, for every face and vertex at once; `prepare` builds them for a larger proxy, and a query
beyond them builds its face's or vertex's alone, in the tick."""
KEPT_STEP = 0.002
"""How far (m) a sweep may move and still be covered by the certificates built for its radius."""
RISING_VERTICES = 4 * STATIC_ABOVE
"""A face with more vertices than this rising above its plane near it is taken as concave at
once (its rising triangles are not gathered)."""
PAIR_CHUNK = 2048
"""Points per numpy pass when gathering the vertices near every face or vertex (bounds memory)."""
SINE_GRID = 2.0 ** 40
"""Steps per unit a kept vertex table's sin β is rounded down to (≈1e-12) for one sort."""
VECTOR_MIN = 64
"""A scan of more triangles than this is narrowed first by one vectorised distance pass
(a point far from a symmetric mesh is nearly as far from hundreds of triangles)."""
DEGENERATE = 1e-6
"""A triangle whose area is below this fraction of its longest edge squared is degenerate
(zero-area: coincident or collinear vertices, within float32 rounding)."""
GRID_CELLS = 64
"""Most grid cells per axis."""
RECENT_HITS = 4
"""Triangles a sweep stopped on that `on_face` remembers (a proxy held in a concave corner of
a mesh rests on up to three)."""


class MeshWarning(UserWarning):
    """A defect found (and repaired or worked around) in a mesh loaded for haptic contact."""


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
# Scalar geometry on one triangle (hot path)
# ---------------------------------------------------------------------------------------
# A triangle is a tuple of 22 floats, in the geom frame:
#   A (0-2), B (3-5), C (6-8), AB = B - A (9-11), AC = C - A (12-14), unit normal N (15-17),
#   AB·AB (18), AB·AC (19), AC·AC (20), 1 / (AB·AB AC·AC - (AB·AC)²) (21).
# Features: 0 the face, 1 edge AB, 2 edge BC, 3 edge CA, 4 vertex A, 5 vertex B, 6 vertex C.





# ---------------------------------------------------------------------------------------
# The shape
# ---------------------------------------------------------------------------------------





def _rows(a: np.ndarray) -> list:
    """The rows of a 2-d array as tuples of floats."""
    return list(map(tuple, a.tolist()))


class MeshShape(Shape):
    """A mesh geom's triangles as seen by a proxy (world frame in, world frame out; m).

    `MeshShape(model, data, geom, static)` like the primitives; `shading=True` returns the
    normal interpolated from the vertex normals over a face (force shading) instead of the
    faceted one; the sweep still stops on the true triangles. Pass `mesh_shape=MeshShape`
    to `shapes_of` / `World` (`functools.partial(MeshShape, shading=True)` for shading).
    """

    gtype = GEOM_MESH
    flat = False
    __slots__ = (
        "mesh", "label", "signed", "shading", "defects", "triangles", "_tri", "_edges", "_pn", "_vn", "_adj", "_plane",
        "_ep", "_ev", "_eil", "_em", "_fn", "_q", "_abc", "_faces", "_sph", "_rhos", "_tv", "_fan", "_ring", "_vcone", "_centre", "_rho", "_slack",
        "_grid_lo", "_grid_h", "_grid_dims", "_grid_start", "_grid_order", "_clear",
        "_off", "_vpos", "_vxyz", "_vtree", "_vt_start", "_vt_tris", "_edge_keys", "_vaxis", "_kept", "_vtable",
    )

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, geom: int, static: bool,
                 shading: bool = False) -> None:
        super().__init__(model, data, geom, static)
        mesh = int(model.geom_dataid[geom])
        if int(model.geom_type[geom]) != int(mujoco.mjtGeom.mjGEOM_MESH) or mesh < 0:
            raise ValueError(f"geom {self.name!r} is not a mesh geom")
        self.mesh = mesh
        self.label = _label(model, geom, mesh, self.name)
        va, vn = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
        fa, fn = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
        vertices = np.array(model.mesh_vert[va:va + vn], dtype=np.float64)
        faces = np.array(model.mesh_face[fa:fa + fn], dtype=np.int64)
        vertices, faces, self.defects, self.signed = _clean(vertices, faces, self.label, warn=True)
        self.shading = bool(shading)
        self.triangles = len(faces)
        # the bounding sphere about the geom origin that the god-object's broad phase uses
        used = vertices[np.unique(faces)]
        self.rbound = float(np.sqrt((used * used).sum(1)).max()) * (1.0 + 1e-12) + 1e-12
        self._build(vertices, faces)
        self._clear: dict = {}   # face (i, or -1 - i for its back) -> radius checked clear (m), or -1
        self._kept = 0.0         # the radius (m) every face's and vertex's certificate holds over
        self._vtable = None      # `_vertex_tables` over every vertex, read into `_vclear` on first touch
        self.prepare(KEPT_RADIUS)

    # -- load-time tables ---------------------------------------------------------------
    def _build(self, v: np.ndarray, f: np.ndarray) -> None:
        a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
        ab, ac = b - a, c - a
        cross = np.cross(ab, ac)
        n = cross / np.linalg.norm(cross, axis=1)[:, None]
        aa, abac, cc = (ab * ab).sum(1), (ab * ac).sum(1), (ac * ac).sum(1)
        inv = 1.0 / (aa * cc - abac * abac)
        self._tri = _rows(np.column_stack([a, b, c, ab, ac, n, aa, abac, cc, inv]))
        self._abc = np.stack([a, b, c], axis=1)  # (faces, 3 vertices, 3): the certificates' batched tests
        self._faces = f
        self._off = (n * a).sum(1)  # each plane's offset n·A (m)
        self._plane = _rows(np.column_stack([n, self._off]))
        # edges AB, BC, CA as (start, unit direction, length) for the swept cylinders
        starts = np.stack([a, b, c], axis=1)
        vecs = np.stack([b - a, c - b, a - c], axis=1)
        lengths = np.linalg.norm(vecs, axis=2)
        units = vecs / lengths[..., None]
        edges = np.concatenate([starts, units, lengths[..., None]], axis=2)
        self._edges = list(zip(*(_rows(edges[:, k]) for k in range(3))))
        # vectorised tables: exact point-triangle distance by edges (region rebuilds), and the
        # plane and the three in-plane edge lines as rows of Q, so that Q @ (p, 1) gives the
        # height over the plane and how far p lies beyond each edge (neighbourhood rebuilds)
        self._ep, self._ev = starts, vecs
        self._eil = 1.0 / (lengths * lengths)
        out = np.cross(units, n[:, None, :])  # in-plane, out of the triangle across each edge
        self._em = out
        self._fn = n
        normals = np.concatenate([n[:, None, :], out], axis=1)                  # (faces, 4, 3)
        points = np.concatenate([a[:, None, :], starts], axis=1)
        self._q = np.concatenate([normals, -(normals * points).sum(2, keepdims=True)], axis=2).reshape(-1, 16)
        # and (-2m, |m|²) for the triangle's centre m, so that (p, 1) gives |p - m|² - |p|²: the
        # bounding-sphere bound (first, to drop the far triangles cheaply; then tight where the
        # edge lines are not: far along a thin triangle that points at p)
        centre = (a + b + c) / 3.0
        self._sph = np.concatenate([-2.0 * centre, (centre * centre).sum(1)[:, None]], axis=1)
        self._rhos = np.sqrt(np.max([((a - centre) ** 2).sum(1), ((b - centre) ** 2).sum(1),
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
        key = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        _, inverse = np.unique(key, axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        enormal = np.zeros((inverse.max() + 1, 3))
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
        self._adj = _rows(adj.reshape(-1, 3))
        fv = vnormal[f]                            # (faces, 3 vertices, 3)
        self._pn = list(zip(_rows(n), *(_rows(enormal[:, k]) for k in range(3)), *(_rows(fv[:, k]) for k in range(3))))
        self._vn = _rows(fv.reshape(-1, 9))

        # vertex fans, for the certificate of a nearest point on a vertex: each triangle's three
        # vertex ids; per vertex, its triangles and the edges to its ring of neighbours (from
        # the vertex, each with a triangle on it), and a circular cone (axis, cosine) of directions that see every edge
        # going away from them (n·e <= 0): inside it, the whole fan lies behind the tangent plane
        self._tv = _rows(f)
        order = np.argsort(f.reshape(-1), kind="stable")
        bounds = np.searchsorted(f.reshape(-1)[order], np.arange(len(v) + 1))
        self._vt_start, self._vt_tris = bounds, order // 3  # per vertex, its triangles (numpy)
        tri_of = (order // 3).tolist()
        bounds = bounds.tolist()
        pairs = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        pairs = np.unique(np.concatenate([pairs, pairs[:, ::-1]]), axis=0)
        pstart = np.searchsorted(pairs[:, 0], np.arange(len(v) + 1)).tolist()
        self._edge_keys = pairs[:, 0] * len(v) + pairs[:, 1]  # sorted: v -> w is an edge
        evec = v[pairs[:, 1]] - v[pairs[:, 0]]
        eunit = evec / np.linalg.norm(evec, axis=1)[:, None]
        fans, rings, cones = [], [], []
        evec_l, eunit_l, vn_l = evec.tolist(), eunit, vnormal.tolist()
        edge_tri = {}
        for t, (i, j, k) in enumerate(f.tolist()):
            for e0, e1 in ((i, j), (j, k), (k, i)):
                edge_tri.setdefault((e0, e1) if e0 < e1 else (e1, e0), t)
        pairs_l = pairs.tolist()
        for i in range(len(v)):
            fans.append(frozenset(tri_of[bounds[i]:bounds[i + 1]]))
            s0, s1 = pstart[i], pstart[i + 1]
            # (edge vector, a triangle on that edge) per neighbour
            rings.append(tuple((*evec_l[k], edge_tri[(i, w) if i < w else (w, i)])
                               for k, (_, w) in zip(range(s0, s1), pairs_l[s0:s1])))
            if s1 > s0:
                # the largest cone about the vertex normal a inside {n: n·e <= 0 for every edge e}
                sines = -(eunit_l[s0:s1] @ vnormal[i])
                smin = float(sines.min())
                cos = math.sqrt(max(0.0, 1.0 - smin * smin)) + 1e-12 if smin > 0.0 else 2.0
            else:
                cos = 2.0
            cones.append((*vn_l[i], cos))
        self._fan, self._ring, self._vcone = fans, rings, cones
        self._vpos, self._vaxis, self._vtree = v, vnormal, cKDTree(v)
        self._vxyz = _rows(v)

        # the static grid of triangle centres
        self._centre, self._rho = centre, float(self._rhos.max())
        lo, hi = centre.min(0), centre.max(0)
        mean_edge = float(lengths.mean())
        h = max(2.0 * self._rho, 2.0 * mean_edge, float((hi - lo).max()) / GRID_CELLS, 1e-9)
        dims = np.minimum(np.floor((hi - lo) / h).astype(np.int64) + 1, GRID_CELLS)
        cell = np.minimum(np.floor((centre - lo) / h).astype(np.int64), dims - 1)
        key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
        order = np.argsort(key, kind="stable")
        self._grid_order = order
        self._grid_start = np.searchsorted(key[order], np.arange(int(dims.prod()) + 1)).tolist()
        self._grid_lo, self._grid_h, self._grid_dims = lo.tolist(), h, dims.tolist()
        self._slack = max(NEIGHBOURHOOD_SLACK, 0.1 * mean_edge)

    # -- the neighbourhood ------------------------------------------------------------------

    # -- certificates kept for the mesh's lifetime ------------------------------------------------
    def prepare(self, radius: float) -> bool:
        """Build the kept certificates of every face and vertex (numpy, all at once) for a proxy
        of `radius` (m) sweeping up to KEPT_STEP, so that its queries never build one in the
        servo tick; call it when a proxy larger than KEPT_RADIUS is made (load builds those)."""
        kept = 2.0 * (radius + CONTACT_TOL) + KEPT_STEP
        if kept <= self._kept:
            return False
        self._clear.update(self._face_tables(np.arange(self.triangles), kept))
        self._vtable = self._vertex_tables(np.arange(len(self._vpos)), kept)
        self._kept = kept
        return True

    def _vertices_near(self, points: np.ndarray, reach: np.ndarray):
        """(k, w) for every vertex w within reach[k] (m) of points[k], as two numpy arrays."""
        ks, ws = [], []
        for s in range(0, len(points), PAIR_CHUNK):
            tree = cKDTree(points[s:s + PAIR_CHUNK])
            got = tree.sparse_distance_matrix(self._vtree, float(reach[s:s + PAIR_CHUNK].max()), output_type="ndarray")
            k = got["i"].astype(np.int64) + s
            keep = got["v"] <= reach[k]
            ks.append(k[keep])
            ws.append(got["j"][keep].astype(np.int64))
        return np.concatenate(ks), np.concatenate(ws)

    def _face_tables(self, faces: np.ndarray, radius: float) -> dict:
        """Kept face certificates for `faces` (ids) over `radius` (m), all at once: per face and
        side (key i, or -1 - i for its back), (radius, the triangles within radius of the face
        that reach above its plane), or (-1, None) when more than STATIC_ABOVE do (a concave
        patch). A triangle reaches above the plane when one of its vertices does (higher than
        ABOVE_TOL), and such a vertex lies within radius + the face's and twice the largest
        triangle's bounding radius of the face's centre: one dot product per vertex that near,
        then the rising vertices' triangles within radius."""
        rhos, centre = self._rhos, self._centre
        k, w = self._vertices_near(centre[faces], radius + rhos[faces] + 2.0 * self._rho)
        face = faces[k]
        h = np.einsum("ij,ij->i", np.take(self._vpos, w, axis=0), np.take(self._fn, face, axis=0))
        h -= np.take(self._off, face)
        start, tris = self._vt_start, self._vt_tris
        ids = faces.tolist()
        out = {}
        for side, rising in ((1.0, h > ABOVE_TOL), (-1.0, h < -ABOVE_TOL)):
            keys = ids if side > 0.0 else [-1 - i for i in ids]
            # a face with many rising vertices near it is concave (or seen from behind): not expanded
            many = np.bincount(k[rising], minlength=len(faces)) > RISING_VERTICES
            rising &= ~many[k]
            rk, rw = k[rising], w[rising]
            # each rising vertex's triangles: (face position, triangle) pairs, kept within radius
            count = start[rw + 1] - start[rw]
            first = np.repeat(start[rw] - np.cumsum(count) + count, count)
            t = tris[first + np.arange(int(count.sum()))]
            rk = np.repeat(rk, count)
            gap = np.linalg.norm(centre[t] - centre[faces[rk]], axis=1) - rhos[t] - rhos[faces[rk]]
            near = gap <= radius
            pair = np.unique(rk[near] * self.triangles + t[near])
            rk, t = pair // self.triangles, pair % self.triangles
            bounds = np.searchsorted(rk, np.arange(len(faces) + 1))
            counts = np.diff(bounds)
            out.update(dict.fromkeys(keys, (radius, ())))
            concave = np.flatnonzero(many | (counts > STATIC_ABOVE)).tolist()
            out.update(dict.fromkeys([keys[j] for j in concave], (-1.0, None)))
            for j in np.flatnonzero((counts > 0) & (counts <= STATIC_ABOVE)).tolist():
                out[keys[j]] = (radius, tuple(t[bounds[j]:bounds[j + 1]].tolist()))
        return out


    def _vertex_tables(self, vertices: np.ndarray, radius: float):
        """Kept vertex certificates for `vertices` (ids) over `radius` (m), all at once: per
        vertex v, the vertices w of the triangles within radius of it (all within radius + twice
        the largest triangle's bounding radius), but v and the ends of its edges (behind the
        tangent plane with the fan), by sin β ascending (β: the angle of w - v below the plane
        square to v's cone axis), the first VERTEX_READ + 1 of them. (radius, start per vertex
        position, sin β, w), the last two flat (numpy)."""
        k, w = self._vertices_near(self._vpos[vertices], np.full(len(vertices), radius + 2.0 * self._rho))
        v = vertices[k]
        keys = v * len(self._vpos) + w
        at = np.minimum(np.searchsorted(self._edge_keys, keys), len(self._edge_keys) - 1)
        off = (w != v) & (self._edge_keys[at] != keys)
        k, w, v = k[off], w[off], v[off]
        u = np.take(self._vpos, w, axis=0) - np.take(self._vpos, v, axis=0)
        sines = -np.einsum("ij,ij->i", u, np.take(self._vaxis, v, axis=0)) / np.linalg.norm(u, axis=1)
        # sorted by vertex, then sin β rounded down to 2^-40 (conservative: a lower sin β reads
        # more), as one integer key
        grid = np.floor((sines + 1.0) * SINE_GRID).astype(np.int64)
        order = np.argsort((k << 42) | grid)
        k, w, sines = k[order], w[order], grid[order] / SINE_GRID - 1.0
        start = np.searchsorted(k, np.arange(len(vertices) + 1))
        head = np.arange(len(k)) - start[k] <= VERTEX_READ
        k, w, sines = k[head], w[head], sines[head]
        return (radius, np.searchsorted(k, np.arange(len(vertices) + 1)), sines, w)














    # -- queries (geom frame) ---------------------------------------------------------------










def _label(model: mujoco.MjModel, geom: int, mesh: int, geom_name: str) -> str:
    """How warnings name a mesh: geom, mesh asset and file when known."""
    mesh_name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_MESH, mesh) or f"#{mesh}"
    parts = [f"geom {geom_name!r}"]
    adr = int(model.mesh_pathadr[mesh])
    if adr >= 0:
        path = bytes(model.paths[adr:]).split(b"\0", 1)[0].decode(errors="replace")
        if path:
            parts.append(f"file {path!r}")
    return f"{mesh_name!r} ({', '.join(parts)})"
