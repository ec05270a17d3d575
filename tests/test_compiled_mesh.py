"""The compiled mesh queries (softproxy.compiled.mesh) against the Python meshes and brute force.

`MeshShape` (softproxy.mesh) is the reference. The compiled twin reads every triangle a grid
cell lists instead of proving most of them away, so where two triangles are equally near it
may answer from the other one: distances agree to rounding, sweeps to the touch of a
brute-force pass over every triangle.
"""

import math
from pathlib import Path

import numpy as np
import pytest
import trimesh
from hypothesis import given, settings, strategies as st

from softproxy.compiled import godobject, layout as L
from softproxy.compiled.mesh import mesh_distance, mesh_sweep
from softproxy.compiled.shapes import shape_tables
from softproxy.geometry import CONTACT_TOL, GRAZE
from softproxy.mesh import POINT_RADIUS, MeshShape, _closest, _sweep_triangle
from softproxy.proxy import GodObject
from test_mesh import TOL, bowl, mesh_model, sphere10k, tilted_ball


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    return str(tmp_path_factory.mktemp("compiled_meshes"))


def sheet(tmp):
    """An open, wavy sheet (no inside: unsigned distance), tilted."""
    plane = trimesh.creation.box(extents=(0.08, 0.08, 0.01))
    plane = plane.subdivide().subdivide().subdivide()
    top = plane.vertices[:, 2] > 0.0
    keep = np.flatnonzero(top[plane.faces].all(axis=1))
    mesh = trimesh.Trimesh(plane.vertices, plane.faces[keep], process=True)
    mesh.vertices[:, 2] += 0.004 * np.sin(60.0 * mesh.vertices[:, 0]) * np.cos(45.0 * mesh.vertices[:, 1])
    with pytest.warns(UserWarning, match="open mesh"):
        return mesh_model(Path(tmp) / "sheet.obj", mesh, body='pos=".01 -.02 .03"',
                          geom='euler="15 -20 35"')


MESHES = {"bowl": lambda tmp: bowl(), "sphere10k": sphere10k, "tilted ball": tilted_ball, "sheet": sheet}


def tables(shapes):
    """(S, T, C, k): the packed world and the mesh's row."""
    S, T, C = shape_tables(shapes)
    k = next(i for i, s in enumerate(shapes) if isinstance(s, MeshShape))
    return S, T, C, k


def around(shape, rng, n, spread=1.6):
    """n random points (world) in a ball `spread` times the mesh's bound about its geom origin."""
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return np.array((shape.px, shape.py, shape.pz)) + u * (spread * shape.rbound * rng.uniform(0, 1, (n, 1)) ** 0.5)


@pytest.mark.parametrize("which", sorted(MESHES))
def test_distance_is_the_python_meshes(tmp, which):
    """Signed (unsigned on the open sheet) distance and normal at random points near and far,
    asked in a random order (the hint and the kept answers in play): MeshShape's to 1e-12 m."""
    m, d, shapes = MESHES[which](tmp)
    S, T, C, k = tables(shapes)
    mesh = shapes[k]
    rng = np.random.default_rng(7)
    points = around(mesh, rng, 400)
    points = np.vstack([points, points[rng.integers(0, len(points), 100)]])  # some asked again
    for x, y, z in points.tolist():
        want = mesh.distance(x, y, z)
        got = mesh_distance(S, T, C, d.geom_xpos, d.geom_xmat, k, x, y, z)
        assert abs(got[0] - want[0]) <= 1e-12, (which, x, y, z, got, want)
        if abs(want[0]) > 1e-6:  # off the surface the normal is (p - q)/|p - q|, unique
            assert np.dot(got[1:], want[1:]) > 1.0 - 1e-9, (which, x, y, z, got, want)
    assert S[k, L.S_HINT] >= 0 and not math.isnan(S[k, L.S_KEY])


def test_force_shading_is_the_python_meshes():
    """With shading on, the interpolated normals are MeshShape's, on the surface and off it."""
    m, d, shapes = bowl()
    mesh = shapes[1]
    shaded = MeshShape(m, d, mesh.geom, True, shading=True)
    S, T, C, k = tables([shapes[0], shaded])
    assert S[k, L.S_SHADING] == 1.0
    rng = np.random.default_rng(3)
    differs = 0
    for x, y, z in around(shaded, rng, 300, 1.1).tolist():
        want, plain = shaded.distance(x, y, z), mesh.distance(x, y, z)
        got = mesh_distance(S, T, C, d.geom_xpos, d.geom_xmat, k, x, y, z)
        assert abs(got[0] - want[0]) <= 1e-12 and np.dot(got[1:], want[1:]) > 1.0 - 1e-9
        differs += np.dot(want[1:], plain[1:]) < 1.0 - 1e-6
    assert differs > 30  # shading changed many normals, and the compiled twin followed


def brute_sweep(mesh, p, u, r):
    """`softproxy.mesh._sweep_triangle` over every triangle: the earliest touch (lam, n) or None.
    Its inputs are computed as the sweeps compute theirs (the segment's length from the world
    vector): a touch that grazes a triangle moves by ~1e-8 of the segment with the last bit."""
    a = mesh.to_local(*p)
    dx, dy, dz = u
    ul = (mesh.r00 * dx + mesh.r10 * dy + mesh.r20 * dz, mesh.r01 * dx + mesh.r11 * dy + mesh.r21 * dz,
          mesh.r02 * dx + mesh.r12 * dy + mesh.r22 * dz)
    dd = dx * dx + dy * dy + dz * dz
    length = math.sqrt(dd)
    r = max(r, POINT_RADIUS)
    far2 = (r + length + CONTACT_TOL) ** 2
    best = None
    for tri, edges in zip(mesh._tri, mesh._edges):
        hit = _sweep_triangle(tri, edges, *a, *ul, r, dd, far2, GRAZE * length)
        if hit is not None and (best is None or hit[0] < best[0]):
            best = hit
    return best


@pytest.mark.parametrize("which", sorted(MESHES))
def test_sweep_is_the_brute_force_sweep(tmp, which):
    """Random spheres (a point included) on random segments, short (the grid's columns) and
    long (cells along the segment), from outside, touching and inside: the same touch as a
    pass over every triangle, to 1e-12 of the segment."""
    m, d, shapes = MESHES[which](tmp)
    S, T, C, k = tables(shapes)
    mesh = shapes[k]
    rng = np.random.default_rng(11)
    starts = around(mesh, rng, 300, 1.3)
    hits = long_hits = 0
    for i, p in enumerate(starts.tolist()):
        scale = [1e-5, 1e-3, 0.01, 0.06][i % 4]
        u = (rng.normal(size=3) * scale).tolist()
        r = [0.0, 0.002, 0.005, 0.008][(i // 4) % 4]
        want = brute_sweep(mesh, p, u, r)
        got = mesh_sweep(S, T, C, d.geom_xpos, d.geom_xmat, k, *p, *u, r)
        if want is None:
            assert got[0] == -1.0, (which, p, u, r, got)
        else:
            assert abs(got[0] - want[0]) <= 1e-12, (which, p, u, r, got, want)
            hits += 1
            long_hits += scale >= 0.01
    assert hits > 20 and long_hits > 5


def test_sweep_hint_and_kept_answers_change_nothing(tmp):
    """The same queries on a fresh table (no hint, nothing kept) and after a long history give
    the same answers: what a query keeps only saves work."""
    m, d, shapes = sphere10k(tmp)
    S, T, C, k = tables(shapes)
    rng = np.random.default_rng(5)
    queries = [(around(shapes[k], rng, 1, 1.2)[0].tolist(), (rng.normal(size=3) * 0.003).tolist())
               for _ in range(120)]
    for p, u in queries:  # history
        mesh_sweep(S, T, C, d.geom_xpos, d.geom_xmat, k, *p, *u, 0.005)
        mesh_distance(S, T, C, d.geom_xpos, d.geom_xmat, k, *p)
    for p, u in queries[::7]:
        fresh = shape_tables(shapes)
        for args in ((mesh_sweep, (*p, *u, 0.005)), (mesh_distance, tuple(p))):
            fn, a = args
            old = fn(S, T, C, d.geom_xpos, d.geom_xmat, k, *a)
            new = fn(*fresh, d.geom_xpos, d.geom_xmat, k, *a)
            assert old[0] == pytest.approx(new[0], abs=1e-12)


def test_a_world_without_meshes_has_empty_mesh_tables():
    import mujoco
    from softproxy.geometry import shapes_of
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom type="sphere" size=".1"/></worldbody></mujoco>')
    d = mujoco.MjData(m)
    S, T, C = shape_tables(shapes_of(m, d))
    assert T.shape == (0, L.T_COLUMNS) and C.tolist() == [0.0] * L.C_STAMPS


class CompiledMeshQueries:
    """A mesh Shape for the Python `GodObject` that answers from the compiled mesh queries on
    tables of its own (and, like the compiled solver, never warm-starts on a mesh face)."""

    def __init__(self, shapes, d):
        self.mesh = next(s for s in shapes if isinstance(s, MeshShape))
        self.S, self.T, self.C, self.k = tables(shapes)
        self.d = d

    def __getattr__(self, name):
        return getattr(self.mesh, name)

    def distance(self, x, y, z):
        return mesh_distance(self.S, self.T, self.C, self.d.geom_xpos, self.d.geom_xmat, self.k, x, y, z)

    def sweep(self, x, y, z, dx, dy, dz, r):
        hit = mesh_sweep(self.S, self.T, self.C, self.d.geom_xpos, self.d.geom_xmat, self.k, x, y, z, dx, dy, dz, r)
        return None if hit[0] < 0.0 else hit

    def on_face(self, nx, ny, nz):
        return False


coord = st.floats(-1.0, 1.0)


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(["sphere10k", "bowl", "tilted ball"]), st.floats(0.0, 0.01), st.floats(0.0, 1.0),
       st.lists(st.tuples(coord, coord, coord), min_size=2, max_size=20))
def test_the_compiled_god_object_on_meshes(tmp, which, radius, mu, points):
    """Random proxy radius, friction and device path (steps of up to ~2 cm a tick) through a
    10k-triangle sphere, the bowl and a tilted ball, solved by the compiled god-object: never
    more than 1e-6 m inside, in contact whenever the device is inside (its sweep budget spent
    following the surface, it ends on the surface, not above it); and every field equal, tick by tick, to the Python `GodObject`
    asking the same compiled mesh queries: the compiled solver is the Python one on meshes too
    (the queries themselves are checked above against MeshShape and brute force)."""
    m, d, shapes = MESHES[which](tmp)
    S, T, C, k = tables(shapes)
    mesh = shapes[k]
    twin = [CompiledMeshQueries(shapes, d) if s is mesh else s for s in shapes]
    centre = np.array((mesh.px, mesh.py, mesh.pz))
    start = tuple((centre + [0.0, 0.0, 1.5 * mesh.rbound + radius]).tolist())
    god = GodObject(twin, radius, mu, 0.8 * mu, start)
    g = np.zeros(L.F_COLUMNS)
    near = np.zeros(len(shapes), dtype=np.int64)
    godobject.pack_god(god, {id(s): i for i, s in enumerate(twin)}, g, near)
    # the same query state (hint, kept answers) as the twin's after the GodObject's first
    # queries: where two triangles are equally near, the hint decides which one answers
    S[:], C[:] = twin[k].S, twin[k].C
    work = godobject.scratch()
    steps = []
    here = np.array(start)
    for p in points:
        goal = centre + np.array(p) * 1.2 * mesh.rbound
        steps += [here + (goal - here) * j / 4 for j in range(1, 5)]
        here = goal
    for q in steps:
        ok_c = godobject.update(S, T, C, d.geom_xpos, d.geom_xmat, g, near, *q.tolist(), *work)
        x, y, z = g[L.G_X], g[L.G_Y], g[L.G_Z]
        assert max(radius - s.distance(x, y, z)[0] for s in shapes) <= TOL
        if min(s.distance(*q.tolist())[0] for s in shapes) < -1e-3:
            assert g[L.G_CONTACT] == 1.0  # the device inside: the proxy holds it back, never lets go
        assert god.update(*q.tolist()) == ok_c
        assert (x, y, z) == (god.x, god.y, god.z)
        assert bool(g[L.G_CONTACT]) == god.contact and bool(g[L.G_STICKING]) == god.sticking
        planes = g[L.G_PLANES:L.G_PLANES + L.PLANE_WIDTH * int(g[L.G_NPLANES])].reshape(-1, L.PLANE_WIDTH)
        assert [(*p[:4], twin[int(p[4])]) for p in planes.tolist()] == god.planes


def hugging_path(mesh, rng, steps, r):
    """Points (world) near the surface of `mesh` for a sphere of radius r: a random walk whose
    every point is pulled back to between 0.5 mm inside and 1 mm beyond touching, with steps
    from 10 µm to 3 mm: what a proxy sliding, pressing and lifting off asks."""
    p = around(mesh, rng, 1, 1.0)[0]
    out = []
    for i in range(steps):
        p = p + rng.normal(size=3) * [1e-5, 3e-4, 3e-3][i % 3]
        d, nx, ny, nz = mesh.distance(*p.tolist())
        p = p - np.array((nx, ny, nz)) * (d - r - rng.uniform(-5e-4, 1e-3))
        out.append(p.tolist())
    return out


def to_world(mesh, local):
    """A point of the mesh's geom frame in the world (m), as a list."""
    R = np.array([[mesh.r00, mesh.r01, mesh.r02], [mesh.r10, mesh.r11, mesh.r12], [mesh.r20, mesh.r21, mesh.r22]])
    return (R @ np.asarray(local) + np.array((mesh.px, mesh.py, mesh.pz))).tolist()


def vertex_path(mesh, rng, steps, r):
    """Points (world) about the mesh's vertices, where a vertex is the nearest feature: each
    off a random vertex along a direction scattered about its normal, at r give or take 0.5 mm,
    every other one a small step from the last (the vertex certificate, its cone and ring)."""
    out = []
    for i in range(steps):
        if i % 2 and out:
            out.append((np.array(out[-1]) + rng.normal(size=3) * 2e-4).tolist())
            continue
        v = rng.integers(len(mesh._vpos))
        u = mesh._vaxis[v] + rng.normal(size=3) * rng.choice([0.05, 0.3, 1.0])
        u /= np.linalg.norm(u)
        local = mesh._vpos[v] + u * max(0.0, r + rng.uniform(-5e-4, 5e-4))
        out.append(to_world(mesh, local))
    return out


@pytest.mark.parametrize("which", sorted(MESHES))
def test_queries_along_the_surface_are_the_python_meshes_and_brute_force(tmp, which):
    """Sweeps and distances along paths that hug the surface and that hop about its vertices
    (the vertex certificate), where the kept certificates
    answer most queries (the hint, the walk to a nearer triangle, the few that rise above a
    tangent plane): each sweep, compiled and MeshShape's, the same touch as a pass over every
    triangle (1e-12 of the segment), each distance at the sweep's start (kept by the sweep) and end MeshShape's to
    1e-12 m."""
    m, d, shapes = MESHES[which](tmp)
    S, T, C, k = tables(shapes)
    mesh = shapes[k]
    rng = np.random.default_rng(13)
    hits = 0
    for r in (0.0, 0.005, 0.008):
        for path in (hugging_path(mesh, rng, 45, r), vertex_path(mesh, rng, 40, r)):
            for p, q in zip(path, path[1:]):
                u = [b - a for a, b in zip(p, q)]
                want = brute_sweep(mesh, p, u, r)
                got = mesh_sweep(S, T, C, d.geom_xpos, d.geom_xmat, k, *p, *u, r)
                py = mesh.sweep(*p, *u, r)
                if want is None:
                    assert got[0] == -1.0 and py is None, (which, p, u, r, got, py)
                else:
                    assert abs(got[0] - want[0]) <= 1e-12, (which, p, u, r, got, want)
                    assert py is not None and abs(py[0] - want[0]) <= 1e-12, (which, p, u, r, py, want)
                    hits += 1
                for x in (p, q):
                    want_d = mesh.distance(*x)
                    got_d = mesh_distance(S, T, C, d.geom_xpos, d.geom_xmat, k, *x)
                    assert abs(got_d[0] - want_d[0]) <= 1e-12, (which, x, got_d, want_d)
                    if abs(want_d[0]) > 1e-6:
                        assert np.dot(got_d[1:], want_d[1:]) > 1.0 - 1e-9, (which, x, got_d, want_d)
    assert hits > 20


def peak_in_a_wall():
    """An open sheet: a convex peak (tip at the origin, falling 1 mm over 2 mm) ringed by a wall
    2–2.5 mm high 3–6 mm out: straight above the tip the wall is nearer than the tip once the
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


def test_straight_above_a_peak_the_vertex_certificate_holds_at_its_cone_axis(tmp):
    """A point straight above a convex vertex sees it along the cone's axis, where n·axis may
    round to 1 + 2e-16: the vertex certificate's tilt sqrt(1 - c²) must not become NaN (the
    compiled engine then certified the tip and answered up to 0.5 mm too far; MeshShape
    raised ValueError). Both engines' distances equal a brute-force pass, the sheet randomly
    turned and moved, each point asked after one on the tip's fan (the hint there)."""
    from scipy.spatial.transform import Rotation
    rng = np.random.default_rng(2)
    base = peak_in_a_wall()
    for trial in range(12):
        turn = Rotation.random(random_state=int(rng.integers(1e9))).as_matrix()
        sheet_ = trimesh.Trimesh(base.vertices @ turn.T + rng.normal(size=3) * 0.01, base.faces, process=False)
        with pytest.warns(UserWarning, match="open mesh"):
            m, d, shapes = mesh_model(Path(tmp) / f"peak{trial}.obj", sheet_)
        S, T, C, k = tables(shapes)
        mesh = shapes[k]
        tip = int(np.flatnonzero(np.array([len(r) for r in mesh._ring]) == 12)[0])
        axis, p0 = mesh._vaxis[tip], mesh._vpos[tip]
        for _ in range(40):
            fan = to_world(mesh, p0 + axis * 3e-4)
            q = to_world(mesh, p0 + axis * rng.uniform(0.0035, 0.0055))
            a = mesh.to_local(*q)
            want = math.sqrt(min(_closest(t, *a)[0] for t in mesh._tri))
            mesh.distance(*fan)
            mesh_distance(S, T, C, d.geom_xpos, d.geom_xmat, k, *fan)
            assert abs(mesh.distance(*q)[0] - want) <= 1e-12, (trial, q)
            assert abs(mesh_distance(S, T, C, d.geom_xpos, d.geom_xmat, k, *q)[0] - want) <= 1e-12, (trial, q)
