"""Meshes at CAD scale: shapes made of explicit triangles, load-time tables bounded by local
geometry, one build per mesh asset, and several fingers on one mesh.

Every query answer is checked against `mesh_oracle.Oracle` (brute force over every triangle,
sharing no code with the engine).
"""

import math

import mujoco
import numpy as np
import pytest
import trimesh

from mesh_oracle import (
    EXACT, Oracle, assert_vertex_table, l_prism, mesh_model, mesh_of, point_triangle, triangles_near,
)
from softproxy.compiled.mesh import SLOT_NEAR
from softproxy.geometry import ShapeSet
from softproxy.mesh import MeshShape


def local_to_world(d, geom, p):
    """Geom-frame points (m) in the world frame."""
    return np.asarray(p) @ d.geom_xmat[geom].reshape(3, 3).T + d.geom_xpos[geom]


def test_explicit_triangles_make_a_mesh_shape_of_any_geom():
    """`MeshShape(..., triangles=(v, f))` answers on the triangles given, in the geom frame,
    whatever the geom is: on a turned box geom, the distances at random points are the brute
    force's over those triangles (a tetrahedron inside the box, so not the box's own), and
    a geom that is no mesh without triangles is refused with one line naming it."""
    xml = ('<mujoco><worldbody><body pos="0.1 -0.2 0.3" euler="20 30 -40">'
           '<geom name="box" type="box" size="0.05 0.05 0.05"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    v = np.array([[0.0, 0.0, 0.0], [0.03, 0.0, 0.0], [0.0, 0.03, 0.0], [0.0, 0.0, 0.03]]) - 0.0075
    f = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]])
    s = MeshShape(m, d, 0, True, triangles=(v, f))
    ShapeSet([s], d)
    assert s.triangles == 4 and s.signed
    o = Oracle(local_to_world(d, 0, v), f, True)
    rng = np.random.default_rng(1)
    points = local_to_world(d, 0, rng.uniform(-0.04, 0.04, size=(60, 3)))
    got = np.array([s.distance(*p)[0] for p in points])
    assert np.abs(got - o.distance(points)).max() <= EXACT
    assert (got < 0.0).any() and (got > 0.0).any()
    with pytest.raises(ValueError, match="'box' is not a mesh geom"):
        MeshShape(m, d, 0, True)
    with pytest.raises(ValueError, match="triangles must be"):
        MeshShape(m, d, 0, True, triangles=(v,))


def test_explicit_convex_hull_of_a_mesh_geom_is_felt_as_the_hull():
    """The convex hull of an L-shaped prism, given as triangles on its mesh geom, is what the
    queries answer on: a point in the L's inner corner is outside the mesh's own triangles
    and inside the hull, and random points match the brute force over the hull."""
    m, d, shapes = mesh_model(l_prism(), body='pos=".02 .01 -.01" euler="30 10 -20"')
    own = mesh_of(shapes)
    k = int(m.geom_dataid[own.geom])
    v = m.mesh_vert[m.mesh_vertadr[k]:m.mesh_vertadr[k] + m.mesh_vertnum[k]].astype(float)
    hull = trimesh.Trimesh(v).convex_hull
    s = MeshShape(m, d, own.geom, False, triangles=(hull.vertices, hull.faces))
    ShapeSet([s], d)
    o = Oracle(local_to_world(d, own.geom, hull.vertices), hull.faces, True)
    points = local_to_world(d, own.geom, np.random.default_rng(2).uniform(v.min(0), v.max(0), size=(80, 3)))
    got = np.array([s.distance(*p)[0] for p in points])
    assert np.abs(got - o.distance(points)).max() <= EXACT
    mine = np.array([own.distance(*p)[0] for p in points])
    assert ((mine > 0.002) & (got < -0.002)).any()  # in the L's inner corner: outside it, inside its hull


# ---------------------------------------------------------------------------------------
# Load-time tables bounded by local geometry
# ---------------------------------------------------------------------------------------

def cad_part(sections: int, seed: int = 0) -> trimesh.Trimesh:
    """Four closed cylinders (radius 6-8 mm, 1-3 cm tall, tilted) tessellated as a CAD export
    does: two slivers per section the whole height of the side, a fan of slivers on each cap."""
    rng = np.random.default_rng(seed)
    parts = []
    for i in range(4):
        c = trimesh.creation.cylinder(radius=rng.uniform(0.006, 0.008), height=rng.uniform(0.01, 0.03),
                                      sections=sections)
        turn = trimesh.transformations.euler_matrix(*rng.uniform(-0.3, 0.3, 3))
        turn[:3, 3] = [0.025 * (i % 2), 0.025 * (i // 2), 0.0]
        c.apply_transform(turn)
        parts.append(c)
    return trimesh.util.concatenate(parts)


def old_rule_pairs(v: np.ndarray, f: np.ndarray, reach: float) -> int:
    """How many (vertex, vertex) pairs the former load-time rule gathered for the vertex
    tables alone: every vertex within reach + twice the largest triangle's bounding radius."""
    from scipy.spatial import cKDTree

    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    centre = (a + b + c) / 3.0
    rho = np.sqrt(np.max([((x - centre) ** 2).sum(1) for x in (a, b, c)], axis=0)).max()
    tree = cKDTree(v)
    return int(tree.count_neighbors(tree, reach + 2.0 * rho))


def test_sliver_heavy_mesh_builds_within_bounded_memory():
    """A CAD-like part of 24k triangles, nearly all slivers (sides 2-3 cm long and ~30 µm
    wide, caps of 1500-sliver fans): the former rule gathered over 10⁸ vertex pairs; the
    tables now build in bounded memory (peak under 200 MB, the tables themselves included)
    and the same triangles load once (a second load is the same tables, at once)."""
    import tracemalloc

    from softproxy.mesh import reach, tables_of

    part = cad_part(1500)
    v, f = np.asarray(part.vertices), np.asarray(part.faces)
    assert old_rule_pairs(v, f, reach(0.005)) > 1e8
    tracemalloc.start()
    tables = tables_of(v, f, "cad part", "g")
    peak = tracemalloc.get_traced_memory()[1]
    tracemalloc.stop()
    assert tables.triangles == len(f) and peak < 200e6
    assert tables_of(v.copy(), f.copy(), "the same part again", "g") is tables


@pytest.mark.slow  # a long property run
def test_sliver_heavy_tables_hold_what_the_queries_need():
    """On a sliver-heavy part (long side slivers, fans on the caps, four cylinders close
    enough to rise above each other's faces), for sampled faces: every triangle within the
    reach of the face (by points spread over both) rising above its plane is listed, or the
    face is marked concave (which only sends its queries to the box tree); for sampled vertices: every vertex of a triangle within the reach
    (exact point-triangle distance) but its ring is in the table no later than its sin β."""
    from softproxy.mesh import reach, tables_of

    part = cad_part(200, seed=3)
    t = tables_of(np.asarray(part.vertices, float), np.asarray(part.faces), "cad part", "g")
    assert t.kept == reach(0.005)
    rng = np.random.default_rng(4)
    certified, concave = assert_tables_hold(t, rng.choice(t.triangles, 100, replace=False),
                                            rng.choice(len(t.vpos), 100, replace=False))
    assert certified > 0 and concave > 0


def assert_tables_hold(t, faces, vertices) -> tuple[int, int]:
    """The kept certificates of tables `t` (a `MeshTables`) hold what the queries need, by
    brute force: for each of `faces`, every triangle within the reach of the face (by points
    spread over both) rising above its plane is listed, or the face is marked concave (which
    only sends its queries to the box tree); for each of `vertices`, every vertex of a
    triangle within the reach (exact point-triangle distance) but its ring is in the table
    no later than its sin β. Returns (sides certified, sides concave)."""
    from mesh_oracle import Oracle
    from softproxy.compiled.certificate import ABOVE_TOL, VERTEX_READ

    v, f = t.vpos, t.tv  # as validated
    o = Oracle(v, f, True)
    radius = t.kept
    abc = v[f]
    weights = np.array([(a, b, 8 - a - b) for a in range(9) for b in range(9 - a)], float) / 8.0
    samples = np.einsum("sk,tkx->tsx", weights, abc)
    certified = concave = 0
    for i in faces:
        near = triangles_near(o, samples, i, radius)
        height = abc[near] @ o.n[i] - o.off[i]
        for side, key in ((1.0, i), (-1.0, -1 - i)):
            rising = set(near[(side * height > ABOVE_TOL).any(axis=1)].tolist()) - {i}
            got = t_lists(t, key)
            if got is None:
                concave += 1
            else:
                certified += 1
                assert rising <= set(got), (i, side)
    _, start, sines, ids = t.vtable
    normal = t.vcone[:, :3]
    for vertex in vertices:
        assert_vertex_table(o, v, f, vertex, radius, normal[vertex], sines[start[vertex]:start[vertex + 1]].tolist(),
                            ids[start[vertex]:start[vertex + 1]].tolist(), VERTEX_READ)
    return certified, concave


def test_a_face_of_long_triangles_sees_short_ones_rising_above_it():
    """A ground of two long triangles with a small box of short ones standing on it: the
    box's triangles rise above the ground's plane within its reach, more than a list holds,
    so each ground face is concave on its upper side. A face's walk finds short triangles
    through their vertices and long ones in their own tree; a walk over the wrong vertices
    (the long triangles') finds nothing rising and would certify the ground empty."""
    import warnings

    from softproxy.compiled.certificate import ABOVE_TOL, STATIC_ABOVE
    from softproxy.mesh import tables_of

    ground = np.array([[-0.02, -0.02, 0.0], [0.02, -0.02, 0.0], [0.02, 0.02, 0.0], [-0.02, 0.02, 0.0]])
    box = trimesh.creation.box(extents=(0.002, 0.002, 0.002))
    bv, bf = trimesh.remesh.subdivide(box.vertices + [0.0, 0.0, 0.001], box.faces)
    bv, bf = trimesh.remesh.subdivide(bv, bf)
    v = np.vstack([ground, bv])
    f = np.vstack([[[0, 1, 2], [0, 2, 3]], bf + len(ground)])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an open sheet
        t = tables_of(v, f, "ground and box", "g")
    abc = t.vpos[t.tv]
    span = np.linalg.norm(abc - np.roll(abc, 1, axis=1), axis=2).max(axis=1)
    floor = np.flatnonzero(span > 0.01)
    assert len(floor) == 2
    rising = np.count_nonzero(abc[span < 0.01, :, 2].max(axis=1) > ABOVE_TOL)
    assert rising > STATIC_ABOVE
    for i in floor:
        up = 0 if t.plane[i, 2] > 0.0 else 1
        assert t.clear[i, up] == -1, (i, t.clear[i])


def t_lists(t, key):
    """A face's kept list (key i or -1 - i for its back) as a tuple, None for a concave patch."""
    i, side = (key, 0) if key >= 0 else (-1 - key, 1)
    m = int(t.clear[i, side])
    return None if m < 0 else tuple(t.listed[i, side, :m].tolist())


def test_sliver_heavy_queries_match_the_brute_force():
    """Distances and sweeps about a sliver-heavy part's edges and vertices (the hint on or near
    the feature: thin fans at the caps' centres, long slivers down the sides), through the
    tables built under the local rule: the brute force's answers."""
    from test_mesh_queries import check_distance, near_features, start_from

    m, d, shapes = mesh_model(cad_part(120, seed=5), body='pos=".01 0 .02" euler="10 20 30"')
    o = Oracle(*world_mesh(m, d, 0), True)
    s = mesh_of(shapes)
    rng = np.random.default_rng(6)
    for k, (p, hint) in enumerate(near_features(o, rng, 120, reach=0.008)):
        start_from(s, hint)
        check_distance(o, s, [p], k)
        start_from(s, hint)
        u = rng.normal(size=3) * rng.choice([1e-4, 1e-3, 3e-3])
        r = [0.0, 0.002, 0.005][k % 3]
        o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=k)


def world_mesh(m, d, geom):
    from mesh_oracle import world_mesh as placed

    return placed(m, d, geom)


# ---------------------------------------------------------------------------------------
# One build per mesh asset
# ---------------------------------------------------------------------------------------

def test_two_geoms_of_one_asset_share_one_build():
    """Two geoms using one mesh asset, at different poses, get the same tables (built once)
    and one copy of its triangles in the engine's table T; each answers at its own pose (the
    brute force's distances)."""
    ball = trimesh.creation.icosphere(3, radius=0.03)
    verts = " ".join(f"{x:.10g}" for x in np.asarray(ball.vertices).ravel())
    faces = " ".join(str(int(i)) for i in np.asarray(ball.faces).ravel())
    xml = (f'<mujoco><asset><mesh name="m" vertex="{verts}" face="{faces}"/></asset><worldbody>'
           '<geom name="a" type="mesh" mesh="m" pos="0.1 0 0"/>'
           '<geom name="b" type="mesh" mesh="m" pos="-0.1 0 0.05" euler="30 0 0"/></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    from softproxy.geometry import shapes_of

    shapes = shapes_of(m, d, mesh_shape=MeshShape)
    a, b = shapes
    assert a.tables is b.tables
    assert len(shapes.T) == a.triangles
    assert shapes.S[a.row].t0 == shapes.S[b.row].t0
    rng = np.random.default_rng(8)
    for g, shape in ((0, a), (1, b)):
        o = Oracle(*world_mesh(m, d, g), True)
        points = d.geom_xpos[g] + rng.normal(scale=0.03, size=(40, 3))
        got = np.array([shape.distance(*p)[0] for p in points])
        assert np.abs(got - o.distance(points)).max() <= EXACT


# ---------------------------------------------------------------------------------------
# Several fingers on one mesh
# ---------------------------------------------------------------------------------------

def finger_paths(o: Oracle, count: int, ticks: int, rng):
    """Device paths for `count` fingers on the mesh's upper side, 2 cm apart: each pressed 2 mm
    into a 5 mm proxy's reach and sliding on a 3 mm circle about its own spot."""
    top = np.flatnonzero(o.n[:, 2] > 0.8)
    spots = [int(top[0])]
    for i in rng.permutation(top):
        if all(np.linalg.norm(o.centre[i] - o.centre[j]) > 0.02 for j in spots):
            spots.append(int(i))
        if len(spots) == count:
            break
    assert len(spots) == count
    paths = []
    for i in spots:
        n = o.n[i]
        t1 = np.cross(n, [1.0, 0.0, 0.0])
        t1 /= np.linalg.norm(t1)
        t2 = np.cross(n, t1)
        at = o.centre[i] + 0.003 * n
        paths.append([at + 0.003 * (math.cos(0.05 * k) * t1 + math.sin(0.05 * k) * t2) for k in range(ticks)])
    return paths


def test_fingers_on_one_mesh_agree_with_each_finger_alone():
    """Five god-objects sliding on one mesh, updated in turn each tick, follow the same paths
    as each alone on a fresh load (to 1e-12 m): one finger's queries never change another's
    answers; and each keeps to a hint slot of its own (their last queries lie by them)."""
    from mesh_oracle import geodesic_sphere
    from softproxy.proxy import GodObject

    mesh = geodesic_sphere(14, 0.05)
    rng = np.random.default_rng(9)
    m, d, shapes = mesh_model(mesh)
    o = Oracle(*world_mesh(m, d, 0), True)
    paths = finger_paths(o, 5, 150, rng)
    gods = [GodObject(shapes, 0.005, 0.5, 0.4, tuple(p[0] + 0.01 * (p[0] / np.linalg.norm(p[0])))) for p in paths]
    together = [[] for _ in gods]
    for k in range(150):
        for god, path, out in zip(gods, paths, together):
            god.update(*path[k])
            out.append((god.x, god.y, god.z))
    assert all(god.contact for god in gods)
    s = mesh_of(shapes)
    slots = shapes.S[s.row].key
    used = slots[~np.isnan(slots[:, 0]), :3]  # a slot never used has no last query
    own = [np.linalg.norm(used - (god.x, god.y, god.z), axis=1).argmin() for god in gods]
    assert len(set(own)) == len(gods)
    for god, k in zip(gods, own):
        assert np.linalg.norm(used[k] - (god.x, god.y, god.z)) < SLOT_NEAR
    for f, path in enumerate(paths):
        _, _, alone_shapes = mesh_model(mesh)
        god = GodObject(alone_shapes, 0.005, 0.5, 0.4, tuple(path[0] + 0.01 * (path[0] / np.linalg.norm(path[0]))))
        alone = []
        for k in range(150):
            god.update(*path[k])
            alone.append((god.x, god.y, god.z))
        assert np.abs(np.array(alone) - np.array(together[f])).max() <= 1e-12, f


def test_bench_meshes_in_miniature():
    """`softproxy bench meshes` in miniature: every kind of mesh loads and is timed pressed and
    sliding, with 1, 2 and 5 fingers at the middle size, and so does each shape of high
    valence at one size; the generated meshes have about the triangles asked for, the
    sliver kind is made of slivers (aspect over 50), and the hubs have the valence asked for."""
    from softproxy.benchmarks import meshes

    v, f = meshes.slivers(40000)
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    longest = np.max([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1), np.linalg.norm(a - c, axis=1)], 0)
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    assert np.median(longest * longest / area2) > 50
    hubs = {"fan-capped cylinder": 2000, "UV sphere, fan poles": 2000, "height field": 24}
    result = meshes.measure(sizes=(1500, 3000, 6000), updates=30, warm=10, hubs=hubs)
    rows = result["rows"]
    assert len(rows) == 9 + len(meshes.BESIDE) + len(meshes.HUBS)
    assert {r["kind"] for r in rows} == set(meshes.KINDS) | set(meshes.HUBS)
    sizes = [1500, 3000, 6000] * 3 + [7500] * len(meshes.BESIDE) + [2000, 2000, 2 * 23 * 23]
    for r, size in zip(rows, sizes):
        assert 0.5 * size < r["triangles"] < 1.5 * size and r["load_s"] > 0.0 and r["peak_mb"] > 0.0
        assert r["rss_mb"] >= 0.0
        assert r["pressed_1f_p99_us"] >= r["pressed_1f_p50_us"] > 0.0
    # the cylinder's caps and the sphere's poles are fans about one vertex of the size asked
    assert [r["hub"] for r in rows[-3:-1]] == [2000 // 4, 2000 // 4]
    assert all("sliding_5f_p99_us" in r and "sliding_5f_alone_p99_us" in r for r in rows[1:9:3])
    # the smallest beside a copy of the largest: the same spot, so the same triangles in reach
    for r in rows[9:9 + len(meshes.BESIDE)]:
        small = next(s for s in rows[:9:3] if s["kind"] == r["kind"])
        assert 0.5 * 6000 < r["beside"] < 1.5 * 6000 and r["triangles"] == small["triangles"] + r["beside"]
        assert r["sliding_in_reach_p50"] == small["sliding_in_reach_p50"]
        assert r["pressed_in_reach_p50"] == small["pressed_in_reach_p50"]
    # a proxy pressed in or sliding touches the surface: at least the triangle under it is within reach
    assert all(r["pressed_in_reach_p50"] >= 1 and r["sliding_in_reach_p50"] >= 1 for r in rows)


def test_the_bench_counts_the_triangles_within_a_ticks_reach():
    """`bench meshes`' count of the triangles within a proxy's radius plus its move that tick,
    on a flat grid of 1 mm squares (6 triangles meet at an inner vertex of this grid): a
    proxy resting on a vertex has those 6 within reach (and still, rising 2 µm in the tick),
    one held 2 µm above it none, and one that slid 3 mm in the tick every triangle within
    √((r + 3 mm)² - r²) ≈ 6.2 mm of it; and over 0.4 mm squares one resting over a
    triangle's incentre (0.117 mm from every side), that one alone (trimesh's closest point,
    used as it comes, compares products of four lengths with 1e-12 and answered ~0.1 mm off
    such a point: none within reach)."""
    from softproxy.benchmarks import meshes

    v, f = meshes.grid(2 * 20 * 20)  # 21 × 21 vertices 5 mm apart: scaled to 1 mm below
    v[:, 2] = 0.0
    r = meshes.RADIUS
    on = np.array([0.0, 0.0, r])  # on the middle vertex
    path = [on, on, on + [0.0, 0.0, 2e-6], on + [0.0, 0.0, 2e-6], on + [0.003, 0.0, 0.0]]
    counts = meshes.within_reach(v / 5.0, f, path, every=1)
    assert counts.tolist()[:3] == [6, 6, 0]
    far = counts[3]
    disc = np.sqrt((r + 0.003 + 1e-6) ** 2 - r * r)
    centres = (v / 5.0)[f].mean(axis=1)
    assert np.sum(np.linalg.norm(centres[:, :2] - [0.003, 0.0], axis=1) < disc - 0.001) <= far
    assert far <= np.sum(np.linalg.norm(centres[:, :2] - [0.003, 0.0], axis=1) < disc + 0.001)
    assert meshes.within_reach(v / 5.0, f, path, every=2).tolist() == [6, 0]
    fine = v * 0.08  # 0.4 mm squares: the disc within reach, 0.1 mm in radius, inside one triangle
    a, b, c = fine[f[200]]
    sides = [np.linalg.norm(b - c), np.linalg.norm(c - a), np.linalg.norm(a - b)]
    middle = (sides[0] * a + sides[1] * b + sides[2] * c) / sum(sides) + [0.0, 0.0, r]  # over its incentre
    assert meshes.within_reach(fine, f, [middle, middle], every=1).tolist() == [1]


# ---------------------------------------------------------------------------------------
# High-valence vertices, long slivers: the shapes whose load once grew faster than their size
# ---------------------------------------------------------------------------------------

HFIELD = ('<mujoco><asset><hfield name="h" nrow="20" ncol="24" size="0.1 0.08 0.02 0.01"/></asset>'
          '<worldbody><body name="b" pos=".01 -.02 .03" euler="10 -20 30"><geom name="g" type="hfield" hfield="h"/>'
          '</body></worldbody></mujoco>')


def hub_shapes():
    """(name, model, data, MeshShape, its triangles in the world frame) of a fan-capped
    cylinder (150 sections: each cap's hub has 152 triangles), a UV sphere whose poles are
    fans of 150 slivers, and a 20 × 24 height field (its bottom a fan of 84 slivers 10-13 cm
    long about one vertex, its walls slivers), each turned and moved off the origin."""
    from softproxy.benchmarks.meshes import fan_cylinder, uv_sphere
    from softproxy.geometry import hfield_triangles, shapes_of

    out = []
    for name, (v, f) in (("fan-capped cylinder", fan_cylinder(600)), ("uv sphere", uv_sphere(600))):
        m, d, shapes = mesh_model(trimesh.Trimesh(v, f, process=False), body='pos=".01 -.02 .03" euler="10 -20 30"')
        out.append((name, m, d, mesh_of(shapes), world_mesh(m, d, 0)))
    m = mujoco.MjModel.from_xml_string(HFIELD)
    rows, cols = int(m.hfield_nrow[0]), int(m.hfield_ncol[0])
    y, x = np.meshgrid(np.linspace(0.0, 1.0, rows), np.linspace(0.0, 1.0, cols), indexing="ij")
    m.hfield_data[:] = (0.5 + 0.4 * np.sin(7.0 * x) * np.cos(5.0 * y)).ravel()
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    v, f = hfield_triangles(m, 0)
    out.append(("height field", m, d, mesh_of(shapes_of(m, d)), (local_to_world(d, 0, v), f)))
    return out


@pytest.mark.parametrize("which", range(3), ids=["fan-capped cylinder", "uv sphere", "height field"])
def test_hubs_and_long_slivers_are_touched_exactly(which):
    """The shapes whose load once grew with a vertex's valence or a sliver's length (a cap's
    fan, a UV sphere's poles, a height field's bottom fan and walls), small: their kept
    certificates hold what the queries need (every face within reach of the hub, vertices
    about it and anywhere), and distances and sweeps about the hub and about random edges
    and vertices, from a hint on or near the feature, are the brute force's."""
    from test_mesh_queries import check_distance, near_features, start_from

    name, m, d, s, (wv, wf) = hub_shapes()[which]
    t = s.tables
    o = Oracle(wv, wf, s.signed)
    valence = np.bincount(t.tv.ravel(), minlength=len(t.vpos))
    hub = int(np.argmax(valence))
    assert valence[hub] > 64  # a hub: its fan is found in the tree of long triangles
    rng = np.random.default_rng(7 + which)
    fan = np.flatnonzero((t.tv == hub).any(axis=1))
    near_hub = np.flatnonzero(np.linalg.norm(t.centre - t.vpos[hub], axis=1) < t.kept + t.rhos)
    around_hub = np.flatnonzero(np.linalg.norm(t.vpos - t.vpos[hub], axis=1) < t.kept)
    faces = np.union1d(rng.choice(near_hub, min(60, len(near_hub)), replace=False), rng.choice(t.triangles, 20))
    vertices = np.union1d(rng.choice(around_hub, min(30, len(around_hub)), replace=False), [hub])
    certified, _ = assert_tables_hold(t, faces, np.union1d(vertices, rng.choice(len(t.vpos), 10)))
    assert certified > 0
    # the hub where the world has it (the world's triangles are the compiled mesh's)
    at = local_to_world(d, s.geom, t.vpos[hub])
    w_hub = int(np.argmin(np.linalg.norm(wv - at, axis=1)))
    w_fan = np.flatnonzero((wf == w_hub).any(axis=1))
    assert len(w_fan) == len(fan)
    ways = rng.normal(size=(40, 3))
    ways /= np.linalg.norm(ways, axis=1)[:, None]
    cases = [(at + u * 0.006 * rng.uniform() ** 2, int(rng.choice(w_fan))) for u in ways]
    cases += near_features(o, rng, 40)
    for k, (p, hint) in enumerate(cases):
        start_from(s, hint)
        check_distance(o, s, [p], (name, k))
        start_from(s, hint)
        u = rng.normal(size=3) * rng.choice([1e-4, 1e-3, 3e-3])
        r = [0.0, 0.002, 0.005][k % 3]
        o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=(name, k))


# ---------------------------------------------------------------------------------------
# The box tree (where no certificate holds)
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["slivers", "noisy_sphere"])
def test_node_frames_match_each_nodes_first_triangle_and_vertices(kind):
    """`node_frames` against a brute force node by node: each node's axes are its first
    triangle's normal, longest edge (the first of equal ones) and their cross product, and
    its extents the least and greatest projection on them of its triangles' vertices (those
    of the leaves under it); a node with no triangle keeps zero axes and inverted extents."""
    from softproxy.benchmarks import meshes
    from softproxy.compiled.tree_walk import LEAF
    from softproxy.mesh_trees import box_tree, node_frames

    v, f = getattr(meshes, kind)(1000)
    t = v[f]
    normal = np.cross(t[:, 1] - t[:, 0], t[:, 2] - t[:, 0])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    plane = np.column_stack([normal, (normal * t[:, 0]).sum(axis=1)])
    some = np.flatnonzero(np.arange(len(f)) % 3 != 1)  # a tree over part of the mesh, as the long triangles'
    order, _, _, size = box_tree(t[some].min(axis=1), t[some].max(axis=1), some)
    axes, ext = node_frames(order, size, v, f, plane)
    for node in range(1, 2 * size):
        level = 1 << (node.bit_length() - 1)
        leaves = size // level
        items = order[(node - level) * leaves * LEAF:(node - level + 1) * leaves * LEAF]
        if len(items) == 0:
            assert not axes[node].any() and (ext[node, :, 0] == np.inf).all() and (ext[node, :, 1] == -np.inf).all()
            continue
        a, b, c = t[items[0]]
        edges = [b - a, c - b, a - c]
        longest = edges[int(np.argmax([e @ e for e in edges]))]
        frame = np.array([normal[items[0]], longest / np.linalg.norm(longest),
                          np.cross(normal[items[0]], longest / np.linalg.norm(longest))])
        assert np.allclose(axes[node], frame, rtol=0.0, atol=1e-15), node
        heights = t[items].reshape(-1, 3) @ frame.T
        assert np.allclose(ext[node, :, 0], heights.min(axis=0), rtol=0.0, atol=1e-15), node
        assert np.allclose(ext[node, :, 1], heights.max(axis=0), rtol=0.0, atol=1e-15), node
    # two longest edges of exactly one length: the first, c2 - c1
    axes, _ = node_frames(np.array([0]), 1, np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, 2.0, 0.0]]),
                          np.array([[0, 1, 2]]), np.array([[0.0, 0.0, 1.0, 0.0]]))
    assert np.allclose(axes[1, 1], np.array([-0.5, 2.0, 0.0]) / math.sqrt(4.25), rtol=0.0, atol=1e-15)


def tree_shape(v, f):
    """(MeshShape on explicit triangles on a turned box geom, brute force in the world frame)."""
    xml = ('<mujoco><worldbody><body pos="0.02 -0.01 0.03" euler="20 -30 40">'
           '<geom type="box" size="0.01 0.01 0.01"/></body></worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    s = MeshShape(m, d, 0, True, triangles=(v, f))
    ShapeSet([s], d)
    t = s.tables
    return s, Oracle(local_to_world(d, 0, t.vpos), t.tv, s.signed)


def from_tree(shape, hint: int = -1) -> None:
    """The next query of `shape` starts from triangle `hint` (-1: none, so it goes straight to
    the box tree), its kept answers forgotten, and it keeps no patches (the tree answers
    what the hint does not)."""
    record = shape.set.S[shape.row]
    record.hint = -1 if hint < 0 else int(record.t0) + hint
    record.key[:, :] = math.nan
    record.patch = -1


def noisy_ball(triangles: int):
    from softproxy.benchmarks.meshes import noisy_sphere

    return noisy_sphere(triangles, seed=3)


def sliver_part():
    part = cad_part(300, seed=7)
    return part.vertices, part.faces


@pytest.mark.parametrize("make", [sliver_part, lambda: noisy_ball(6000)], ids=["slivers", "noisy sphere"])
def test_tree_queries_match_the_brute_force(make):
    """With no hint, every distance and sweep is the box tree's walk alone: on a sliver-heavy
    part and on a noisy sphere, at random points near and far and on random segments short
    and long (radius 0, 2 and 5 mm), its answers are the brute force's. The tree holds fewer
    nodes than triangles (its memory is bounded by the mesh's)."""
    from test_mesh_queries import check_distance

    v, f = make()
    s, o = tree_shape(np.asarray(v, float), np.asarray(f))
    _, size, nodes = s.tables.tree
    assert len(nodes) == 2 * size <= max(2, s.triangles)
    rng = np.random.default_rng(11)
    lo, hi = o.v.min(0), o.v.max(0)
    surface = o.centre[rng.choice(len(o.f), 60)] + rng.normal(scale=0.004, size=(60, 3))
    points = np.vstack([surface, rng.uniform(lo - 0.02, hi + 0.02, size=(20, 3))])
    for k, p in enumerate(points):
        from_tree(s)
        check_distance(o, s, [p], k)
    for k, p in enumerate(surface):
        u = rng.normal(size=3) * rng.choice([1e-4, 3e-3, 3e-2])
        r = [0.0, 0.002, 0.005][k % 3]
        from_tree(s)
        o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=k)


def test_tree_sweeps_sliding_over_a_fan_of_slivers_match_the_brute_force():
    """A sphere resting on a cap of a CAD part (a fan of 300 slivers meeting at its centre,
    every one within its reach) and sliding along it, into it, or off its rim into a
    neighbouring part's side, swept by the box tree: from no hint, the nodes it stays r
    above are left out though its start lies within reach of them; from the sliver it rests
    on, whose tangent plane too many triangles rise above for a certificate, so are the
    nodes wholly behind that plane. The nodes it moves into, or that rise above the plane,
    are not: every answer is the brute force's, and the walls are hit."""
    s, o = tree_shape(*sliver_part())
    # the centre of the cap's fan with the most of its neighbours' sides level with it
    counts = np.bincount(o.f.ravel())
    level = []
    for h in np.flatnonzero(counts >= 100):
        t = np.flatnonzero((o.f == h).any(axis=1))[0]
        n = np.cross(o.b[t] - o.a[t], o.c[t] - o.a[t])
        n /= np.linalg.norm(n)
        level.append(np.count_nonzero((np.abs((o.centre - o.v[h]) @ n) < 0.002)
                                      & (np.linalg.norm(o.centre - o.v[h], axis=1) > 0.012)))
    hub = np.flatnonzero(counts >= 100)[int(np.argmax(level))]
    fan = np.flatnonzero((o.f == hub).any(axis=1))
    rng = np.random.default_rng(5)
    hits = walls = 0
    for k in range(90):
        t = fan[rng.integers(len(fan))]
        n = np.cross(o.b[t] - o.a[t], o.c[t] - o.a[t])
        n /= np.linalg.norm(n)
        w = rng.dirichlet([1.0, 1.0, 1.0] if k % 2 else [0.1, 3.0, 3.0])  # (every other near the rim)
        foot = w[0] * o.a[t] + w[1] * o.b[t] + w[2] * o.c[t]
        if o.distance([foot + 1e-4 * n])[0] < 0.0:
            n = -n  # outward
        r = [0.002, 0.005][k % 2]
        if k % 3 == 2:  # along the cap, off its rim and on into a neighbouring part's side
            height = (o.centre - foot - r * n) @ n  # over the sphere's centre
            aim = np.flatnonzero((np.abs(height) < 0.5 * r) & (np.linalg.norm(o.centre - foot, axis=1) > 0.012))
            along = o.centre[aim[rng.integers(len(aim))]] - foot
            along = 0.04 * (along - n * (along @ n)) / np.linalg.norm(along - n * (along @ n))
        else:
            along = np.cross(n, rng.normal(size=3))
            along *= rng.choice([1e-4, 1e-3, 5e-3]) / np.linalg.norm(along)
        u = along + n * np.linalg.norm(along) * [-0.05, 0.0, 0.0][k % 3]
        # from the tree alone, then from the touched sliver as the hint (a tangent plane the
        # sphere stays r above: what lies behind it is left out)
        for hint in (-1, t):
            from_tree(s, hint)
            got = s.sweep(*(foot + r * n), *u, r)
            o.check_sweep(foot + r * n, u, r, got, context=(k, hint))
            hits += got is not None
            walls += got is not None and k % 3 == 2
    assert 20 <= hits < 180 and walls >= 6


def test_tree_finds_the_nearest_triangle_in_a_far_leaf():
    """Where the nearest triangle lies in a part of the tree far from the hint (a small
    tetrahedron 2.5 cm off a noisy sphere, the hint on the sphere's far side), the walk
    finds it; and a sphere leaving the sphere's surface towards the tetrahedron, its start
    inside the boxes of the sphere's nodes nearby (entered first), stops on the tetrahedron
    where the brute force does: a walk that left out a node it must read (a box bound too
    tight, a best distance or touch taken too early) would answer on the noisy sphere or
    miss the tetrahedron."""
    from mesh_oracle import small_tetra
    from test_mesh_queries import check_distance

    bv, bf = noisy_ball(4000)
    tetra = small_tetra(np.array([0.075, 0.0, 0.0]))
    v = np.vstack([bv, tetra.vertices])
    f = np.vstack([bf, np.asarray(tetra.faces) + len(bv)])
    s, o = tree_shape(v, f)
    assert s.triangles == len(f)
    far_side = int(np.argmin(s.tables.centre[:, 0]))
    toward = o.v[-4:].mean(0)  # the tetrahedron's centre (world frame)
    out = (toward - o.v[:-4].mean(0)) / np.linalg.norm(toward - o.v[:-4].mean(0))
    rng = np.random.default_rng(12)
    points = toward + rng.normal(scale=0.003, size=(20, 3))
    assert (o.nearest(points)[2] >= len(bf)).all()  # every one nearest a tetrahedron's triangle
    for k, p in enumerate(points):
        from_tree(s, far_side)
        check_distance(o, s, [p], k)
    hits = 0
    for k in range(12):
        start = toward - 0.021 * out + rng.normal(scale=0.001, size=3)
        u = toward + rng.normal(scale=1e-4, size=3) - start
        from_tree(s, far_side)
        hit = s.sweep(*start, *u, 0.001)
        o.check_sweep(start, u, 0.001, hit, context=k)
        hits += hit is not None
    assert hits == 12


def fine_dish(spacing: float = 5e-4, half: float = 0.012):
    """An open dish z = (x² + y²) / 0.2 m (concave: no certificate holds on it) of triangles
    `spacing` (m) apart: dense enough that a 5 mm sphere resting on it has hundreds of
    triangles within 1 mm of its reach."""
    n = int(round(2 * half / spacing)) + 1
    x, y = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n), indexing="ij")
    v = np.column_stack([x.ravel(), y.ravel(), (x.ravel() ** 2 + y.ravel() ** 2) / 0.2])
    k = np.arange(n * n).reshape(n, n)[:-1, :-1].ravel()
    f = np.vstack([np.column_stack([k, k + n, k + 1]), np.column_stack([k + 1, k + n, k + n + 1])])
    return v, f


def dish_floor(spacing: float, half: float = 0.012):
    """A `fine_dish` as a mesh shape on a turned geom (shape, brute force), and at the bottom of
    its floor a corner a of a triangle there, that triangle's unit normal n and a unit
    tangent t (world frame)."""
    import warnings

    v, f = fine_dish(spacing, half)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an open mesh
        s, o = tree_shape(v, f)
    a, b, c = o.v[f[f[:, 0] == len(v) // 2][0]]  # (0, 0, 0): faces (k, k + n, k + 1) begin at k
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    t = np.cross(n, [1.0, 0.0, 0.0])
    return s, o, a, n, t / np.linalg.norm(t)


def segment_triangles(a, b, A, B, C) -> np.ndarray:
    """Distance (m) from the segment a..b to each triangle (A[k], B[k], C[k]): the least of
    the point-to-triangle distance along the segment, which is convex in the position along
    it, by golden-section search (brute force; a little above the least, never below)."""
    lo, hi = np.zeros(len(A)), np.ones(len(A))
    g = (math.sqrt(5.0) - 1.0) / 2.0

    def at(t):
        return point_triangle(a + t[:, None] * (b - a), A, B, C)[0]

    for _ in range(80):
        t1, t2 = hi - g * (hi - lo), lo + g * (hi - lo)
        left = at(t1) <= at(t2)
        hi, lo = np.where(left, t2, hi), np.where(left, lo, t1)
    return np.minimum(at((lo + hi) / 2.0), np.minimum(at(np.zeros(len(A))), at(np.ones(len(A)))))


def test_a_patch_holds_every_triangle_nearer_than_its_radius():
    """A hint slot's patch (`_gather`) against brute force on a dense dish: it holds every
    triangle within its capsule's radius of its segment, nearest first by a lower bound on
    the distance that never exceeds it; where more than PATCH_RECORDS lie within the radius
    asked, the capsule shrinks to what it holds, as it does where the walk has no room to keep
    a node waiting; and where even that falls below the least asked for, the patch is left
    as it was."""
    import warnings

    from softproxy.compiled.layout import (
        P_COUNT, P_KEYS, P_RADIUS, P_RECORDS, PATCH_RECORDS, PATCH_WIDTH, R_ROW, RECORD_WIDTH,
    )
    from softproxy.compiled.patch import _gather

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an open mesh
        s, _ = tree_shape(*fine_dish(2.5e-4))
    t = s.tables
    A, B, Cv = (t.vpos[t.tv[:, k]] for k in range(3))
    centre = (A + B + Cv) / 3.0
    circum = np.max([np.linalg.norm(X - centre, axis=1) for X in (A, B, Cv)], axis=0)
    S, C, k = s.set.S, s.set.C, s.row
    at, t0 = int(S[k].patch), int(S[k].t0)
    rng = np.random.default_rng(7)
    shrunk = whole = 0
    for i in range(24):
        x, y = rng.uniform(-0.006, 0.006, 2)
        a = np.array([x, y, (x * x + y * y) / 0.2 + rng.uniform(0.0, 0.006)])
        b = a + rng.normal(size=3) * [0.0, 1e-4, 2e-3][i % 3]
        radius = rng.uniform(0.0005, 0.004)
        assert _gather(S, C, k, at, *a, *b, radius, 0.0)
        m, held = int(C[at + P_COUNT]), C[at + P_RADIUS]
        keys = C[at + P_KEYS:at + P_KEYS + m]
        rows = C[at + P_RECORDS + R_ROW:at + P_RECORDS + RECORD_WIDTH * m:RECORD_WIDTH].astype(np.int64) - t0
        # the brute force, on the triangles a ball about a may hold (a bound, not the engine's)
        near = np.flatnonzero(np.linalg.norm(centre - a, axis=1) - circum <= radius + np.linalg.norm(b - a))
        d = np.full(len(A), np.inf)
        d[near] = segment_triangles(a, b, A[near], B[near], Cv[near])
        assert len(set(rows.tolist())) == m, i
        assert np.all(np.diff(keys) >= 0.0), i
        assert np.all(keys <= d[rows] ** 2 * (1.0 + 1e-9) + 1e-18), i
        assert set(np.flatnonzero(d <= held - 1e-9).tolist()) <= set(rows.tolist()), i
        if m == PATCH_RECORDS and held < radius:
            shrunk += 1
            assert np.count_nonzero(d <= radius) > PATCH_RECORDS, i
        else:
            whole += 1
            assert held == radius and np.all(keys <= radius * radius), i
    assert shrunk >= 4 and whole >= 4
    # with room for only a few nodes waiting, the walk cannot keep every node within the
    # radius: the capsule shrinks to the nearest it dropped, and still holds all within it
    short = 0
    for i in range(24):
        x, y = rng.uniform(-0.006, 0.006, 2)
        a = np.array([x, y, (x * x + y * y) / 0.2 + rng.uniform(0.0, 0.006)])
        b = a + rng.normal(size=3) * [0.0, 1e-4, 2e-3][i % 3]
        radius = rng.uniform(0.0005, 0.004)
        assert _gather(S, C, k, at, *a, *b, radius, 0.0, 3)
        m, held = int(C[at + P_COUNT]), C[at + P_RADIUS]
        rows = C[at + P_RECORDS + R_ROW:at + P_RECORDS + RECORD_WIDTH * m:RECORD_WIDTH].astype(np.int64) - t0
        near = np.flatnonzero(np.linalg.norm(centre - a, axis=1) - circum <= radius + np.linalg.norm(b - a))
        d = np.full(len(A), np.inf)
        d[near] = segment_triangles(a, b, A[near], B[near], Cv[near])
        assert held <= radius and set(np.flatnonzero(d <= held - 1e-9).tolist()) <= set(rows.tolist()), i
        short += m < PATCH_RECORDS and held < radius
    assert short >= 4
    # asked to hold at least more than it can: the patch is left as it was
    before = C[at:at + PATCH_WIDTH].copy()
    a = np.array([0.0, 0.0, 0.005])
    assert not _gather(S, C, k, at, *a, *a, 0.006, 0.0055)
    assert np.array_equal(C[at:at + PATCH_WIDTH], before)


def test_a_query_inside_a_too_full_capsule_keeps_it():
    """On a dish so dense that every query past the certificates is too full for a patch, a
    long sweep notes its capsule as too full; a distance query at its start (a ball inside
    it, much shorter) is found too full as well and noted in it rather than replacing it, so
    the next long sweep is served by the tree at once instead of gathering again. Every
    answer is the brute force's."""
    from test_mesh_queries import check_distance, patches

    s, o, a, n, t = dish_floor(1.5e-4)
    r = 0.005
    p = a + (r + 2e-6) * n
    u = 0.004 * t  # along the floor, into the rising dish
    o.check_sweep(p, u, r, s.sweep(*p, *u, r))
    full = [f for _, count, f in patches(s) if f[6] > 0.0]
    assert len(full) == 1 and all(count == 0 for _, count, _ in patches(s))
    assert np.linalg.norm(np.subtract(full[0][3:6], full[0][:3])) > 0.002  # a long one
    check_distance(o, s, [p])
    assert [f for _, _, f in patches(s) if f[6] > 0.0] == full  # the same capsule
    o.check_sweep(p, u, r, s.sweep(*p, *u, r))
    assert [f for _, _, f in patches(s) if f[6] > 0.0] == full


def test_a_finger_held_still_gathers_a_close_patch():
    """On a dish so dense that a patch 0.1 mm wider than a query is too full (~300 triangles
    within 0.1 mm of a 5 mm sphere resting on it), a finger held still (each query within
    PATCH_STILL of its slot's last) gathers a patch PATCH_CLOSE wider than its query once and
    reads it from then on; a query that moved is answered by the tree, the patch left as it
    was. On a dish denser still, where even that patch is too full, it is tried once and
    remembered. Every answer is the brute force's."""
    from softproxy.compiled.layout import HINT_SLOTS, P_FULL, PATCH_WIDTH
    from softproxy.compiled.patch import PATCH_CLOSE, PATCH_STILL
    from test_mesh_queries import check_distance, patches

    r = 0.005
    rng = np.random.default_rng(8)
    for spacing, half, close in ((1.5e-4, 0.012, True), (5e-5, 0.004, False)):
        s, o, a, n, t = dish_floor(spacing, half)
        p = a + (r + 1e-6) * n
        check_distance(o, s, [p])  # the first: too full for a patch, the tree answers
        assert all(count == 0 for _, count, _ in patches(s))
        q = p
        for i in range(20):  # held still: trembling by well under PATCH_STILL
            q = p + rng.normal(size=3) * PATCH_STILL / 10
            check_distance(o, s, [q], i)
            u = t * PATCH_STILL / 2
            o.check_sweep(q, u, r, s.sweep(*q, *u, r), context=i)
            if i == 1:
                held = patches(s)
        used = [(radius, count) for radius, count, _ in patches(s) if count > 0]
        at, C = int(s.set.S[s.row].patch), s.set.C
        tried = [C[at + PATCH_WIDTH * k + P_FULL + 9] for k in range(HINT_SLOTS)]
        if close:
            assert len(used) == 1 and r + PATCH_CLOSE / 2 <= used[0][0] <= r + 2 * PATCH_CLOSE, used
            assert patches(s) == held and not any(tried)  # gathered once, read since
            q = q + 5 * PATCH_CLOSE * t  # moved: past the patch, not held still
            check_distance(o, s, [q])
            assert patches(s) == held
        else:
            assert not used and sum(tried) == 1


def test_a_sliding_finger_stretches_its_capsules_ahead():
    """A finger sliding 3 mm along a dense dish's floor, 12 µm a tick: past its first patch,
    each patch is stretched PATCH_AHEAD ahead along the way its slot travelled (a strip
    serves a longer slide than a round capsule holding as many triangles); on a dish so dense
    that a patch is too full, the capsule noted too full is stretched PATCH_MARGIN ahead and
    is PATCH_KEEP wider than its query, and the close patch gathered where the finger is asked
    about twice at one place is stretched too. A capsule holds the query that noted it, 4 mm
    across the slide. Every answer is the brute force's."""
    from softproxy.compiled.layout import HINT_SLOTS, P_FULL, PATCH_WIDTH
    from softproxy.compiled.patch import PATCH_AHEAD, PATCH_CLOSE, PATCH_KEEP, PATCH_MARGIN
    from test_mesh_queries import check_distance

    r = 0.005
    for spacing, too_full in ((3.5e-4, False), (1.5e-4, True)):
        s, o, a, n, t = dish_floor(spacing)
        # r above the floor (z = x² / 0.2 m), within the dish's tilt (~1 µm)
        path = [a + x * t + (r + 1e-6 + x * x / 0.2) * n for x in np.arange(251) * 1.2e-5]
        at, C = int(s.set.S[s.row].patch), s.set.C
        stretched = close = 0.0
        for i in range(250):
            p, u = path[i], path[i + 1] - path[i]
            check_distance(o, s, [p], i)
            # asked again about (nearly) the same place, as at the turn of a tick (a 1 µm sweep
            # into the floor): a close patch where a patch is too full, stretched once it
            # slides on
            h = p + 2e-7 * t
            o.check_sweep(h, -1e-6 * n, r, s.sweep(*h, *(-1e-6 * n), r), context=i)
            o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=i)
            for k in range(HINT_SLOTS):
                c = at + PATCH_WIDTH * k + (P_FULL if too_full else 0)
                if C[c + 6] > 0.0:
                    stretched = max(stretched, float(np.linalg.norm(C[c + 3:c + 6] - C[c:c + 3])))
                    if too_full:
                        assert C[c + 6] <= r + 1.2e-5 + 1e-6 + PATCH_KEEP, (i, k, C[c + 6])
                c = at + PATCH_WIDTH * k
                if too_full and 0.0 < C[c + 6] < r + 2 * PATCH_CLOSE:
                    close = max(close, float(np.linalg.norm(C[c + 3:c + 6] - C[c:c + 3])))
        # then 4 mm across the slide, coming down 5 µm into the rising floor at the end: its
        # end lies ~1 mm off the stretched capsule, which must be that much wider to hold it
        w = np.cross(n, t)
        q = path[-1]
        e = 0.004 * w + (0.004 ** 2 / 0.2 - 5e-6) * n
        o.check_sweep(q, e, r, s.sweep(*q, *e, r), context="across")
        if too_full:  # the capsule it noted holds it: its end within the radius less r
            g = s.geom
            local = (np.array([q, q + e]) - s.set.xpos[g]) @ s.set.xmat[g].reshape(3, 3)
            noted = [at + PATCH_WIDTH * k + P_FULL for k in range(HINT_SLOTS)]
            noted = [c for c in noted if np.allclose(C[c:c + 3], local[0], atol=1e-12)]
            assert len(noted) == 1, noted
            c = noted[0]
            ends = C[c:c + 3], C[c + 3:c + 6]
            along = np.clip(np.dot(local[1] - ends[0], ends[1] - ends[0]) / np.sum((ends[1] - ends[0]) ** 2), 0, 1)
            off = np.linalg.norm(local[1] - ends[0] - along * (ends[1] - ends[0]))
            assert off > 5 * PATCH_KEEP and off + r <= C[c + 6], (off, C[c + 6])
        # a round capsule's segment is its query's: at most a tick's 12 µm
        if too_full:
            assert 0.9 * PATCH_MARGIN < stretched < 1.1 * PATCH_MARGIN, stretched
            assert 0.9 * PATCH_AHEAD < close < 1.1 * PATCH_AHEAD, close
        else:
            assert 0.9 * PATCH_AHEAD < stretched < 1.1 * PATCH_AHEAD, stretched


def test_a_dense_patch_shrinks_to_what_it_holds():
    """On a dense concave sheet the patch a query gathers (its capsule grown by 1 mm) would
    hold too many triangles, so the slot keeps the nearest PATCH_RECORDS and a thinner
    capsule: a sphere pressed at the bottom, trembling and creeping, reads it. Every answer is
    the brute force's."""
    from softproxy.compiled.layout import PATCH_RECORDS
    from softproxy.compiled.patch import PATCH_MARGIN
    from test_mesh_queries import check_distance, patches

    s, o, a, n, _ = dish_floor(3.5e-4)
    r = 0.005
    p = a + r * n
    rng = np.random.default_rng(4)
    thin = 0
    for i in range(40):
        p = p + rng.normal(size=3) * [2e-6, 3e-5][i % 2]
        dist, nx, ny, nz = check_distance(o, s, [p], i)[0]
        n = np.array((nx, ny, nz))
        p = p - n * (dist - r)
        for u in (-n * 1e-4, np.cross(n, rng.normal(size=3)) * 5e-5):
            o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=i)
        used = [(radius, count) for radius, count, _ in patches(s) if count > 0]
        thin += any(count == PATCH_RECORDS and radius < r + PATCH_MARGIN / 2 for radius, count in used)
    assert thin >= 30


def test_record_bounds_hold_and_are_as_thin_as_a_sliver():
    """A record's bound (`record_gap2`: height over the triangle's plane, distance beyond
    the rectangle that holds it in the plane) never exceeds the brute-force distance from a
    segment to the triangle, and is tight across slivers: over the cap fans of a CAD part
    (slivers 7 mm long, a fifth of a millimetre wide at the rim), a point a few millimetres
    over a cap is bounded near only the slivers truly near it. A ball about each sliver
    would be as wide as the cap and rule out none of a third of the fan."""
    from softproxy.compiled.layout import RECORD_WIDTH, R_ROW, TREE_RECORDS
    from softproxy.compiled.box_tree import record_gap2

    s, _ = tree_shape(*sliver_part())
    t = s.tables
    A, B, Cv = (t.vpos[t.tv[:, k]] for k in range(3))
    S, C, k = s.set.S, s.set.C, s.row
    first, t0, n = int(C[int(S[k].tree) + TREE_RECORDS]), int(S[k].t0), int(S[k].nt)
    records = first + RECORD_WIDTH * np.arange(n)
    rows = C[records + R_ROW].astype(np.int64) - t0
    A, B, Cv = A[rows], B[rows], Cv[rows]
    normal = np.cross(B - A, Cv - A)
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    centre = (A + B + Cv) / 3.0
    hub = np.bincount(t.tv.ravel()).argmax()  # the centre of a cap's fan
    fan = np.flatnonzero((t.tv[rows] == hub).any(axis=1))
    rng = np.random.default_rng(11)
    for i in range(30):
        on = fan[rng.integers(len(fan))] if i % 2 == 0 else rng.integers(n)
        a = centre[on] + normal[on] * rng.uniform(0.0, 0.004)
        b = a + rng.normal(size=3) * [0.0, 2e-4, 2e-3][i % 3]
        ha = np.einsum("ij,ij->i", normal, a - A)
        hb = np.einsum("ij,ij->i", normal, b - A)
        bound = np.array([record_gap2(C, j, *a, *b, ha[q], hb[q]) for q, j in enumerate(records)])
        d = segment_triangles(a, b, A, B, Cv)
        assert np.all(bound <= d * d * (1.0 + 1e-9) + 1e-18), i
        if i % 6 == 0:  # a point over a cap's fan: bounded near only the slivers near it
            reach = d[fan].min() + 5e-4
            near = np.count_nonzero(d[fan] <= reach)
            assert np.count_nonzero(bound[fan] <= reach * reach) <= 2 * near + 4, (i, near)


@pytest.mark.parametrize("jump", [0.001, 0.003])
def test_a_proxy_slid_across_fine_facets_ends_nearest_the_device(jump):
    """A god-object ends at the free position nearest the device (no free position is
    nearer it than r less its distance to the surface). On a dish of 0.25 mm facets
    (concave, curvature radius 0.1 m, far above the 5 mm proxy's) a frictionless proxy
    pressed 2 mm in and pulled 1 or 3 mm sideways in one tick crosses a dozen facets, a sweep
    each: it ends r off the surface point nearest the device (brute force), overlapping
    nothing, not short of it where its budget of sweeps ran out."""
    import warnings

    from softproxy.proxy import GodObject

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # an open mesh
        s, o = tree_shape(*fine_dish(2.5e-4))
    r = 0.005
    local = s.tables.vpos
    turn = np.linalg.lstsq(local - local.mean(0), o.v - o.v.mean(0), rcond=None)[0]  # geom to world, row vectors
    bottom = o.v[np.argmin(np.linalg.norm(local, axis=1))]  # the dish's lowest point, (0, 0, 0) in its frame
    n, side = np.array([0.0, 0.0, 1.0]) @ turn, np.array([0.6, 0.8, 0.0]) @ turn
    god = GodObject([s], r, 0.0, 0.0, tuple(bottom + 3.0 * r * n))
    device = bottom + (r - 0.002) * n
    for _ in range(5):
        god.update(*device)
    device = device + jump * side
    god.update(*device)
    d, q, _ = o.nearest([device])
    best = device + (r - d[0]) * (device - q[0]) / d[0]
    at = np.array([god.x, god.y, god.z])
    assert o.nearest([at])[0][0] >= r - 1e-7
    assert np.linalg.norm(at - best) <= 1e-6, np.linalg.norm(at - best)
