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

import bisect
import math
import warnings

import mujoco
import numpy as np
import trimesh
from scipy.spatial import cKDTree

from softproxy.geometry import CONTACT_TOL, FACE_PARALLEL, GRAZE, Shape

ABOVE_TOL = 1e-9
"""A vertex this far (m) above a certificate plane counts as above it. MuJoCo stores vertices
in float32 (≈4e-9 m at 5 cm), so coplanar neighbours differ by about this much; a certified
distance may be overstated by at most this (m)."""
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
STATIC_ABOVE = 8
"""Most triangles reaching above a face's plane that its kept certificate lists (and a query
then reads: e.g. a vertex a rounding above a coplanar neighbour brings its fan of ~6); more,
and the face is on a concave patch: the neighbourhood's lists serve it."""
VERTEX_READ = 64
"""Most vertices a kept vertex certificate tests against a tangent plane tilted from its cone's
axis (those whose sin β is below the tilt's sine); more, and the neighbourhood serves it."""
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
POINT_RADIUS = 1e-8
"""A point proxy (r = 0) is swept as a sphere this big (m). On an edge or a vertex the direction
from the nearest point to a point lying on it is rounding noise, so whether it moves into the
mesh is not decidable; 10 nm gives it a direction and is far below the 1 µm promise."""
DEGENERATE = 1e-6
"""A triangle whose area is below this fraction of its longest edge squared is degenerate
(zero-area: coincident or collinear vertices, within float32 rounding)."""
GRID_CELLS = 64
"""Most grid cells per axis."""
WALK_STEPS = 8
"""Most steps from a vertex to a nearer triangle around it before a query reads the fan."""
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

def _closest(t, px, py, pz):
    """Closest point of triangle t to p: (squared distance, qx, qy, qz, feature). Ericson's
    Voronoi-region walk, with the dot products about B and C derived from those about A."""
    ax, ay, az, bx, by, bz, cx, cy, cz, ux, uy, uz, vx, vy, vz, nx, ny, nz, aa, ab, cc, _ = t
    wx, wy, wz = px - ax, py - ay, pz - az
    d1 = ux * wx + uy * wy + uz * wz
    d2 = vx * wx + vy * wy + vz * wz
    if d1 <= 0.0 and d2 <= 0.0:
        return (wx * wx + wy * wy + wz * wz, ax, ay, az, 4)
    d3 = d1 - aa
    d4 = d2 - ab
    if d3 >= 0.0 and d4 <= d3:
        ex, ey, ez = px - bx, py - by, pz - bz
        return (ex * ex + ey * ey + ez * ez, bx, by, bz, 5)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        s = d1 / aa
        qx, qy, qz = ax + s * ux, ay + s * uy, az + s * uz
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, 1)
    d5 = d1 - ab
    d6 = d2 - cc
    if d6 >= 0.0 and d5 <= d6:
        ex, ey, ez = px - cx, py - cy, pz - cz
        return (ex * ex + ey * ey + ez * ez, cx, cy, cz, 6)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        s = d2 / cc
        qx, qy, qz = ax + s * vx, ay + s * vy, az + s * vz
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, 3)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and d4 >= d3 and d5 >= d6:
        s = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        qx, qy, qz = bx + s * (cx - bx), by + s * (cy - by), bz + s * (cz - bz)
        ex, ey, ez = px - qx, py - qy, pz - qz
        return (ex * ex + ey * ey + ez * ez, qx, qy, qz, 2)
    h = nx * wx + ny * wy + nz * wz  # inside the face's prism: straight down to the plane
    return (h * h, px - h * nx, py - h * ny, pz - h * nz, 0)


def _sweep_triangle(t, edges, ax, ay, az, dx, dy, dz, r, dd, far2, graze, close=None):
    """First touch of a sphere (radius r) from a moving by d into triangle t, in the geom frame.

    Returns (lam, nx, ny, nz, feature) with lam in [0, 1), n the unit normal of the inflated
    triangle at the touch (out of it, against the motion) and the feature touched, or None. `dd` = |d|², `far2` =
    (r + |d| + CONTACT_TOL)², `graze` = GRAZE |d|; `close`: `_closest(t, a)` when the caller has it.
    """
    nx, ny, nz = t[15], t[16], t[17]
    h0 = nx * (ax - t[0]) + ny * (ay - t[1]) + nz * (az - t[2])
    hd = nx * dx + ny * dy + nz * dz
    h1 = h0 + hd
    reach = r + CONTACT_TOL
    if (h0 > reach and h1 > reach) or (h0 < -reach and h1 < -reach):
        return None  # the segment never comes within r of the triangle's plane
    d2, qx, qy, qz, feature = _closest(t, ax, ay, az) if close is None else close
    if d2 > far2:
        return None  # farther than the sphere can reach on this segment
    if d2 <= reach * reach:
        # touching now: a hit only if moving into it (the inflated triangle is convex)
        dist = math.sqrt(d2)
        if dist > 1e-12:
            mx, my, mz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
        elif hd != 0.0:  # centre on the triangle (a point proxy): the side it comes from
            s = -1.0 if hd > 0.0 else 1.0
            mx, my, mz = s * nx, s * ny, s * nz
        else:
            return None
        if mx * dx + my * dy + mz * dz < -graze:
            return (0.0, mx, my, mz, feature)
        return None
    # 1. the face: the slab |h| <= r is entered at most once; if the sphere enters it over
    #    the triangle's interior, nothing of the inflated triangle was reached before
    if h0 > r or h0 < -r:
        s = 1.0 if h0 > 0.0 else -1.0
        rate = s * hd
        if rate >= -graze:
            return None  # moving along or away from the plane: the slab is never entered
        lam = (s * h0 - r) / -rate
        if lam >= 1.0:
            return None
        wx = ax + lam * dx - s * r * nx - t[0]
        wy = ay + lam * dy - s * r * ny - t[1]
        wz = az + lam * dz - s * r * nz - t[2]
        d1 = t[9] * wx + t[10] * wy + t[11] * wz
        d2 = t[12] * wx + t[13] * wy + t[14] * wz
        inv = t[21]
        v = (t[20] * d1 - t[19] * d2) * inv
        w = (t[18] * d2 - t[19] * d1) * inv
        if v >= 0.0 and w >= 0.0 and v + w <= 1.0:
            return (lam, s * nx, s * ny, s * nz, 0)
    # 2. the edges (cylinders of radius r; their ends belong to the vertex balls)
    best = 1.0
    hit = None
    for feature, (px, py, pz, ex, ey, ez, length) in enumerate(edges, 1):
        wx, wy, wz = ax - px, ay - py, az - pz
        we = wx * ex + wy * ey + wz * ez
        de = dx * ex + dy * ey + dz * ez
        qa = dd - de * de
        qb = wx * dx + wy * dy + wz * dz - we * de
        if qa <= 0.0 or qb >= 0.0:
            continue  # along the edge, or moving away from its axis
        qc = wx * wx + wy * wy + wz * wz - we * we - r * r
        if qc <= 0.0:
            continue  # already within r of the axis, beyond the edge's ends: a vertex ball first
        disc = qb * qb - qa * qc
        if disc <= 0.0:
            continue
        lam = (-qb - math.sqrt(disc)) / qa
        if lam < best:
            s = we + lam * de
            if 0.0 <= s <= length:
                best = lam
                hit = (wx + lam * dx - s * ex, wy + lam * dy - s * ey, wz + lam * dz - s * ez, feature)
    # 3. the vertices (balls of radius r)
    for k in (0, 3, 6):
        wx, wy, wz = ax - t[k], ay - t[k + 1], az - t[k + 2]
        qb = wx * dx + wy * dy + wz * dz
        if qb >= 0.0:
            continue
        qc = wx * wx + wy * wy + wz * wz - r * r
        disc = qb * qb - dd * qc
        if disc <= 0.0:
            continue
        lam = (-qb - math.sqrt(disc)) / dd
        if lam < best:
            best = lam
            hit = (wx + lam * dx, wy + lam * dy, wz + lam * dz, 4 + k // 3)
    if hit is None:
        return None
    mx, my, mz, feature = hit
    n = math.sqrt(mx * mx + my * my + mz * mz)
    mx, my, mz = mx / n, my / n, mz / n
    if mx * dx + my * dy + mz * dz >= -graze:
        return None  # a tangent graze: the sphere touches without entering
    return (best if best > 0.0 else 0.0, mx, my, mz, feature)


# ---------------------------------------------------------------------------------------
# The shape
# ---------------------------------------------------------------------------------------

def _rows(a: np.ndarray) -> list:
    """The rows of a 2-d array as tuples of floats (the hot path's form)."""
    return list(map(tuple, a.tolist()))


def _convex_edge(t, u, nx: float, ny: float, nz: float, side0: float, dot0: float):
    """Whether the tangent plane of normal n at a point on the edge between triangle t (n on
    its side side0, dot0 = n·t's normal) and its neighbour u holds both faces behind it:
    (side1, coplanar) when n lies in the cone of the two faces' outward normals (a convex
    edge seen from outside; coplanar faces: n must be their own normal, since a sphere
    touching the edge from beside it is not held by the plane), else None (concave, folded)."""
    dot1 = nx * u[15] + ny * u[16] + nz * u[17]
    side1 = 1.0 if dot1 >= 0.0 else -1.0
    g = side0 * side1 * (t[15] * u[15] + t[16] * u[16] + t[17] * u[17])
    det = 1.0 - g * g
    a0, a1 = side0 * dot0, side1 * dot1
    if det < 1e-12:
        return (side1, True) if g > 0.0 and a0 > 1.0 - 1e-9 else None
    if a0 - g * a1 < -1e-12 * det or a1 - g * a0 < -1e-12 * det:
        return None  # n outside the cone: a concave edge
    return (side1, False)


class MeshShape(Shape):
    """A mesh geom's triangles as seen by a proxy (world frame in, world frame out; m).

    `MeshShape(model, data, geom, static)` like the primitives; `shading=True` returns the
    normal interpolated from the vertex normals over a face (force shading) instead of the
    faceted one; the sweep still stops on the true triangles. Pass `mesh_shape=MeshShape`
    to `shapes_of` / `World` (`functools.partial(MeshShape, shading=True)` for shading).
    """

    flat = False
    __slots__ = (
        "mesh", "label", "signed", "shading", "defects", "triangles", "_tri", "_edges", "_pn", "_vn", "_adj", "_plane",
        "_ep", "_ev", "_eil", "_em", "_fn", "_q", "_abc", "_faces", "_sph", "_rhos", "_tv", "_fan", "_ring", "_vcone", "_centre", "_rho", "_slack",
        "_grid_lo", "_grid_h", "_grid_dims", "_grid_start", "_grid_order",
        "_cx", "_cy", "_cz", "_cr", "_cslack", "_cd", "_ci", "_cids", "_cpos", "_above", "_vmemo", "_work", "_hint", "rebuilds",
        "_recent", "_dkey", "_dval", "_skey", "_sval", "_clear", "_vclear",
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
        self._cx = self._cy = self._cz = 0.0
        self._cr = -1.0  # no neighbourhood yet
        self._cslack = 0.0
        self._cd: list = []
        self._ci: list = []
        self._cids = None
        self._cpos: dict = {}
        self._above: dict = {}
        self._vmemo: dict = {}
        self._work = 0
        self._hint = -1
        self.rebuilds = 0  # how often the neighbourhood was rebuilt
        # the triangles sweeps last stopped on (RECENT_HITS at most, newest last): [triangle,
        # sphere centre at the touch (geom frame), whether the hit before was there too]
        self._recent: list = []
        self._dkey = None  # the last distance query (geom frame) and its answer
        self._dval = None
        self._skey = None  # a sweep's start point (geom frame) and its certified nearest point
        self._sval = None
        self._clear: dict = {}   # face (i, or -1 - i for its back) -> radius checked clear (m), or -1
        self._vclear: dict = {}  # vertex -> (radius checked (m), sin β, vertices, threshold on c²)
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
    def _cells(self, cx: float, cy: float, cz: float, radius: float):
        """Ids (numpy) of the triangles in the grid cells a ball about c (m) overlaps, grown by
        the largest triangle: every triangle that may come within `radius` of c; None if none."""
        reach = radius + self._rho
        (lx, ly, lz), h, (nx, ny, nz) = self._grid_lo, self._grid_h, self._grid_dims
        x0, x1 = max(0, int((cx - reach - lx) // h)), min(nx - 1, int((cx + reach - lx) // h))
        y0, y1 = max(0, int((cy - reach - ly) // h)), min(ny - 1, int((cy + reach - ly) // h))
        z0, z1 = max(0, int((cz - reach - lz) // h)), min(nz - 1, int((cz + reach - lz) // h))
        start, order = self._grid_start, self._grid_order
        chunks = []
        if z0 <= z1:  # one slice per column
            for ix in range(x0, x1 + 1):
                for iy in range(y0, y1 + 1):
                    row = (ix * ny + iy) * nz
                    s, e = start[row + z0], start[row + z1 + 1]
                    if e > s:
                        chunks.append(order[s:e])
        if not chunks:
            return None
        return np.concatenate(chunks) if len(chunks) > 1 else chunks[0]

    # -- certificates kept for the mesh's lifetime ------------------------------------------------
    def prepare(self, radius: float) -> None:
        """Build the kept certificates of every face and vertex (numpy, all at once) for a proxy
        of `radius` (m) sweeping up to KEPT_STEP, so that its queries never build one in the
        servo tick; call it when a proxy larger than KEPT_RADIUS is made (load builds those)."""
        kept = 2.0 * (radius + CONTACT_TOL) + KEPT_STEP
        if kept <= self._kept:
            return
        self._clear.update(self._face_tables(np.arange(self.triangles), kept))
        self._vtable = self._vertex_tables(np.arange(len(self._vpos)), kept)
        self._vclear = {}
        self._kept = kept

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

    def _face_clear(self, i: int, side: float, need: float):
        """The triangles within `need` (m) of triangle i that reach above its plane on `side`, as
        a tuple of at most STATIC_ABOVE ids (e.g. a coplanar neighbour a rounding above it), or
        None when there are more (a concave patch): every other triangle that near lies behind
        the tangent plane. Built for every face at load or by `prepare`; a need beyond that
        builds this face's over twice the need, here."""
        key = i if side > 0.0 else -1 - i
        got = self._clear.get(key)
        if got is None or 0.0 <= got[0] < need:
            self._clear.update(self._face_tables(np.array([i]), 2.0 * need))
            got = self._clear[key]
        return got[1]

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

    def _vertex_clear(self, vertex: int, need: float):
        """The vertex certificate's table over every triangle within `need` (m) of the vertex:
        (radius checked (m), sin β ascending (the first VERTEX_READ + 1), the vertices in that
        order, threshold). A tangent plane with the fan behind it, at cosine c from the cone's
        axis, has every such triangle behind it when c > 0 and c² > the threshold (2.0 when none
        is certified by angle alone), else all but those on a vertex with sin β < sin α that
        rises above it. Read from the table built at load or by `prepare` on first touch (a few
        µs); a need beyond it builds this vertex's over twice the need, here."""
        table = self._vtable
        k = vertex
        if need > table[0]:
            table, k = self._vertex_tables(np.array([vertex]), 2.0 * need), 0
        radius, start, sines, ids = table
        sines, ids = sines[start[k]:start[k + 1]].tolist(), ids[start[k]:start[k + 1]].tolist()
        s0 = (sines[0] if sines else 1.0) - 1e-12
        got = (radius, sines, ids, 1.0 - s0 * s0 if s0 > 0.0 else 2.0)
        self._vclear[vertex] = got
        return got

    def _static_clear(self, hint: int, feature: int, nx: float, ny: float, nz: float, need: float):
        """The few triangles within `need` (m) of the hint's nearest point q that may reach above
        the tangent plane there (normal n, out of the hint), as a tuple, by the certificates kept
        for the mesh's lifetime (`_face_clear`, `_vertex_clear`); every other triangle that near
        lies behind the plane, and no neighbourhood is needed. None when they do not hold. A point
        p at distance d from q has no nearer triangle off the tuple when need >= 2d; a sphere of
        radius r touching at p and sliding by L on or above that plane enters none when
        need >= 2r + L."""
        t = self._tri[hint]
        dot0 = nx * t[15] + ny * t[16] + nz * t[17]
        side0 = 1.0 if dot0 >= 0.0 else -1.0
        clear = self._clear
        if feature == 0:
            got = clear.get(hint if side0 > 0.0 else -1 - hint)
            if got is not None and (got[0] >= need or got[0] < 0.0):  # `_face_clear` without the call
                return got[1]
            return self._face_clear(hint, side0, need)
        if feature > 3:
            vertex = self._tv[hint][feature - 4]
            ax, ay, az, cos = self._vcone[vertex]
            c = nx * ax + ny * ay + nz * az
            if c <= 0.0:
                return None
            if c < cos:
                for ex, ey, ez, _ in self._ring[vertex]:
                    if nx * ex + ny * ey + nz * ez > ABOVE_TOL:
                        return None
            got = self._vclear.get(vertex)
            if got is None or got[0] < need:
                got = self._vertex_clear(vertex, need)
            if c * c > got[3]:
                return ()
            # the few vertices with sin β < sin α, each against the tangent plane; the triangles
            # on those above it are read
            m = bisect.bisect_left(got[1], math.sqrt(max(0.0, 1.0 - c * c)) + 1e-12)  # c may round above 1
            if m > VERTEX_READ:
                return None
            k3 = 3 * (feature - 4)
            off = nx * t[k3] + ny * t[k3 + 1] + nz * t[k3 + 2] + ABOVE_TOL
            vxyz, few = self._vxyz, ()
            for w in got[2][:m]:
                x, y, z = vxyz[w]
                if nx * x + ny * y + nz * z > off:
                    few = self._fan[w].union(few)
                    if len(few) > STATIC_ABOVE:
                        return None
            return tuple(few)
        other = self._adj[hint][feature - 1]
        if other < 0:
            return None
        edge = _convex_edge(t, self._tri[other], nx, ny, nz, side0, dot0)
        if edge is None:
            return None
        side1 = edge[0]
        got = clear.get(hint if side0 > 0.0 else -1 - hint)
        first = got[1] if got is not None and (got[0] >= need or got[0] < 0.0) else self._face_clear(hint, side0, need)
        if first is None:
            return None
        got = clear.get(other if side1 > 0.0 else -1 - other)
        second = got[1] if got is not None and (got[0] >= need or got[0] < 0.0) else self._face_clear(other, side1, need)
        if second is None:
            return None
        return first + second if second else first

    def _neighbourhood(self, cx: float, cy: float, cz: float, radius: float, slack: float) -> None:
        """Cache the triangles that may lie within `radius` (m) of c, sorted by a lower bound on
        their distance: the larger of sqrt(h² + b²), h the height over the plane, b how far c
        lies beyond the farthest edge line (exact over the face and most of the edges, short of
        it near a vertex), and the distance to the triangle's bounding sphere about its centre.
        `slack` (m): how far queries may drift from c before a new one pays. A ball inside the
        current one (re-centred after a drift) is gathered from the current triangles, not the grid."""
        self.rebuilds += 1
        ex, ey, ez = cx - self._cx, cy - self._cy, cz - self._cz
        inside = self._cids is not None and math.sqrt(ex * ex + ey * ey + ez * ez) + radius <= self._cr
        self._cx, self._cy, self._cz, self._cr, self._cslack = cx, cy, cz, radius, slack
        self._above = {}
        self._vmemo = {}
        self._work = 0
        ids = self._cids if inside else self._cells(cx, cy, cz, radius)
        if ids is None:
            self._cd, self._ci, self._cids, self._cpos = [], [], None, {}
            return
        # the bounding spheres first: only the triangles whose sphere meets the ball go on
        # (np.take: a third of fancy indexing's cost here)
        take = np.take
        c4 = np.array((cx, cy, cz, 1.0))
        sphere = take(self._sph, ids, axis=0) @ c4
        sphere += cx * cx + cy * cy + cz * cz
        np.maximum(sphere, 0.0, out=sphere)
        np.sqrt(sphere, out=sphere)
        sphere -= take(self._rhos, ids)
        keep = np.flatnonzero(sphere <= radius)
        ids, sphere = take(ids, keep), take(sphere, keep)
        # then one matrix product (k, 16) @ (16, 4): height, beyond each edge line
        p = np.zeros((16, 4))
        for j in range(4):
            p[4 * j:4 * j + 4, j] = c4
        v = take(self._q, ids, axis=0) @ p
        beyond = np.maximum(np.maximum(v[:, 1], v[:, 2]), v[:, 3])
        np.maximum(beyond, 0.0, out=beyond)
        beyond *= beyond
        bound = v[:, 0]
        bound *= bound
        bound += beyond
        np.maximum(sphere, 0.0, out=sphere)
        sphere *= sphere
        np.maximum(bound, sphere, out=bound)
        keep = np.flatnonzero(bound <= radius * radius)
        bound, ids = take(bound, keep), take(ids, keep)
        sort = np.argsort(bound)
        self._cd = np.sqrt(take(bound, sort)).tolist()
        ids = take(ids, sort)
        self._cids = ids
        self._ci = ids.tolist()
        self._cpos = dict.fromkeys(self._ci)

    def _distances(self, p: np.ndarray, ids: np.ndarray) -> np.ndarray:
        """Exact distances (m) from point p to triangles `ids`: the plane inside the triangle,
        else the nearest of its three edges."""
        w = p - np.take(self._ep, ids, axis=0)         # (k, 3 edges, 3)
        ev = np.take(self._ev, ids, axis=0)
        t = np.clip(np.einsum("kij,kij->ki", w, ev) * np.take(self._eil, ids, axis=0), 0.0, 1.0)
        diff = w - t[..., None] * ev
        edge2 = np.einsum("kij,kij->ki", diff, diff).min(axis=1)
        inside = (np.einsum("kij,kij->ki", w, np.take(self._em, ids, axis=0)) <= 0.0).all(axis=1)
        h = np.einsum("kj,kj->k", w[:, 0], np.take(self._fn, ids, axis=0))
        return np.sqrt(np.where(inside, h * h, edge2))

    def _above_list(self, i: int, side: float, n: int) -> list:
        """Neighbourhood positions below n of the triangles reaching above triangle i's plane
        on `side` (a vertex higher than ABOVE_TOL). Built lazily, as far as scans have read."""
        key = i if side > 0.0 else -1 - i
        memo = self._above.get(key)
        if memo is None:
            memo = self._above[key] = [0, []]
        done, out = memo
        if n > done:
            nx, ny, nz, off = self._plane[i]
            if side < 0.0:
                nx, ny, nz, off = -nx, -ny, -nz, -off
            off += ABOVE_TOL
            if n - done > BATCH_MIN:
                # many positions at once (a new hint after a rebuild): one batched test
                h = np.take(self._abc, self._cids[done:n], axis=0) @ np.array((nx, ny, nz))
                out.extend((np.flatnonzero((h > off).any(axis=1)) + done).tolist())
            else:
                tris, ci = self._tri, self._ci
                for k in range(done, n):
                    t = tris[ci[k]]
                    if (nx * t[0] + ny * t[1] + nz * t[2] > off or nx * t[3] + ny * t[4] + nz * t[5] > off
                            or nx * t[6] + ny * t[7] + nz * t[8] > off):
                        out.append(k)
            memo[0] = n
            return out
        return out[:bisect.bisect_left(out, n)] if out and out[-1] >= n else out

    def _shortlist(self, positions, n: int, x: float, y: float, z: float, radius: float):
        """The neighbourhood positions below n (all, or those in `positions`) worth a scalar
        test from p; when there are many, only those whose exact distance is within `radius`
        (one vectorised pass instead of a long scalar scan)."""
        if positions is None:
            if n <= VECTOR_MIN:
                return range(n)
            positions = np.arange(n)
        else:
            positions = positions[:bisect.bisect_left(positions, n)]
            if len(positions) <= VECTOR_MIN:
                return positions
            positions = np.array(positions)
        dist = self._distances(np.array((x, y, z)), self._cids[positions])
        return positions[dist <= radius + CONTACT_TOL].tolist()

    def _certified(self, hint: int, feature: int, nx: float, ny: float, nz: float, n: int):
        """Neighbourhood positions that may come nearer than the tangent plane (normal n, out of
        the hint at its closest point q), among the first n, or None (read them all).

        A triangle wholly behind the hint's plane lies in the half-space behind the tangent
        plane when q is inside the face. When q is on an edge shared with a neighbour and n
        lies in the cone of the two faces' normals (a convex edge seen from outside), the
        wedge behind both planes lies behind the tangent plane: a triangle behind both is
        safe. Only those reaching above the plane(s) are left to read."""
        t = self._tri[hint]
        dot0 = nx * t[15] + ny * t[16] + nz * t[17]
        side0 = 1.0 if dot0 >= 0.0 else -1.0
        above = self._above
        if feature == 0:
            memo = above.get(hint if side0 > 0.0 else -1 - hint)
            if memo is not None and memo[0] >= n:  # `_above_list` without the call
                out = memo[1]
                return out if not out or out[-1] < n else out[:bisect.bisect_left(out, n)]
            return self._above_list(hint, side0, n)
        if feature > 3:
            return self._vertex_certified(hint, feature, nx, ny, nz, n)
        other = self._adj[hint][feature - 1]
        if other < 0 or other not in self._cpos:
            return None
        edge = _convex_edge(t, self._tri[other], nx, ny, nz, side0, dot0)
        if edge is None:
            return None
        side1, coplanar = edge
        if coplanar:
            return self._merged(self._above_list(hint, side0, n), self._above_list(other, side1, n))
        memo = above.get(hint if side0 > 0.0 else -1 - hint)
        memo1 = above.get(other if side1 > 0.0 else -1 - other)
        if memo is not None and memo1 is not None and memo[0] >= n and memo1[0] >= n and not memo[1] and not memo1[1]:
            return []  # both faces certified clear as far as n, the common case on a convex patch
        return self._merged(self._above_list(hint, side0, n), self._above_list(other, side1, n))

    def _vertex_certified(self, hint: int, feature: int, nx: float, ny: float, nz: float, n: int):
        """`_certified` when q is a vertex v of the hint: the tangent plane there passes through
        v, and a fan triangle (v's own) lies behind it when every edge leaving v does
        (n·e <= ABOVE_TOL; first by the precomputed cone, one dot product). Then the positions
        below n of the triangles left to read, else None. Where 50 thin triangles meet (a
        uv-sphere's pole) this is what keeps a proxy held there cheap.

        A triangle off the fan lies behind the tangent plane too when each of its vertices w
        does. An end of an edge leaving v does (the fan's own test). Any other w is far enough
        below the cone's axis a: with β the angle of u = w - v below the plane normal to a
        (sin β = -a·u / |u|, the least over the triangle's vertices off the ring) and α the
        angle of n from a, the angle between n and u is at least 90° + β - α, so n·u <= 0
        whenever β >= α. sin β depends on v and the triangle only: it is kept per vertex,
        sorted, so a query reads off (one bisection on sin α) the few triangles that may rise
        too close to the plane (on a convex patch of fairly even triangles, none) and tests
        only their vertices against it."""
        vertex = self._tv[hint][feature - 4]
        ax, ay, az, cos = self._vcone[vertex]
        c = nx * ax + ny * ay + nz * az
        if c < cos:
            for ex, ey, ez, _ in self._ring[vertex]:
                if nx * ex + ny * ey + nz * ez > ABOVE_TOL:
                    return None
        memo = self._vmemo.get(vertex)
        if memo is None or n > memo[0]:
            memo = self._vertex_table(vertex, hint, feature, n, memo)
        # the triangles with sin β < sin α (+ a rounding margin) may rise above the plane: at
        # once none when sin α is below the least sin β (1 - c² < s0²), the common case
        if c > 0.0 and c * c > memo[3]:
            return []
        sines = memo[1]
        m = bisect.bisect_left(sines, math.sqrt(max(0.0, 1.0 - c * c)) + 1e-12) if c > 0.0 else len(sines)
        if m == 0:
            return []
        t = self._tri[hint]
        # those few: each vertex against the tangent plane itself
        k3 = 3 * (feature - 4)
        off = nx * t[k3] + ny * t[k3 + 1] + nz * t[k3 + 2] + ABOVE_TOL
        tris, ci = self._tri, self._ci
        keep = []
        for k in memo[2][:m]:
            if k < n:
                u = tris[ci[k]]
                if (nx * u[0] + ny * u[1] + nz * u[2] > off or nx * u[3] + ny * u[4] + nz * u[5] > off
                        or nx * u[6] + ny * u[7] + nz * u[8] > off):
                    keep.append(k)
        if len(keep) > 1:
            keep.sort()
        return keep

    def _fan_ring(self, vertex: int) -> set:
        """The vertex and the far ends of its edges: the vertices of its fan."""
        ring = set()
        for i in self._fan[vertex]:
            ring.update(self._tv[i])
        return ring

    def _least_sines(self, vertex: int, vx: float, vy: float, vz: float, ids: np.ndarray, ring: set) -> np.ndarray:
        """Per triangle in `ids` (numpy, batched), the least sin β of its vertices seen from v
        below the cone's axis; the fan's own vertices count as 1 (behind with the fan)."""
        ax, ay, az, _ = self._vcone[vertex]
        u = np.take(self._abc, ids, axis=0) - np.array((vx, vy, vz))  # (k, 3 vertices, 3)
        norm = np.sqrt((u * u).sum(2))
        sb = -(u @ np.array((ax, ay, az))) / np.where(norm > 0.0, norm, 1.0)
        sb[np.isin(np.take(self._faces, ids, axis=0), list(ring))] = 1.0  # v and the ends of its edges
        return sb.min(axis=1)

    def _vertex_table(self, vertex: int, hint: int, feature: int, n: int, memo):
        """The vertex certificate's table over the neighbourhood positions below n, extended
        from `memo` (positions already done): [done, sin β ascending, positions in that order,
        1 - (least sin β - margin)² (2 when nothing is certified by angle alone)]."""
        if memo is None:
            memo = self._vmemo[vertex] = [0, [], [], 2.0]
        done, sines, out = memo[0], memo[1], memo[2]
        t = self._tri[hint]
        k3 = 3 * (feature - 4)
        vx, vy, vz = t[k3], t[k3 + 1], t[k3 + 2]
        ax, ay, az, _ = self._vcone[vertex]
        fan, ci, tris, tv = self._fan[vertex], self._ci, self._tri, self._tv
        ring = self._fan_ring(vertex)
        if n - done > BATCH_MIN:
            # many positions at once (after a rebuild): batched, merged into the sorted table
            ids = self._cids[done:n]
            least = self._least_sines(vertex, vx, vy, vz, ids, ring)
            offfan = ~np.isin(ids, list(fan))
            sines_all = np.concatenate([np.array(sines), least[offfan]])
            out_all = np.concatenate([np.array(out, dtype=np.int64), np.flatnonzero(offfan) + done])
            order = np.argsort(sines_all, kind="stable")
            memo[1] = sines = sines_all[order].tolist()
            memo[2] = out = out_all[order].tolist()
        else:
            for k in range(done, n):
                i = ci[k]
                if i in fan:
                    continue
                u = tris[i]
                least = 1.0
                for j, w in enumerate(tv[i]):
                    if w in ring:
                        continue  # v or an end of an edge leaving v: behind the plane with the fan
                    j *= 3
                    wx, wy, wz = u[j] - vx, u[j + 1] - vy, u[j + 2] - vz
                    norm = math.sqrt(wx * wx + wy * wy + wz * wz)
                    sb = -(wx * ax + wy * ay + wz * az) / norm
                    if sb < least:
                        least = sb
                at = bisect.bisect_left(sines, least)
                sines.insert(at, least)
                out.insert(at, k)
        memo[0] = n
        s0 = (sines[0] if sines else 1.0) - 1e-12
        memo[3] = 1.0 - s0 * s0 if s0 > 0.0 else 2.0
        return memo

    def _walk(self, hint, d2, qx, qy, qz, feature, x, y, z):
        """From the hint's closest point q to p on an edge or a vertex, step to a nearer triangle:
        across the edge (p may lie over the neighbour's face, or beyond it), or from a vertex to a
        triangle on an edge leaving it that rises above the tangent plane there (it holds a nearer
        point); while there is one (WALK_STEPS at most): then the certificate of the face, edge or
        vertex reached holds more often. Returns (d2, qx, qy, qz, feature, hint)."""
        tris, tv, rings, cones, adj = self._tri, self._tv, self._ring, self._vcone, self._adj
        for _ in range(WALK_STEPS):
            if feature == 0 or d2 <= 0.0:
                break
            if feature < 4:
                step = adj[hint][feature - 1]
            else:
                v = tv[hint][feature - 4]
                dist = math.sqrt(d2)
                nx, ny, nz = (x - qx) / dist, (y - qy) / dist, (z - qz) / dist
                ax, ay, az, cos = cones[v]
                if nx * ax + ny * ay + nz * az >= cos:
                    break
                step = -1
                for ex, ey, ez, t in rings[v]:
                    if nx * ex + ny * ey + nz * ez > ABOVE_TOL:
                        step = t
                        break
            if step < 0:
                break
            c = _closest(tris[step], x, y, z)
            if c[0] >= d2:
                break
            d2, qx, qy, qz, feature = c
            hint = step
        return d2, qx, qy, qz, feature, hint

    @staticmethod
    def _merged(first: list, second: list) -> list:
        """Sorted union of two sorted position lists."""
        if not second:
            return first
        if not first:
            return second
        return sorted(set(first).union(second))

    # -- queries (geom frame) ---------------------------------------------------------------
    def on_face(self, nx: float, ny: float, nz: float) -> bool:
        """True when n (world) is the normal of a triangle the last two sweeps that stopped on
        it stopped at the same point: a proxy held on a face, whose plane holds while the proxy
        stays over the face (the god-object then warm-starts from it, and checks that the proxy
        still touches the mesh after). A sliding proxy is not warm-started: on a curved or
        concave mesh the face planes it leaves behind would cost it a second solve."""
        lx = self.r00 * nx + self.r10 * ny + self.r20 * nz
        ly = self.r01 * nx + self.r11 * ny + self.r21 * nz
        lz = self.r02 * nx + self.r12 * ny + self.r22 * nz
        tris = self._tri
        for i, _, _, _, held in self._recent:
            if held:
                t = tris[i]
                dot = lx * t[15] + ly * t[16] + lz * t[17]
                if dot > FACE_PARALLEL or dot < -FACE_PARALLEL:
                    return True
        return False

    def distance(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        """Signed distance (m) to the nearest triangle and the outward unit normal, world frame.

        `Shape.distance` inlined (the god-object asks this several times a tick). The last
        answer is kept (the god-object asks again about the point it holds), and so is the
        answer a sweep certified for its start point (the god-object then asks about that
        point, where the proxy stayed); both keyed by the point in the geom frame, where the
        triangles never move, so a new pose (`refresh`) changes the key, never the answer."""
        dx, dy, dz = x - self.px, y - self.py, z - self.pz
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (self.r00, self.r01, self.r02, self.r10, self.r11,
                                                       self.r12, self.r20, self.r21, self.r22)
        key = (r00 * dx + r10 * dy + r20 * dz, r01 * dx + r11 * dy + r21 * dz, r02 * dx + r12 * dy + r22 * dz)
        if key == self._dkey:
            d, nx, ny, nz = self._dval
        else:
            if key == self._skey:
                d, nx, ny, nz = self._answer(*key, *self._sval)
            else:
                d, nx, ny, nz = self._answer(*key, *self._nearest(*key))
            self._dkey = key
            self._dval = (d, nx, ny, nz)
        return (d, r00 * nx + r01 * ny + r02 * nz, r10 * nx + r11 * ny + r12 * nz, r20 * nx + r21 * ny + r22 * nz)

    def local_distance(self, x: float, y: float, z: float) -> tuple[float, float, float, float]:
        """`distance` in the geom frame: signed distance (m) and outward unit normal."""
        key = (x, y, z)
        if key == self._dkey:
            return self._dval
        value = self._answer(x, y, z, *(self._sval if key == self._skey else self._nearest(x, y, z)))
        self._dkey = key
        self._dval = value
        return value

    def _answer(self, x, y, z, best, qx, qy, qz, feature, tri) -> tuple[float, float, float, float]:
        """The signed distance and outward normal at p (geom frame) from its nearest point q
        (at distance `best`, m) on `feature` of triangle `tri`."""
        ex, ey, ez = x - qx, y - qy, z - qz
        length = math.sqrt(ex * ex + ey * ey + ez * ez)
        if best > 0.0 and length > 0.0:
            # by its own length, not by `best`: within ~1 nm of the surface p - q carries the
            # rounding of p's coordinates (~1e-18 m), which would leave |n| off 1 by ~1e-9
            nx, ny, nz = ex / length, ey / length, ez / length
        else:
            nx, ny, nz = self._tri[tri][15:18]
        sign = 1.0
        if self.signed:
            px, py, pz = self._pn[tri][feature]
            if (x - qx) * px + (y - qy) * py + (z - qz) * pz < 0.0:
                sign = -1.0  # behind the nearest feature: inside; the normal still points out
                nx, ny, nz = -nx, -ny, -nz
            elif best == 0.0:
                n = math.sqrt(px * px + py * py + pz * pz)
                nx, ny, nz = px / n, py / n, pz / n
        if self.shading and feature <= 3:
            nx, ny, nz = self._shade(tri, qx, qy, qz, nx, ny, nz)
        return (sign * best, nx, ny, nz)

    def _nearest(self, x: float, y: float, z: float):
        """(distance, closest point, feature, triangle) of the nearest triangle, geom frame."""
        tris, planes = self._tri, self._plane
        hint0 = self._hint
        near = None
        if hint0 >= 0:
            # the hint's nearest point, and the certificates kept for the mesh's lifetime: on a
            # convex patch they prove it the nearest, with no neighbourhood
            hint = hint0
            best2, qx, qy, qz, bf = _closest(tris[hint], x, y, z)
            if 1 <= bf <= 3:
                # nearest on an edge: the point may lie over the neighbour's face instead (or
                # beyond it: then walk on)
                other = self._adj[hint][bf - 1]
                if other >= 0:
                    d2, rx, ry, rz, f = _closest(tris[other], x, y, z)
                    if d2 < best2:
                        best2, qx, qy, qz, bf, hint = d2, rx, ry, rz, f, other
            if (bf and hint != hint0) or bf >= 4:  # stepped across an edge, or on a vertex: walk on
                best2, qx, qy, qz, bf, hint = self._walk(hint, best2, qx, qy, qz, bf, x, y, z)
            if best2 > 0.0:
                best = math.sqrt(best2)
                few = self._static_clear(hint, bf, (x - qx) / best, (y - qy) / best, (z - qz) / best, 2.0 * best)
                if few is not None:
                    for i in few:  # the few that may rise above the tangent plane: read them
                        if i != hint:
                            d2, rx, ry, rz, f = _closest(tris[i], x, y, z)
                            if d2 < best2:
                                best2, qx, qy, qz, bf, hint = d2, rx, ry, rz, f, i
                    self._hint = hint
                    return (math.sqrt(best2), qx, qy, qz, bf, hint)
            near = (best2, qx, qy, qz, bf, hint)
        ex, ey, ez = x - self._cx, y - self._cy, z - self._cz
        e = math.sqrt(ex * ex + ey * ey + ez * ez)
        drifted = e > self._cslack
        while True:
            cd, ci = self._cd, self._ci
            best2, bq, bf, bi = math.inf, (0.0, 0.0, 0.0), 0, -1
            positions = None
            n = len(cd)
            hint = hint0
            if e < self._cr and near is not None and hint0 in self._cpos:
                best2, qx, qy, qz, bf, hint = near
                bq, bi = (qx, qy, qz), hint
                best = math.sqrt(best2)
                n = bisect.bisect_left(cd, best + e)
                if best2 > 0.0:
                    # the tangent plane at the hint's nearest point, as a certificate: every
                    # triangle behind it is at least as far
                    positions = self._certified(hint, bf, (x - qx) / best, (y - qy) / best, (z - qz) / best, n)
            best = math.sqrt(best2)
            scan = n if positions is None else len(positions)
            self._work += scan
            if drifted and best + e < self._cr and scan > DRIFT_SCAN and self._work > REBUILD_WORK:
                # a neighbourhood centred here is cheaper to scan (radius kept)
                self._neighbourhood(x, y, z, max(self._cr - e - 1e-12, best + self._cslack), self._cslack)
                e = 0.0
                drifted = False
                continue
            if e < self._cr:
                if positions is None or len(positions) > VECTOR_MIN:  # a certificate's list is cut at n
                    positions = self._shortlist(positions, n, x, y, z, best)
                for k in positions:
                    if cd[k] - e >= best:
                        break
                    i = ci[k]
                    if i == hint:
                        continue
                    nx, ny, nz, off = planes[i]
                    h = nx * x + ny * y + nz * z - off
                    if h >= best or -h >= best:
                        continue  # its plane is already farther than the best
                    d2, qx, qy, qz, f = _closest(tris[i], x, y, z)
                    if d2 < best2:
                        best2, bq, bf, bi = d2, (qx, qy, qz), f, i
                        best = math.sqrt(d2)
            if best + e <= self._cr:
                break
            # the nearest triangle may lie outside the neighbourhood: one around the point,
            # large enough to hold a triangle known to be that near
            bound = best
            if bound == math.inf and ci:
                bound = math.sqrt(_closest(tris[ci[0]], x, y, z)[0])
            if bound == math.inf:
                # nothing cached near: the nearest triangle centre bounds the distance
                c = self._centre - np.array((x, y, z))
                bound = math.sqrt(float(np.einsum("ij,ij->i", c, c).min()))
            slack = max(self._slack, 0.05 * bound)
            self._neighbourhood(x, y, z, bound + slack, slack)
            e = 0.0
        self._hint = bi
        return (best, bq[0], bq[1], bq[2], bf, bi)

    def sweep(self, x0: float, y0: float, z0: float, dx: float, dy: float, dz: float, r: float):
        """First touch of a sphere (radius r, m) moving from x0 by d into a triangle, world frame.

        Returns (fraction in [0, 1), nx, ny, nz) or None, like `Shape.sweep`: a sphere that
        touches a triangle and moves along or away from it is not stopped by it.
        """
        dd = dx * dx + dy * dy + dz * dz
        if dd == 0.0:
            return None
        if r < POINT_RADIUS:
            r = POINT_RADIUS
        length = math.sqrt(dd)
        graze = GRAZE * length
        far = r + length + CONTACT_TOL
        far2 = far * far
        # into the geom frame
        px, py, pz = x0 - self.px, y0 - self.py, z0 - self.pz
        r00, r01, r02, r10, r11, r12, r20, r21, r22 = (self.r00, self.r01, self.r02, self.r10, self.r11,
                                                       self.r12, self.r20, self.r21, self.r22)
        ax = r00 * px + r10 * py + r20 * pz
        ay = r01 * px + r11 * py + r21 * pz
        az = r02 * px + r12 * py + r22 * pz
        ux = r00 * dx + r10 * dy + r20 * dz
        uy = r01 * dx + r11 * dy + r21 * dz
        uz = r02 * dx + r12 * dy + r22 * dz
        tris, edges = self._tri, self._edges
        reach = r + CONTACT_TOL
        hint = self._hint
        hint_hit = None
        touching = False
        start = None
        feature = nx = ny = nz = 0
        if hint >= 0:
            t = tris[hint]
            d2, qx, qy, qz, feature = _closest(t, ax, ay, az)
            if 1 <= feature <= 3:
                # nearest on an edge: the start may lie over the neighbour's face instead (or
                # beyond it: then walk on)
                other = self._adj[hint][feature - 1]
                if other >= 0:
                    c = _closest(tris[other], ax, ay, az)
                    if c[0] < d2:
                        d2, qx, qy, qz, feature = c
                        hint = other
                        t = tris[hint]
            if (feature and hint != self._hint) or feature >= 4:  # as in `_nearest`
                d2, qx, qy, qz, feature, hint = self._walk(hint, d2, qx, qy, qz, feature, ax, ay, az)
                t = tris[hint]
            if d2 <= reach * reach and d2 > 1e-24:
                # touching the triangle it touched last: pressed into it, nothing can come
                # earlier; moving along or away, it is no obstacle (the inflated triangle is
                # convex) and its tangent plane may certify most of the others
                dist = math.sqrt(d2)
                nx, ny, nz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
                into = nx * ux + ny * uy + nz * uz
                if into < -graze:
                    return self._world_hit(hint, (0.0, nx, ny, nz, feature), ax, ay, az, ux, uy, uz, r, graze)
                # the segment stays r above the hint's tangent plane, from a start not pressed
                # into it (a sphere that dips below the plane may overlap a triangle behind it):
                # only triangles reaching above it need reading
                touching = dist >= r - CONTACT_TOL and dist + into >= r - CONTACT_TOL
                start = (dist, qx, qy, qz, feature, hint)
                few = self._static_clear(hint, feature, nx, ny, nz, 2.0 * reach + length) if touching else None
                if few is not None:
                    # every triangle within reach of the segment but these few lies behind the
                    # tangent plane (certificates kept for the mesh's lifetime): the few are
                    # swept, and the start's nearest point is among them or q
                    if not few:  # (the common case, inline)
                        self._skey = (ax, ay, az)
                        self._sval = start
                        return None
                    return self._sweep_few(few, hint, start, ax, ay, az, ux, uy, uz, r, dd, far2, graze, None)
            else:
                hint_hit = _sweep_triangle(t, edges[hint], ax, ay, az, ux, uy, uz, r, dd, far2, graze,
                                           (d2, qx, qy, qz, feature))
                if hint_hit is not None and 1 <= hint_hit[4] <= 3:
                    # touched on an edge: the neighbour across it may be touched first
                    other = self._adj[hint][hint_hit[4] - 1]
                    if other >= 0:
                        hit = _sweep_triangle(tris[other], edges[other], ax, ay, az, ux, uy, uz, r, dd, far2, graze)
                        if hit is not None and hit[0] < hint_hit[0]:
                            hint, hint_hit = other, hit
                elif hint_hit is not None and hint_hit[4] >= 4 and hint_hit[0] > 0.0:
                    # touched on a vertex: a fan triangle on an edge rising above the tangent
                    # plane there holds a nearer point, so it was touched first
                    lam = hint_hit[0]
                    sx, sy, sz = ax + lam * ux, ay + lam * uy, az + lam * uz
                    c = _closest(t, sx, sy, sz)
                    if c[4] >= 4:
                        walked = self._walk(hint, *c, sx, sy, sz)[5]
                        if walked != hint:
                            hit = _sweep_triangle(tris[walked], edges[walked], ax, ay, az, ux, uy, uz, r, dd, far2, graze)
                            if hit is not None and hit[0] < lam:
                                hint, hint_hit = walked, hit
                if hint_hit is not None:
                    if hint_hit[0] == 0.0:
                        return self._world_hit(hint, hint_hit, ax, ay, az, ux, uy, uz, r, graze)
                    # the segment up to the touch stays r above the tangent plane there, behind
                    # which lies every triangle within reach of it but a few
                    few = self._static_clear(hint, hint_hit[4], hint_hit[1], hint_hit[2], hint_hit[3],
                                             2.0 * reach + hint_hit[0] * length)
                    if few is not None:
                        return self._sweep_few(few, hint, None, ax, ay, az, ux, uy, uz, r, dd, far2, graze, hint_hit)
                elif d2 > 1e-24 and d2 <= (reach + length) * (reach + length):
                    # near the hint, not touching it and not moving into it (a proxy lifted off a
                    # curved mesh): when the segment stays r above the tangent plane at q, only
                    # the few that rise above it can be touched
                    dist = math.sqrt(d2)
                    nx, ny, nz = (ax - qx) / dist, (ay - qy) / dist, (az - qz) / dist
                    if dist + nx * ux + ny * uy + nz * uz >= r - CONTACT_TOL:
                        few = self._static_clear(hint, feature, nx, ny, nz, dist + reach + length)
                        if few is not None:
                            start = (dist, qx, qy, qz, feature, hint) if dist <= reach + length else None
                            return self._sweep_few(few, hint, start, ax, ay, az, ux, uy, uz, r, dd, far2, graze, None)
        # the neighbourhood must hold every triangle within r of the segment
        ex, ey, ez = ax - self._cx, ay - self._cy, az - self._cz
        ea = math.sqrt(ex * ex + ey * ey + ez * ez)
        ex, ey, ez = ex + ux, ey + uy, ez + uz
        eb = math.sqrt(ex * ex + ey * ey + ez * ez)
        rebuilt = ea + reach > self._cr or eb + reach > self._cr
        if rebuilt:
            # centred on the start: the scan reads triangles in order of distance from it, so
            # once a hit is found near the start, the triangles beyond reach of the part of the
            # segment before it are left unread
            self._neighbourhood(ax, ay, az, length + reach + NEIGHBOURHOOD_RADIUS, self._slack)
            ea, eb = 0.0, length
        best, best_lam, best_tri = None, 1.0, -1
        if hint_hit is not None:
            # only the part of the segment before the hint's hit matters now
            best, best_lam, best_tri = hint_hit, hint_hit[0], hint
            far = reach + best_lam * length
            far2 = far * far
            ex = ax + best_lam * ux - self._cx
            ey = ay + best_lam * uy - self._cy
            ez = az + best_lam * uz - self._cz
            eb = math.sqrt(ex * ex + ey * ey + ez * ez)
        emax = ea if ea > eb else eb
        n = bisect.bisect_right(self._cd, reach + emax)
        if hint_hit is not None:
            # before reaching the hint, the sphere stays r above the tangent plane at the
            # point it reaches: the same certificate holds for that part of the segment
            _, nx, ny, nz, feature = hint_hit
            touching = True
        positions = self._certified(hint, feature, nx, ny, nz, n) if touching and hint in self._cpos else None
        scan = n if positions is None else len(positions)
        self._work += scan
        if not rebuilt and ea > self._slack and scan > DRIFT_SCAN and self._work > REBUILD_WORK:
            # drifted: re-centred, the scan reads fewer triangles
            self._neighbourhood(ax, ay, az, length + reach + NEIGHBOURHOOD_RADIUS, self._slack)
            ea = 0.0
            if hint_hit is None:
                eb = length
            else:
                eb = best_lam * length
            emax = eb
            n = bisect.bisect_right(self._cd, reach + emax)
            positions = self._certified(hint, feature, nx, ny, nz, n) if touching and hint in self._cpos else None
        # a start within reach of the hint: every triangle nearer the start than the hint is
        # within reach of the segment, so the scan reads it (or the certificate proved it
        # behind the tangent plane, no nearer): the nearest point is found on the way
        sbest2 = start[0] * start[0] if start is not None else -1.0
        cd, ci, planes = self._cd, self._ci, self._plane
        limit = reach + emax
        if positions is None or len(positions) > VECTOR_MIN:  # a certificate's list is cut at n
            positions = self._shortlist(positions, n, ax, ay, az, far)
        slab = reach + 1e-12  # the plane test of _sweep_triangle, inline, rounding on the safe side
        for k in positions:
            if cd[k] > limit:
                break
            i = ci[k]
            if i == hint:
                continue
            # a segment that stays more than r off the triangle's plane, on one side, never
            # reaches it: most triangles of a concave neighbourhood end here, without a call
            pnx, pny, pnz, off = planes[i]
            h0 = pnx * ax + pny * ay + pnz * az - off
            h1 = h0 + pnx * ux + pny * uy + pnz * uz
            if (h0 > slab and h1 > slab) or (h0 < -slab and h1 < -slab):
                continue
            if sbest2 >= 0.0:
                close = _closest(tris[i], ax, ay, az)
                if close[0] < sbest2:
                    sbest2 = close[0]
                    start = (math.sqrt(sbest2), close[1], close[2], close[3], close[4], i)
                hit = _sweep_triangle(tris[i], edges[i], ax, ay, az, ux, uy, uz, r, dd, far2, graze, close)
            else:
                hit = _sweep_triangle(tris[i], edges[i], ax, ay, az, ux, uy, uz, r, dd, far2, graze)
            if hit is not None and hit[0] < best_lam:
                best, best_lam, best_tri = hit, hit[0], i
                if best_lam == 0.0:
                    sbest2 = -1.0  # the scan stops here: the start's nearest point is not known
                    break
                # only the part of the segment before this hit matters now
                ex = ax + best_lam * ux - self._cx
                ey = ay + best_lam * uy - self._cy
                ez = az + best_lam * uz - self._cz
                eb = math.sqrt(ex * ex + ey * ey + ez * ez)
                limit = reach + (ea if ea > eb else eb)
                far = reach + best_lam * length
                far2 = far * far
        if sbest2 >= 0.0:
            self._skey = (ax, ay, az)
            self._sval = start
        if best is None:
            return None
        return self._world_hit(best_tri, best, ax, ay, az, ux, uy, uz, r, graze)

    def _sweep_few(self, few, hint, start, ax, ay, az, ux, uy, uz, r, dd, far2, graze, hint_hit):
        """End of `sweep` when a kept certificate left only `few` triangles to read: the earliest
        hit among them and `hint_hit` (the hint's, or None), and, when `start` is the hint's
        nearest point to the start, the start's nearest point kept for `distance`."""
        best, best_tri = (hint_hit, hint) if hint_hit is not None else (None, -1)
        best_lam = 1.0 if best is None else best[0]
        tris, edges, planes = self._tri, self._edges, self._plane
        slab = r + CONTACT_TOL + 1e-12
        for i in few:
            if i == hint:
                continue
            close = None
            if start is not None:
                # before the slab test: a start lifted off by more than r may lie nearer to a
                # triangle the segment never reaches than to the hint
                close = _closest(tris[i], ax, ay, az)
                if close[0] < start[0] * start[0]:
                    start = (math.sqrt(close[0]), close[1], close[2], close[3], close[4], i)
            pnx, pny, pnz, off = planes[i]
            h0 = pnx * ax + pny * ay + pnz * az - off
            h1 = h0 + pnx * ux + pny * uy + pnz * uz
            if (h0 > slab and h1 > slab) or (h0 < -slab and h1 < -slab):
                continue
            if close is None:
                close = _closest(tris[i], ax, ay, az)
            hit = _sweep_triangle(tris[i], edges[i], ax, ay, az, ux, uy, uz, r, dd, far2, graze, close)
            if hit is not None and hit[0] < best_lam:
                best, best_lam, best_tri = hit, hit[0], i
        if start is not None:
            self._skey = (ax, ay, az)
            self._sval = start
        if best is None:
            return None
        return self._world_hit(best_tri, best, ax, ay, az, ux, uy, uz, r, graze)

    def _world_hit(self, tri, hit, ax, ay, az, ux, uy, uz, r, graze):
        """The hit with its normal turned into the world frame (shaded when asked)."""
        self._hint = tri
        lam, nx, ny, nz, _ = hit
        cx, cy, cz = ax + lam * ux, ay + lam * uy, az + lam * uz
        recent = self._recent
        for entry in recent:
            if entry[0] == tri:
                entry[4] = entry[1] == cx and entry[2] == cy and entry[3] == cz
                entry[1], entry[2], entry[3] = cx, cy, cz
                break
        else:
            recent.append([tri, cx, cy, cz, False])
            if len(recent) > RECENT_HITS:
                del recent[0]
        if self.shading:
            qx, qy, qz = ax + lam * ux - r * nx, ay + lam * uy - r * ny, az + lam * uz - r * nz
            sx, sy, sz = self._shade(tri, qx, qy, qz, nx, ny, nz)
            if sx * ux + sy * uy + sz * uz < -graze:  # still against the motion: use it
                nx, ny, nz = sx, sy, sz
        return (lam,
                self.r00 * nx + self.r01 * ny + self.r02 * nz,
                self.r10 * nx + self.r11 * ny + self.r12 * nz,
                self.r20 * nx + self.r21 * ny + self.r22 * nz)

    def _shade(self, tri, qx, qy, qz, nx, ny, nz):
        """Force shading: the vertex normals interpolated at q (barycentric), on n's side."""
        t = self._tri[tri]
        wx, wy, wz = qx - t[0], qy - t[1], qz - t[2]
        d1 = t[9] * wx + t[10] * wy + t[11] * wz
        d2 = t[12] * wx + t[13] * wy + t[14] * wz
        v = (t[20] * d1 - t[19] * d2) * t[21]
        w = (t[18] * d2 - t[19] * d1) * t[21]
        v = 0.0 if v < 0.0 else 1.0 if v > 1.0 else v
        w = 0.0 if w < 0.0 else 1.0 - v if w > 1.0 - v else w
        u = 1.0 - v - w
        a0, a1, a2, b0, b1, b2, c0, c1, c2 = self._vn[tri]
        sx, sy, sz = u * a0 + v * b0 + w * c0, u * a1 + v * b1 + w * c1, u * a2 + v * b2 + w * c2
        if sx * t[15] + sy * t[16] + sz * t[17] < 0.0:
            return (nx, ny, nz)  # vertex normals disagree with the face: keep the geometric one
        if sx * nx + sy * ny + sz * nz < 0.0:  # n on the back side of the face (open mesh)
            sx, sy, sz = -sx, -sy, -sz
        s = math.sqrt(sx * sx + sy * sy + sz * sz)
        return (sx / s, sy / s, sz / s) if s > 0.0 else (nx, ny, nz)


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
