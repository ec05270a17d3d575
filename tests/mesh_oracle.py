"""Independent answers for the mesh tests, and the meshes they run on.

`Oracle` answers on a mesh's triangles by brute force in numpy, sharing no code with the
engine: the distance is the minimum over every triangle of the textbook point-triangle
distance (the foot on the plane when it falls inside the triangle, else the nearest point of
its three edges), its sign the generalised winding number (van Oosterom & Strackee's solid
angles) on a watertight mesh, none on an open one. A sweep is checked triangle by triangle:
along a segment the distance to one triangle is convex, so golden-section search finds its
least value on any stretch and bisection the first time it comes down to r; a triangle whose
bounding ball stays farther than r from the whole segment is left out (it cannot touch).
"""

from __future__ import annotations

import functools
import math
from pathlib import Path

import mujoco
import numpy as np
import trimesh

from softproxy.compiled.mesh import POINT_RADIUS
from softproxy.compiled.tolerances import CONTACT_TOL, GRAZE
from softproxy.geometry import shapes_of
from softproxy.mesh import MeshShape

TOL = 1e-6
"""The promise (m): never more than 1 µm inside anything."""
EXACT = 1e-9
"""How near (m) an exact query must come to the brute force (float32 vertices, rounding)."""
SCENES = Path(__file__).resolve().parent.parent / "scenes"
PHI = (math.sqrt(5.0) - 1.0) / 2.0


# ---------------------------------------------------------------------------------------
# Brute force
# ---------------------------------------------------------------------------------------

def point_triangle(p, a, b, c):
    """Distance (m) and nearest point of each point p[k] to triangle (a[k], b[k], c[k]), all
    (..., 3) arrays broadcast together: the textbook way (not the engine's Voronoi walk)."""
    n = np.cross(b - a, c - a)
    n = n / np.linalg.norm(n, axis=-1)[..., None]
    h = ((p - a) * n).sum(-1)
    foot = p - h[..., None] * n
    # inside when the foot is on the inner side of all three edges (signed sub-triangle areas)
    inside = ((np.cross(b - foot, c - foot) * n).sum(-1) >= 0.0) & \
             ((np.cross(c - foot, a - foot) * n).sum(-1) >= 0.0) & \
             ((np.cross(a - foot, b - foot) * n).sum(-1) >= 0.0)
    best = np.where(inside, np.abs(h), np.inf)
    q = np.where(inside[..., None], foot, np.nan)
    for s0, s1 in ((a, b), (b, c), (c, a)):
        e = s1 - s0
        t = np.clip(((p - s0) * e).sum(-1) / (e * e).sum(-1), 0.0, 1.0)
        on = s0 + t[..., None] * e
        dist = np.linalg.norm(p - on, axis=-1)
        nearer = dist < best
        best = np.where(nearer, dist, best)
        q = np.where(nearer[..., None], on, q)
    return best, q



def triangles_near(o, samples: np.ndarray, i: int, radius: float) -> np.ndarray:
    """Indices of the triangles of `o` within `radius` (m) of triangle i, judged on `samples`
    (points spread over each triangle, (triangles, k, 3)): a triangle with a sample that close
    to triangle i, or close to one of triangle i's samples, is within the reach (a subset of
    the triangles truly within it, which the engine's tables must cover)."""
    maybe = np.flatnonzero(np.linalg.norm(o.centre - o.centre[i], axis=1) - o.rho - o.rho[i] <= radius)
    gap = np.minimum(
        point_triangle(samples[maybe], o.a[i], o.b[i], o.c[i])[0].min(axis=1),
        point_triangle(samples[i][None], o.a[maybe][:, None], o.b[maybe][:, None], o.c[maybe][:, None])[0].min(axis=1))
    return maybe[gap <= radius]


def assert_vertex_table(o, v, f, vertex: int, radius: float, normal, table: list, table_ids: list, read: int,
                        id_of=lambda w: w) -> None:
    """A vertex's table (sin β ascending, `table_ids` its vertices by `id_of`) against brute
    force: every vertex of a triangle within `radius` (m, exact point-triangle distance) of
    `vertex` but its ring is listed no later than its sin β (β: below the plane square to
    `normal`, the vertex normal), where the table reaches that far (all of it when it holds no
    more than `read` entries)."""
    fan = (f == vertex).any(axis=1)
    ring = set(f[fan].reshape(-1).tolist())
    near = (point_triangle(v[vertex][None], o.a, o.b, o.c)[0] <= radius) & ~fan
    others = sorted(set(f[near].reshape(-1).tolist()) - ring)
    u = v[others] - v[vertex]
    beta = -(u @ normal) / np.linalg.norm(u, axis=1)
    assert table == sorted(table)
    cut = table[-1] if len(table) > read else math.inf
    kept = dict(zip(table_ids, table))
    for w, sine in zip(others, beta):
        if sine < cut:
            assert kept[id_of(w)] <= sine + 1e-12, (vertex, w)


class Oracle:
    """A mesh's triangles (world frame, m) and brute-force answers about them."""

    def __init__(self, v: np.ndarray, f: np.ndarray, signed: bool, depth: float = math.inf) -> None:
        """`signed`: watertight (an inside). `depth` (m): no point of the solid lies farther than
        this from its surface (half a shell's thickness), so no farther point needs its winding
        number. A convex mesh is told inside by its face planes instead."""
        self.v, self.f, self.signed, self.depth = np.asarray(v, float), np.asarray(f), signed, depth
        self.a, self.b, self.c = (self.v[self.f[:, k]] for k in range(3))
        self.centre = (self.a + self.b + self.c) / 3.0
        self.rho = np.sqrt(np.max([((x - self.centre) ** 2).sum(1) for x in (self.a, self.b, self.c)], axis=0))
        n = np.cross(self.b - self.a, self.c - self.a)
        self.n = n / np.linalg.norm(n, axis=1)[:, None]
        self.off = (self.n * self.a).sum(1)
        self.convex = signed and all((self.v[s:s + 500] @ self.n.T - self.off).max() <= 1e-12
                                     for s in range(0, len(self.v), 500))

    def nearest(self, points):
        """(distance, nearest point, triangle) of each point over every triangle (unsigned).
        Every triangle is bounded first: one whose bounding ball is farther than the point's
        nearest vertex cannot hold the nearest point; the others are measured exactly."""
        points = np.atleast_2d(np.asarray(points, float))
        dist, near, tri = [], [], []
        chunk = max(1, 2_000_000 // (len(self.f) + len(self.v)))
        for s in range(0, len(points), chunk):
            p = points[s:s + chunk]
            vertex = np.sqrt(((p[:, None, :] - self.v[None]) ** 2).sum(2)).min(axis=1)
            gap = np.sqrt(((p[:, None, :] - self.centre[None]) ** 2).sum(2)) - self.rho[None]
            k, i = np.nonzero(gap <= vertex[:, None] * (1.0 + 1e-9) + 1e-12)
            d, q = point_triangle(p[k], self.a[i], self.b[i], self.c[i])
            order = np.lexsort((d, k))  # by point, nearest first
            first = order[np.searchsorted(k[order], np.arange(len(p)))]
            dist.append(d[first])
            near.append(q[first])
            tri.append(i[first])
        return np.concatenate(dist), np.concatenate(near), np.concatenate(tri)

    def winding(self, points):
        """Generalised winding number of the mesh at each point (1 inside, 0 outside)."""
        points = np.atleast_2d(np.asarray(points, float))
        out = []
        chunk = max(1, 200_000 // len(self.f))
        for s in range(0, len(points), chunk):
            p = points[s:s + chunk, None, :]
            a, b, c = self.a[None] - p, self.b[None] - p, self.c[None] - p
            la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
            det = (a * np.cross(b, c)).sum(2)
            den = la * lb * lc + (a * b).sum(2) * lc + (b * c).sum(2) * la + (c * a).sum(2) * lb
            out.append(np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi))
        return np.concatenate(out)

    def inside(self, points, dist=None):
        """Whether each point lies inside the (watertight) mesh; `dist`: their distances, if known."""
        points = np.atleast_2d(np.asarray(points, float))
        if not self.signed:
            return np.zeros(len(points), dtype=bool)
        if self.convex:
            return np.array([(p @ self.n.T - self.off).max() < 0.0 for p in points])
        maybe = np.ones(len(points), dtype=bool) if dist is None else np.asarray(dist) <= self.depth
        out = np.zeros(len(points), dtype=bool)
        if maybe.any():
            out[maybe] = self.winding(points[maybe]) > 0.5
        return out

    def distance(self, points):
        """Signed distance (m; < 0 inside a watertight mesh, unsigned on an open one)."""
        d = self.nearest(points)[0]
        return np.where(self.inside(points, d), -d, d)

    # -- sweeps -------------------------------------------------------------------------
    def _along(self, ids, a, dvec, t):
        """Distance from a + t[k] dvec to triangle ids[k]."""
        p = a + t[:, None] * dvec
        return point_triangle(p, self.a[ids], self.b[ids], self.c[ids])

    def _reachable(self, a, dvec, r):
        """The triangles whose bounding ball comes within r (+1 µm) of the segment."""
        dd = dvec @ dvec
        t = np.clip(((self.centre - a) @ dvec) / dd, 0.0, 1.0) if dd > 0.0 else np.zeros(len(self.f))
        gap = np.linalg.norm(a + t[:, None] * dvec - self.centre, axis=1) - self.rho
        return np.flatnonzero(gap <= r + 1e-6)

    def _least(self, ids, a, dvec, t1, r):
        """Per triangle of ids, the least distance to it over t in [0, t1] and where: sampled
        at 65 points, then, where that could come within 1 µm of r (the distance is
        1-Lipschitz), found by golden-section search between the samples on either side of
        the least sample (it is convex in t). Elsewhere the least sample, above r + 1 µm."""
        t = np.linspace(0.0, t1, 65)
        k, j = np.meshgrid(np.arange(len(ids)), np.arange(len(t)), indexing="ij")
        d = self._along(ids[k.ravel()], a, dvec, t[j.ravel()])[0].reshape(len(ids), len(t))
        at = d.argmin(axis=1)
        least, where = d[np.arange(len(ids)), at], t[at]
        near = np.flatnonzero(least - 0.5 * (t[1] - t[0]) * math.sqrt(dvec @ dvec) <= r + 1e-6)
        if len(near):
            lo, hi = t[np.maximum(at[near] - 1, 0)], t[np.minimum(at[near] + 1, len(t) - 1)]
            sub = ids[near]
            m1, m2 = hi - PHI * (hi - lo), lo + PHI * (hi - lo)
            f1, f2 = self._along(sub, a, dvec, m1)[0], self._along(sub, a, dvec, m2)[0]
            for _ in range(60):  # golden section: one new point per step
                left = f1 <= f2
                lo, hi = np.where(left, lo, m1), np.where(left, m2, hi)
                m1, m2 = np.where(left, hi - PHI * (hi - lo), m2), np.where(left, m1, lo + PHI * (hi - lo))
                fp = self._along(sub, a, dvec, np.where(left, m1, m2))[0]
                f1, f2 = np.where(left, fp, f2), np.where(left, f1, fp)
            mid = 0.5 * (lo + hi)
            value = self._along(sub, a, dvec, mid)[0]
            better = value < least[near]
            least[near[better]], where[near[better]] = value[better], mid[better]
        return least, where

    def sweep_facts(self, a, dvec, r, first=True):
        """What a sphere of radius r (a point: POINT_RADIUS) from a moving by dvec meets:
        dict(into=True when it starts within reach of a triangle and is pressed into it (moves
        in by more than a graze, so far that the tangent line of its distance to the triangle
        ends more than CONTACT_TOL deeper than a touch); ids: the triangles it does not start
        touching; slid: those it touches and is not pressed into, with its distances to them
        (`floor`) and the least each may come down to (in by a graze at most, or to a touch
        less CONTACT_TOL: the distance along the segment is convex, above its tangent line);
        first: the first fraction at which it comes within r of one of ids, None if never)."""
        a, dvec = np.asarray(a, float), np.asarray(dvec, float)
        r = max(r, POINT_RADIUS)
        ids = self._reachable(a, dvec, r)
        d0, q0 = point_triangle(a[None], self.a[ids], self.b[ids], self.c[ids])
        touching = d0 <= r + CONTACT_TOL
        out = (a - q0) / np.maximum(d0, 1e-300)[:, None]
        # a centre on a triangle goes into it on whichever side it moves to
        on = d0 <= 1e-12
        out[on] = -np.sign(self.n[ids[on]] @ dvec)[:, None] * self.n[ids[on]]
        graze = GRAZE * math.sqrt(dvec @ dvec)
        rate = out @ dvec
        pressed = touching & (rate < -graze) & (d0 + rate < r - CONTACT_TOL)
        slid = touching & ~pressed
        floor = np.where(rate >= -graze, d0 - graze, np.minimum(d0, r - CONTACT_TOL))[slid]
        facts = {"into": bool(pressed.any()), "ids": ids[~touching], "slid": ids[slid], "floor": floor, "r": r,
                 "pressed": ids[pressed]}
        ids = facts["ids"]
        if not first:
            return {**facts, "first": None}
        first = None
        if len(ids):
            least, at = self._least(ids, a, dvec, 1.0, r)
            hit = least <= r
            if hit.any():
                lo, hi = np.zeros(hit.sum()), at[hit]
                for _ in range(60):  # the distance falls from above r to the least: one crossing
                    mid = 0.5 * (lo + hi)
                    below = self._along(ids[hit], a, dvec, mid)[0] <= r
                    hi = np.where(below, mid, hi)
                    lo = np.where(below, lo, mid)
                first = float(hi.min())
        return {**facts, "first": first}

    def check_sweep(self, a, dvec, r, hit, normal_check=True, context=()):
        """Asserts a sweep's answer (None or (lam, nx, ny, nz)) against the brute force: pressed
        into a triangle it touches, it stops at once (or goes on, if it never comes within
        r - CONTACT_TOL of that triangle before it stops); else it stops where the sphere first
        comes within r of a triangle (touching, and never nearer than r before), or, when it
        misses, the sphere never comes nearer than r; and up to where it stops it never goes
        further into a triangle it touched at the start than a graze, or a touch less
        CONTACT_TOL. The normal is a unit vector against the motion, from the surface to the
        sphere's centre (its foot lies on the surface).
        Touches agree to EXACT, or to 1e-14 L²/r when more (a 10 nm point proxy on a segment
        of length L: an edge's or a vertex's touch is the root of a quadratic whose terms are
        ~L², of which r² is a rounding's worth; ~2 nm on a 6 cm segment). Returns the facts."""
        a, dvec = np.asarray(a, float), np.asarray(dvec, float)
        facts = self.sweep_facts(a, dvec, r, first=False)
        r, ids = facts["r"], facts["ids"]
        length = math.sqrt(dvec @ dvec)
        tol = EXACT + 1e-14 * length * length / r
        end = 1.0 if hit is None else hit[0]
        if facts["into"]:
            if hit is not None and hit[0] == 0.0:
                return facts
            # or it slides on where the tangent line of the distance dips in and the distance
            # itself never does (a coplanar neighbour touched at its edge, slid along: a
            # certificate reads nothing behind the tangent plane, nor the tree a node whose
            # plane the sphere stays r above)
            least = self._least(facts["pressed"], a, dvec, end, r)[0]
            assert (least >= r - CONTACT_TOL - tol).all(), ("pressed into a triangle it touches", context, hit)
        if len(facts["slid"]) and end > 0.0:
            least = self._least(facts["slid"], a, dvec, end, r)[0]
            assert (least >= facts["floor"] - tol).all(), ("went into a triangle it touched", context, hit)
        if hit is None:
            if len(ids):
                assert self._least(ids, a, dvec, 1.0, r)[0].min() >= r - tol, \
                    ("missed a touch", context, self.sweep_facts(a, dvec, r)["first"])
        else:
            lam = hit[0]
            assert 0.0 <= lam < 1.0, (context, hit)
            if len(ids) and lam > 0.0:
                assert self._least(ids, a, dvec, lam, r)[0].min() >= r - tol, \
                    ("went in before stopping", context, hit, self.sweep_facts(a, dvec, r)["first"])
            centre = a + lam * dvec
            if lam > 0.0:  # the sphere touches a triangle it did not start touching
                gap = point_triangle(centre[None], self.a[ids], self.b[ids], self.c[ids])[0].min()
                assert abs(gap - r) <= tol, ("stopped off the surface", context, hit, gap, r)
            n = np.array(hit[1:])
            assert abs(np.linalg.norm(n) - 1.0) < 1e-9 and n @ dvec < 0.0, (context, hit)
            if normal_check:
                assert self.nearest(centre - r * n)[0][0] <= 1e-8 + tol, \
                    ("normal not from the surface", context, hit)
        return facts


def world_mesh(model, data, geom):
    """A mesh geom's triangles as MuJoCo compiled them, in the world frame: (vertices, faces)."""
    k = int(model.geom_dataid[geom])
    v = model.mesh_vert[model.mesh_vertadr[k]:model.mesh_vertadr[k] + model.mesh_vertnum[k]].astype(float)
    f = model.mesh_face[model.mesh_faceadr[k]:model.mesh_faceadr[k] + model.mesh_facenum[k]].astype(np.int64)
    return v @ data.geom_xmat[geom].reshape(3, 3).T + data.geom_xpos[geom], f


def oracle(model, data, shapes) -> Oracle:
    """The Oracle of the (first) mesh of a ShapeSet, placed where its geom is now (kept while
    the geom stays there)."""
    s = mesh_of(shapes)
    key = (id(shapes), data.geom_xpos[s.geom].tobytes(), data.geom_xmat[s.geom].tobytes())
    if _oracles.get(id(shapes), (None,))[0] != key:
        _oracles[id(shapes)] = (key, Oracle(*world_mesh(model, data, s.geom), s.signed), shapes)
    return _oracles[id(shapes)][1]


_oracles: dict = {}


def mesh_of(shapes) -> MeshShape:
    return next(s for s in shapes if isinstance(s, MeshShape))


# ---------------------------------------------------------------------------------------
# Meshes
# ---------------------------------------------------------------------------------------

def mesh_model(mesh: trimesh.Trimesh, body: str = "", geom: str = "", extra: str = "", shading: bool = False):
    """A model with one mesh geom 'g' (asset 'm', vertices inline) in body 'b': (model, data,
    ShapeSet with MeshShape)."""
    verts = " ".join(f"{x:.10g}" for x in np.asarray(mesh.vertices).ravel())
    faces = " ".join(str(int(i)) for i in np.asarray(mesh.faces).ravel())
    xml = (f'<mujoco><asset><mesh name="m" vertex="{verts}" face="{faces}"/></asset><worldbody>'
           f'<body name="b" {body}><geom name="g" type="mesh" mesh="m" {geom}/></body>{extra}</worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    shape = functools.partial(MeshShape, shading=True) if shading else MeshShape
    return m, d, shapes_of(m, d, mesh_shape=shape)


def geodesic_sphere(freq: int, radius: float) -> trimesh.Trimesh:
    """An icosahedron with each face cut into freq² triangles, pushed onto the sphere (20 freq² faces)."""
    ico = trimesh.creation.icosahedron()
    verts, faces, index = [], [], {}

    def vertex(p):
        p = p / np.linalg.norm(p)
        key = tuple(np.round(p, 9))
        if key not in index:
            index[key] = len(verts)
            verts.append(p * radius)
        return index[key]

    for a, b, c in ico.vertices[ico.faces]:
        grid = {(i, j): vertex(a + (b - a) * i / freq + (c - a) * j / freq)
                for i in range(freq + 1) for j in range(freq + 1 - i)}
        for i in range(freq):
            for j in range(freq - i):
                faces.append([grid[i, j], grid[i + 1, j], grid[i, j + 1]])
                if i + j < freq - 1:
                    faces.append([grid[i + 1, j], grid[i + 1, j + 1], grid[i, j + 1]])
    return trimesh.Trimesh(np.array(verts), np.array(faces), process=False)


def uv_sphere_mesh() -> trimesh.Trimesh:
    """trimesh's uv-sphere (radius 5 cm, ~10k triangles): ~100 thin triangles meet at each pole."""
    mesh = trimesh.creation.uv_sphere(radius=0.05, count=[51, 51])
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    return mesh


def small_tetra(at) -> trimesh.Trimesh:
    """A tetrahedron (4 triangles, 0.6 mm legs) centred at `at` (m)."""
    tetra = trimesh.Trimesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * 6e-4,
                            np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]), process=False)
    tetra.apply_translation(at - tetra.vertices.mean(0))
    return tetra


def l_prism() -> trimesh.Trimesh:
    """A watertight L-shaped prism (4 × 4 cm, 2 cm thick along y, arms 2 cm wide): a concave
    crease along the inner corner, x = z = 0, where two faces meet at 270°."""
    outline = np.array([[-0.02, -0.02], [0.02, -0.02], [0.02, 0.0], [0.0, 0.0], [0.0, 0.02], [-0.02, 0.02]])
    n = len(outline)
    v = [[x, -0.01, z] for x, z in outline] + [[x, 0.01, z] for x, z in outline]
    fan = [(3, 4, 5), (3, 5, 0), (3, 0, 1), (3, 1, 2)]  # the L from its inner corner
    f = [(a, b, c) for a, b, c in fan] + [(a + n, c + n, b + n) for a, b, c in fan]
    for i in range(n):
        j = (i + 1) % n
        f += [(i, j + n, j), (i, i + n, j + n)]
    mesh = trimesh.Trimesh(np.array(v), np.array(f), process=False)
    trimesh.repair.fix_normals(mesh)
    return mesh


def wavy_sheet() -> trimesh.Trimesh:
    """An open, wavy sheet 8 cm square (no inside: unsigned distance)."""
    plane = trimesh.creation.box(extents=(0.08, 0.08, 0.01)).subdivide().subdivide().subdivide()
    keep = np.flatnonzero((plane.vertices[:, 2] > 0.0)[plane.faces].all(axis=1))
    mesh = trimesh.Trimesh(plane.vertices, plane.faces[keep], process=True)
    mesh.vertices[:, 2] += 0.004 * np.sin(60.0 * mesh.vertices[:, 0]) * np.cos(45.0 * mesh.vertices[:, 1])
    return mesh


def peak_in_a_wall() -> trimesh.Trimesh:
    """An open sheet: a convex peak (tip at the origin, falling 1 mm over 2 mm) ringed by a wall
    2-2.5 mm high 3-6 mm out: straight above the tip the wall is nearer than the tip once the
    point is ~4 mm up, and the tip's vertex table holds vertices above its cone (sin β < 0)."""
    seg, radii, heights = 12, [0.001, 0.002, 0.003, 0.004, 0.006], [-0.0005, -0.001, 0.002, 0.0025, 0.0025]
    v = [(0.0, 0.0, 0.0)] + [(r * math.cos(2 * math.pi * j / seg), r * math.sin(2 * math.pi * j / seg), h)
                             for r, h in zip(radii, heights) for j in range(seg)]
    f = [(0, 1 + j, 1 + (j + 1) % seg) for j in range(seg)]
    for ring in range(1, len(radii)):
        b0, b1 = 1 + (ring - 1) * seg, 1 + ring * seg
        f += [t for j in range(seg) for t in ((b0 + j, b1 + j, b1 + (j + 1) % seg),
                                               (b0 + j, b1 + (j + 1) % seg, b0 + (j + 1) % seg))]
    return trimesh.Trimesh(np.array(v), np.array(f), process=False)


@functools.cache
def sphere10k():
    """The 10k-triangle sphere (geodesic, radius 5 cm, 9680 triangles) at the origin."""
    return mesh_model(geodesic_sphere(22, 0.05))


@functools.cache
def scanned_sphere():
    """The 10k-triangle sphere with each vertex moved radially by a tenth of an edge at random
    (a scan's noise): dents and ridges between facets where the sphere was smooth."""
    mesh = geodesic_sphere(22, 0.05)
    v = np.array(mesh.vertices)
    v *= (1.0 + 0.1 * (1.1 / 22) * np.random.default_rng(5).standard_normal(len(v)))[:, None]
    return mesh_model(trimesh.Trimesh(v, mesh.faces, process=False))


@functools.cache
def bowl():
    """The mesh_object scene's bowl (7200 triangles, rim at z = 4 cm) on its table plane."""
    m = mujoco.MjModel.from_xml_path(str(SCENES / "mesh_object.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, shapes_of(m, d, mesh_shape=MeshShape)


@functools.cache
def tilted_ball():
    """An icosphere (1280 triangles) in a rotated, offset body, itself offset and rotated in it."""
    return mesh_model(trimesh.creation.icosphere(3, radius=0.03),
                      body='pos="0.1 -0.05 0.2" euler="20 -35 50"', geom='pos="0.01 0.02 -0.01" euler="10 0 -70"')


@functools.cache
def uv_sphere():
    return mesh_model(uv_sphere_mesh())


@functools.cache
def sheet():
    """`wavy_sheet`, tilted and moved (open: MeshWarning at load)."""
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return mesh_model(wavy_sheet(), body='pos=".01 -.02 .03"', geom='euler="15 -20 35"')


@functools.cache
def prism():
    """`l_prism`, turned and moved."""
    return mesh_model(l_prism(), body='pos=".02 .01 -.01" euler="30 10 -20"')


MESHES = {"bowl": bowl, "sphere10k": sphere10k, "tilted ball": tilted_ball, "sheet": sheet, "prism": prism}
