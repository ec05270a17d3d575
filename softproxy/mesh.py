"""A mesh geom for the god-object: its own triangles, checked, and the tables the engine reads.

MuJoCo collides a mesh geom through its convex hull, so a finger pressed into a bowl would
stop on the plane of the rim. The engine's mesh queries (`softproxy.compiled.mesh`: exact
distance, sweep of the proxy's sphere) answer on the triangles themselves; this module gets
those triangles ready, once, when a world is loaded (numpy; nothing here runs in the tick):

- `validate_mesh` checks and repairs the triangles MuJoCo compiled (`model.mesh_vert`, in
  the frame of `data.geom_xpos` / `geom_xmat`): coincident vertices welded, degenerate and
  duplicate triangles dropped, winding made consistent, inverted normals flipped, open and
  non-manifold meshes reported, each defect a `MeshWarning` naming geom, mesh and file.
- `MeshShape`, the `Shape` of a mesh geom, builds what `softproxy.compiled.mesh.mesh_tables`
  and `softproxy.compiled.certificate.certificate_tables` pack into the tables T and C. Per
  triangle: its corners, edges, plane, the angle-weighted pseudo-normals of its face, edges
  and vertices (they sign the distance on a watertight mesh; Bærentzen & Aanæs 2005), its
  vertex normals (force shading) and the triangles across its edges. Per vertex: its fan,
  the edges leaving it and the cone of tangent planes that hold its fan behind them. And
  the kept certificates: per face and side the few triangles near it rising above its plane
  (`_face_tables`), per vertex the vertices near it by how far below its cone they lie
  (`_vertex_tables`), built for every face and vertex at once over the reach of a
  KEPT_RADIUS proxy at load, and of a larger one by `prepare`.
A watertight mesh has an inside (signed distance); an open or non-manifold one is a
two-sided sheet (unsigned distance, both sides solid).
"""

from __future__ import annotations

import warnings

import mujoco
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from softproxy.compiled.certificate import ABOVE_TOL, STATIC_ABOVE, VERTEX_READ
from softproxy.compiled.layout import GEOM_MESH
from softproxy.compiled.tolerances import CONTACT_TOL
from softproxy.geometry import Shape

KEPT_RADIUS = 0.005
"""Proxy radius (m) the kept certificates are built for at load, for every face and vertex at
once; `prepare` builds them for a larger proxy (a query beyond their reach scans the grid)."""
KEPT_STEP = 0.002
"""How far (m) a sweep may move and still be covered by the certificates built for its radius."""
RISING_VERTICES = 4 * STATIC_ABOVE
"""A face with more vertices than this rising above its plane near it is taken as concave at
once (its rising triangles are not gathered)."""
PAIR_CHUNK = 2048
"""Points per numpy pass when gathering the vertices near every face or vertex (bounds memory)."""
SINE_GRID = 2.0 ** 40
"""Steps per unit a kept vertex table's sin β is rounded down to (≈1e-12) for one sort."""
DEGENERATE = 1e-6
"""A triangle whose area is below this fraction of its longest edge squared is degenerate
(zero-area: coincident or collinear vertices, within float32 rounding)."""


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
    Arrays in the geom frame (m); a triangle's features are 0 its face, 1-3 its edges AB,
    BC, CA, 4-6 its vertices A, B, C.
    """

    gtype = GEOM_MESH
    __slots__ = (
        "signed", "shading", "defects", "triangles", "_tri", "_edges", "_plane", "_pn", "_vn", "_adj", "_tv",
        "_centre", "_rhos", "_rho", "_vpos", "_vtree", "_vcone", "_ring", "_fan", "_vt_start", "_vt_tris",
        "_edge_keys", "_clear", "_kept", "_vtable",
    )

    def __init__(self, model: mujoco.MjModel, data: mujoco.MjData, geom: int, static: bool,
                 shading: bool = False, triangles=None) -> None:
        super().__init__(model, data, geom, static)
        if triangles is None:
            mesh = int(model.geom_dataid[geom])
            if int(model.geom_type[geom]) != int(mujoco.mjtGeom.mjGEOM_MESH) or mesh < 0:
                raise ValueError(f"geom {self.name!r} is not a mesh geom: give its triangles=(vertices, faces)")
            va, vn = int(model.mesh_vertadr[mesh]), int(model.mesh_vertnum[mesh])
            fa, fn = int(model.mesh_faceadr[mesh]), int(model.mesh_facenum[mesh])
            vertices = np.array(model.mesh_vert[va:va + vn], dtype=np.float64)
            faces = np.array(model.mesh_face[fa:fa + fn], dtype=np.int64)
            label = _label(model, geom, mesh, self.name)
        else:
            vertices, faces = _explicit(triangles, self.name)
            label = f"'triangles' (geom {self.name!r})"
        vertices, faces, self.defects, self.signed = _clean(vertices, faces, label, warn=True)
        self.shading = bool(shading)
        self.triangles = len(faces)
        # the bounding sphere about the geom origin that the god-object's broad phase uses
        used = vertices[np.unique(faces)]
        self.rbound = float(np.sqrt((used * used).sum(1)).max()) * (1.0 + 1e-12) + 1e-12
        self._build(vertices, faces)
        self._clear: dict = {}  # face i (or -1 - i, its back) -> (reach (m), triangles rising above it), or (-1, None)
        self._kept = 0.0        # the reach (m) every face's and vertex's certificate holds over
        self._vtable = None     # `_vertex_tables` over every vertex
        self.prepare(KEPT_RADIUS)

    # -- load-time tables ---------------------------------------------------------------
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
        self._tri = np.column_stack([a, b, c, ab, ac, n, aa, abac, cc, inv])
        self._plane = np.column_stack([n, (n * a).sum(1)])  # unit normal, offset n·A (m)
        # edges AB, BC, CA as (start, unit direction, length): the swept cylinders
        starts = np.stack([a, b, c], axis=1)
        vecs = np.stack([b - a, c - b, a - c], axis=1)
        lengths = np.linalg.norm(vecs, axis=2)
        self._edges = np.concatenate([starts, vecs / lengths[..., None], lengths[..., None]], axis=2)
        # each triangle's bounding sphere about its centre (the certificates' reach tests)
        centre = (a + b + c) / 3.0
        self._centre = centre
        self._rhos = np.sqrt(np.max([((a - centre) ** 2).sum(1), ((b - centre) ** 2).sum(1),
                                     ((c - centre) ** 2).sum(1)], axis=0))
        self._rho = float(self._rhos.max())

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
        self._adj = adj.reshape(-1, 3)
        fv = vnormal[f]                            # (faces, 3 vertices, 3)
        self._pn = np.concatenate([n[:, None, :], enormal, fv], axis=1)  # face, edges AB BC CA, vertices A B C
        self._vn = fv.reshape(-1, 9)               # the vertex normals at A, B, C (force shading)

        # vertex fans, for the certificate of a nearest point on a vertex: each triangle's
        # three vertex ids; per vertex its triangles (ascending), the edges to its ring of
        # neighbours (from the vertex, each with a triangle on it), and a circular cone (axis,
        # cosine) of directions n that see every edge going away (n·e <= 0): inside it, the
        # whole fan lies behind the tangent plane of normal n at the vertex
        self._tv = f
        order = np.argsort(f.reshape(-1), kind="stable")
        bounds = np.searchsorted(f.reshape(-1)[order], np.arange(len(v) + 1))
        self._vt_start, self._vt_tris = bounds, order // 3
        self._fan = np.split(self._vt_tris, bounds[1:-1])
        pairs = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        pairs = np.unique(np.concatenate([pairs, pairs[:, ::-1]]), axis=0)  # v -> w, sorted
        pstart = np.searchsorted(pairs[:, 0], np.arange(len(v) + 1))
        self._edge_keys = pairs[:, 0] * len(v) + pairs[:, 1]
        evec = v[pairs[:, 1]] - v[pairs[:, 0]]
        eunit = evec / np.linalg.norm(evec, axis=1)[:, None]
        # the first triangle (in face order) on each undirected edge
        undirected = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
        ukeys, at = np.unique(undirected[:, 0] * len(v) + undirected[:, 1], return_index=True)
        lo, hi = np.minimum(pairs[:, 0], pairs[:, 1]), np.maximum(pairs[:, 0], pairs[:, 1])
        on_edge = at[np.searchsorted(ukeys, lo * len(v) + hi)] // 3
        self._ring = np.split(np.column_stack([evec, on_edge]), pstart[1:-1])
        cones = np.empty((len(v), 4))
        cones[:, :3] = vnormal
        for i in range(len(v)):
            s0, s1 = pstart[i], pstart[i + 1]
            cos = 2.0  # no cone: a vertex without edges
            if s1 > s0:
                # the largest cone about the vertex normal inside {n: n·e <= 0 for every edge e}
                smin = float((-(eunit[s0:s1] @ vnormal[i])).min())
                cos = float(np.sqrt(max(0.0, 1.0 - smin * smin))) + 1e-12 if smin > 0.0 else 2.0
            cones[i, 3] = cos
        self._vcone = cones
        self._vpos, self._vtree = v, cKDTree(v)

    # -- certificates kept for the mesh's lifetime ------------------------------------------------
    def prepare(self, radius: float) -> bool:
        """Build the kept certificates of every face and vertex (numpy, all at once) for a proxy
        of `radius` (m) sweeping up to KEPT_STEP, so that its queries find them (beyond their
        reach a query scans the grid). True when they grew (the engine's tables must be rebuilt);
        load builds them for KEPT_RADIUS."""
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
        h = np.einsum("ij,ij->i", np.take(self._vpos, w, axis=0), np.take(self._plane[:, :3], face, axis=0))
        h -= np.take(self._plane[:, 3], face)
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
        sines = -np.einsum("ij,ij->i", u, np.take(self._vcone[:, :3], v, axis=0)) / np.linalg.norm(u, axis=1)
        # sorted by vertex, then sin β rounded down to 2^-40 (conservative: a lower sin β reads
        # more), as one integer key
        grid = np.floor((sines + 1.0) * SINE_GRID).astype(np.int64)
        order = np.argsort((k << 42) | grid)
        k, w, sines = k[order], w[order], grid[order] / SINE_GRID - 1.0
        start = np.searchsorted(k, np.arange(len(vertices) + 1))
        head = np.arange(len(k)) - start[k] <= VERTEX_READ
        k, w, sines = k[head], w[head], sines[head]
        return (radius, np.searchsorted(k, np.arange(len(vertices) + 1)), sines, w)


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
