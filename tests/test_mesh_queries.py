"""The mesh queries (`Shape.distance`, `Shape.sweep` on a mesh) against brute force.

Every answer is checked against `mesh_oracle.Oracle`, which shares no code with the engine:
the distance to the nearest of every triangle, signed by the winding number on a watertight
mesh and unsigned on an open one; a sweep's first touch while moving into a triangle, found
triangle by triangle. The engine proves most triangles away (the hint, the walk to a nearer
triangle, the kept certificates, the grid); these tests put the hint on purpose where a
certificate could be wrong: at edges, vertices, concave creases, thin fans, and beside
small objects rising above a face or a vertex.
"""

import math

import mujoco
import numpy as np
import pytest
import trimesh
from hypothesis import example, given, settings, strategies as st

from mesh_oracle import (
    EXACT, MESHES, Oracle, assert_vertex_table, bowl, geodesic_sphere, mesh_model, mesh_of, oracle, peak_in_a_wall,
    point_triangle, prism, sheet, small_tetra, sphere10k, tilted_ball, triangles_near, uv_sphere,
)
from softproxy.compiled.certificate import ABOVE_TOL, VERTEX_READ
from softproxy.compiled.layout import (
    EDGE_BC, EDGE_WIDTH, HINT_SLOTS, P_COUNT, P_FULL, P_RADIUS, PATCH_RECORDS, PATCH_WIDTH, T_COLUMNS, T_EDGES,
)
from softproxy.compiled.triangle import Sweep, sweep_triangle
from softproxy.compiled.tolerances import GRAZE
from softproxy.proxy import GodObject


def start_from(shape, tri: int) -> None:
    """Make triangle `tri` the hint the next query of `shape` starts from, its kept answers
    forgotten (as after a query that ended on that triangle somewhere else)."""
    record = shape.set.S[shape.row]
    record.hint = int(shape.set.S[shape.row].t0) + tri
    record.key[:, :] = math.nan


def forget_queries(shape) -> None:
    """Put a mesh shape's query state back as it was loaded: no hint, no slot used, no patch
    held, no capsule found too full (the shared test meshes carry the last test's)."""
    record = shape.set.S[shape.row]
    record.hint = record.feature = -1
    record.key[:, :] = math.nan
    at, C = int(record.patch), shape.set.C
    C[at:at + HINT_SLOTS * PATCH_WIDTH] = 0.0
    for k in range(HINT_SLOTS):
        C[at + PATCH_WIDTH * k + P_RADIUS] = C[at + PATCH_WIDTH * k + P_FULL + 6] = -1.0


def check_distance(o: Oracle, shape, points, context=()):
    """Each point's distance and normal from `shape` against the brute force: the signed
    distance to EXACT (the sign only where the point is off the surface), a unit normal, and
    its foot (the point moved back by the distance along it) on the surface."""
    points = np.atleast_2d(points)
    got = np.array([shape.distance(*p) for p in points.tolist()])
    unsigned, _, _ = o.nearest(points)
    inside = o.inside(points, unsigned)
    for p, (d, nx, ny, nz), u, ins in zip(points, got, unsigned, inside):
        assert abs(abs(d) - u) <= EXACT, (context, p.tolist(), d, u)
        if u > 1e-7:
            assert (d < 0.0) == ins, (context, p.tolist(), d, "inside" if ins else "outside")
        assert abs(nx * nx + ny * ny + nz * nz - 1.0) < 1e-9, (context, p.tolist())
    feet = points - got[:, :1] * got[:, 1:]
    assert o.nearest(feet)[0].max() <= 1e-8, context
    return got


def around(o: Oracle, rng, n, spread=1.6):
    """n random points in a ball `spread` times the mesh's bounding radius about its box centre."""
    centre = (o.v.min(0) + o.v.max(0)) / 2.0
    bound = np.linalg.norm(o.v - centre, axis=1).max()
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    return centre + u * (spread * bound * rng.uniform(0, 1, (n, 1)) ** 0.5)


def vertex_normals(o: Oracle) -> np.ndarray:
    """Each vertex's outward direction: the sum of its triangles' normals, normalised."""
    n = np.zeros_like(o.v)
    for k in range(3):
        np.add.at(n, o.f[:, k], o.n)
    return n / np.maximum(np.linalg.norm(n, axis=1), 1e-300)[:, None]


def near_features(o: Oracle, rng, n, reach=0.006):
    """n (point, triangle) pairs about the mesh's edges and vertices, where a certificate has
    the most to prove: at a random vertex, or a random point of a random triangle's edge,
    moved by up to `reach` (m) along a direction scattered about the outward normal (a fifth
    of them inward), with a triangle on that feature, or one within 1 cm, as the hint."""
    normals = vertex_normals(o)
    out = []
    for _ in range(n):
        t = int(rng.integers(len(o.f)))
        corners = o.v[o.f[t]]
        if rng.uniform() < 0.5:
            k = int(rng.integers(3))
            at, vid = corners[k], o.f[t, k]
            normal = normals[vid]
            on = np.flatnonzero((o.f == vid).any(axis=1))
        else:
            k = int(rng.integers(3))
            s = rng.uniform()
            at = corners[k] + s * (corners[(k + 1) % 3] - corners[k])
            normal = o.n[t]
            ends = o.f[t, [k, (k + 1) % 3]]
            on = np.flatnonzero(np.isin(o.f, ends).sum(axis=1) == 2)
        u = normal + rng.normal(size=3) * rng.choice([0.1, 0.5, 1.5])
        u /= np.linalg.norm(u)
        if rng.uniform() < 0.2:
            u = -u
        point = at + u * reach * rng.uniform() ** 2
        if rng.uniform() < 0.7:
            hint = int(rng.choice(on))
        else:  # one of the 30 triangles nearest the feature
            hint = int(rng.choice(np.argsort(np.linalg.norm(o.centre - at, axis=1))[:30]))
        out.append((point, hint))
    return out


# ---------------------------------------------------------------------------------------
# Distance
# ---------------------------------------------------------------------------------------

def test_vertices_are_in_the_geom_frame():
    """MuJoCo recentres a mesh; mesh_vert is in the frame of geom_xpos/geom_xmat: every vertex of
    the file, placed by the body and geom poses written in the XML, lies on the surface."""
    m, d, shapes = tilted_ball()
    s = mesh_of(shapes)
    ico = trimesh.creation.icosphere(3, radius=0.03)

    def pose(pos, euler):
        quat = np.zeros(4)
        mujoco.mju_euler2Quat(quat, np.radians(euler), "xyz")
        mat = np.zeros(9)
        mujoco.mju_quat2Mat(mat, quat)
        return np.array(pos), mat.reshape(3, 3)

    pb, rb = pose([0.1, -0.05, 0.2], [20, -35, 50])
    pg, rg = pose([0.01, 0.02, -0.01], [10, 0, -70])
    world = (ico.vertices @ rg.T + pg) @ rb.T + pb
    for p in world[::7]:
        assert abs(s.distance(*p)[0]) < 1e-7  # float32 vertices
    centre = rb @ pg + pb
    assert s.distance(*centre)[0] == pytest.approx(-0.03, abs=5e-4)  # 3 cm inside


coord = st.floats(-1.0, 1.0)


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(["tilted ball", "bowl"]), st.lists(st.tuples(coord, coord, coord), min_size=5, max_size=20))
@example("bowl", [(0.0, 0.0, 0.0)] * 4 + [(0.0, 0.0, -0.5)])  # 0.9 nm over the bowl's floor
def test_distance_and_normal_match_the_brute_force(which, unit_points):
    """Exact distance and outward normal at random points in and around a turned ball and the
    bowl, world frame; the sign says inside (winding number) wherever the point is not on the
    surface."""
    m, d, shapes = MESHES[which]()
    o = oracle(m, d, shapes)
    lo, hi = o.v.min(0), o.v.max(0)
    check_distance(o, mesh_of(shapes), (lo + hi) / 2 + np.array(unit_points) * 0.75 * (hi - lo), which)


@pytest.mark.parametrize("which", sorted(MESHES))
def test_distance_near_and_far_in_any_order(which):
    """Signed distance (unsigned on the open sheet) and normal at random points near the mesh
    and far from it, asked in a random order, some of them again (the hint and the kept
    answers in play): the brute force's, and the same answer when asked again."""
    m, d, shapes = MESHES[which]()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    rng = np.random.default_rng(7)
    surface = o.centre[rng.integers(0, len(o.f), 150)] + rng.normal(scale=0.002, size=(150, 3))
    points = np.vstack([around(o, rng, 150), surface])
    points = points[rng.permutation(len(points))]
    points = np.vstack([points, points[rng.integers(0, len(points), 60)]])
    got = check_distance(o, s, points, which)
    if not s.signed:
        assert (got[:, 0] >= 0.0).all()
    again = np.array([s.distance(*p) for p in points[::-1].tolist()])[::-1]
    assert np.abs(again - got).max() <= 1e-12


def test_distance_far_from_the_mesh_is_exact():
    """Far queries (an audit of a free finger) and queries over the rim stay exact."""
    m, d, shapes = bowl()
    o = oracle(m, d, shapes)
    check_distance(o, mesh_of(shapes), [[0.0, 0.0, 0.09], [0.0, 0.0, 0.04], [0.3, 0.1, -0.2],
                                        [0.0, 0.0, 0.0405], [0.05, 0.0, 0.0401]])


def test_open_mesh_is_unsigned_on_both_sides():
    """An open sheet has no inside: just over and just under a triangle's centre the distance
    is the same, positive, and the normal points from the sheet to the point on both sides."""
    m, d, shapes = sheet()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    rng = np.random.default_rng(2)
    for t in rng.integers(0, len(o.f), 40):
        foot = o.centre[t]
        h = rng.uniform(1e-5, 1e-4)
        up, down = s.distance(*(foot + h * o.n[t])), s.distance(*(foot - h * o.n[t]))
        assert up[0] == pytest.approx(h, abs=EXACT) and down[0] == pytest.approx(h, abs=EXACT)
        assert np.dot(up[1:], o.n[t]) > 1.0 - 1e-9 and np.dot(down[1:], o.n[t]) < -1.0 + 1e-9


def test_distance_answer_kept_only_for_the_same_point_and_pose():
    """The last distance is kept for a repeated query; a mesh that moved (a new pose in mjData,
    nothing else told) answers anew, exactly."""
    m, d, shapes = mesh_model(trimesh.creation.box(extents=(0.1, 0.1, 0.1)), body='mocap="true"')
    s = mesh_of(shapes)
    p = (0.01, 0.02, 0.08)
    first = s.distance(*p)
    assert first[0] == pytest.approx(0.03, abs=1e-7)
    assert s.distance(*p) == first
    d.mocap_pos[0] = (0.0, 0.0, 0.01)
    mujoco.mj_forward(m, d)
    assert s.distance(*p)[0] == pytest.approx(0.02, abs=1e-7)
    d.mocap_quat[0] = (math.cos(math.pi / 8), math.sin(math.pi / 8), 0.0, 0.0)  # 45° about x
    mujoco.mj_forward(m, d)
    got = s.distance(*p)
    local = d.geom_xmat[0].reshape(3, 3).T @ (np.array(p) - d.geom_xpos[0])
    assert got[0] == pytest.approx(np.linalg.norm(local - np.clip(local, -0.05, 0.05)), abs=1e-7)
    check_distance(oracle(m, d, shapes), s, [p])


# ---------------------------------------------------------------------------------------
# Sweep
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("which", sorted(MESHES))
def test_sweep_matches_the_brute_force(which):
    """Random spheres (a point included) on random segments, short (a grid column) and long
    (cells along the segment), from outside, touching and inside: stopped at once when pressed
    into a triangle they touch, else where the sphere first comes within r of a triangle and
    never nearer before; a miss never comes nearer than r."""
    m, d, shapes = MESHES[which]()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    rng = np.random.default_rng(11)
    near = o.centre[rng.integers(0, len(o.f), 80)] + rng.normal(scale=0.004, size=(80, 3))
    hits = long_hits = pressed = 0
    for i, p in enumerate(np.vstack([around(o, rng, 80, 1.3), near])[rng.permutation(160)]):
        scale = [1e-5, 1e-3, 0.01, 0.06][i % 4]
        u = rng.normal(size=3) * scale
        r = [0.0, 0.002, 0.005, 0.008][(i // 4) % 4]
        hit = s.sweep(*p, *u, r)
        facts = o.check_sweep(p, u, r, hit, context=(which, i))
        hits += hit is not None
        long_hits += hit is not None and scale >= 0.01
        pressed += facts["into"]
    assert hits > 20 and long_hits > 5 and pressed > 0


def test_sweep_touching_sphere_slides_and_lifts_freely():
    """A sphere resting on the 10k sphere and moving along or away from it is not stopped by
    the face it rests on; moved into it, at once, with the face's normal."""
    m, d, shapes = sphere10k()
    s = mesh_of(shapes)
    o = oracle(m, d, shapes)
    r = 0.005
    god = GodObject(shapes, r, 0.0, 0.0, (0.0, 0.0, 0.08))
    god.update(0.0, 0.0, 0.05)
    assert god.contact
    x = np.array((god.x, god.y, god.z))
    n = np.array(s.distance(*x)[1:])
    tangent = np.cross(n, [1.0, 0.0, 0.0])
    tangent *= 1e-4 / np.linalg.norm(tangent)
    assert s.sweep(*x, *(n * 1e-3), r) is None
    hit = s.sweep(*x, *(-n * 1e-3), r)
    assert hit is not None and hit[0] == 0.0 and np.allclose(hit[1:], n, atol=1e-6)
    hit = s.sweep(*x, *tangent, r)
    assert hit is None or hit[0] > 0.0  # a neighbour may rise in the way, never the face touched
    o.check_sweep(x, tangent, r, hit)


def hugging_path(o: Oracle, shape, rng, steps, r):
    """Points near the surface for a sphere of radius r: a random walk whose every point is
    pulled back to between 0.5 mm inside and 1 mm beyond touching, with steps from 10 µm to
    3 mm: what a proxy sliding, pressing and lifting off asks."""
    p = o.centre[rng.integers(len(o.f))]
    out = []
    for i in range(steps):
        p = p + rng.normal(size=3) * [1e-5, 3e-4, 3e-3][i % 3]
        d, nx, ny, nz = shape.distance(*p)
        p = p - np.array((nx, ny, nz)) * (d - r - rng.uniform(-5e-4, 1e-3))
        out.append(p)
    return out


def vertex_path(o: Oracle, rng, steps, r):
    """Points about the mesh's vertices, where a vertex is the nearest feature: each off a
    random vertex along a direction scattered about its normal, at r give or take 0.5 mm,
    every other one a small step from the last (the vertex certificate, its cone and ring)."""
    normals = vertex_normals(o)
    out = []
    for i in range(steps):
        if i % 2 and out:
            out.append(out[-1] + rng.normal(size=3) * 2e-4)
            continue
        v = rng.integers(len(o.v))
        u = normals[v] + rng.normal(size=3) * rng.choice([0.05, 0.3, 1.0])
        out.append(o.v[v] + u / np.linalg.norm(u) * max(0.0, r + rng.uniform(-5e-4, 5e-4)))
    return out


@pytest.mark.parametrize("which", sorted(MESHES))
def test_queries_along_the_surface_match_the_brute_force(which):
    """Sweeps and distances along paths that hug the surface and hop about its vertices,
    where the hint, the walk and the kept certificates answer most queries: each sweep the
    brute force's first touch, each distance at its start and end the brute force's."""
    m, d, shapes = MESHES[which]()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    rng = np.random.default_rng(13)
    hits = 0
    for r in (0.0, 0.005, 0.008):
        for path in (hugging_path(o, s, rng, 18, r), vertex_path(o, rng, 18, r)):
            for p, q in zip(path, path[1:]):
                hit = s.sweep(*p, *(q - p), r)
                o.check_sweep(p, q - p, r, hit, context=(which, r))
                hits += hit is not None
                check_distance(o, s, [p, q], (which, r))
    assert hits > 10


def test_hint_and_kept_answers_change_nothing():
    """The same queries after a long history and from a fresh state (no hint, nothing kept)
    give the same answers: what a query keeps only saves work."""
    m, d, shapes = sphere10k()
    s = mesh_of(shapes)
    o = oracle(m, d, shapes)
    rng = np.random.default_rng(5)
    queries = [(p, rng.normal(size=3) * 0.003) for p in around(o, rng, 80, 1.2)]
    for p, u in queries:
        s.sweep(*p, *u, 0.005)
        s.distance(*p)
    for p, u in queries[::5]:
        after = s.sweep(*p, *u, 0.005), s.distance(*p)
        start_from(s, -1 - int(shapes.S[s.row].t0))  # no hint
        fresh = s.sweep(*p, *u, 0.005)
        start_from(s, -1 - int(shapes.S[s.row].t0))
        fresh = fresh, s.distance(*p)
        assert (after[0] is None) == (fresh[0] is None)
        if after[0] is not None:
            assert after[0][0] == pytest.approx(fresh[0][0], abs=1e-12)
        assert after[1][0] == pytest.approx(fresh[1][0], abs=1e-12)


def test_sliding_on_one_of_two_nearly_parallel_edges_is_not_pressing_the_other():
    """A sphere resting on the bowl's inner rim, on the two rim edges that meet at a vertex
    (their touch normals 2e-4 rad apart), moved along the tangent plane of the one edge toward
    a device below the rim, inward: the other edge's plane lies a rounding (~1e-10 m) above
    the end of the move, and the sphere comes no nearer to it: no touch (not at once either),
    as the brute force says. Tilted into that plane by 3 nm more than the rounding, it is
    pressed, and stops at once."""
    m, d, shapes = bowl()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    r = 0.005
    p = np.array([0.03497532562938234, 0.0, 0.04499993828562851])
    device = np.array([0.03289387, 0.0, 0.0421364])
    dist, feet = point_triangle(p[None], o.a, o.b, o.c)
    normals = []
    for q in feet[dist <= r + 1e-12]:   # the touches' normals: two edges' (each on two triangles)
        n = (p - q) / np.linalg.norm(p - q)
        if all(np.linalg.norm(n - k) > 1e-9 for k in normals):
            normals.append(n)
    assert dist.min() == pytest.approx(r, abs=1e-12) and len(normals) == 2
    n1, n2 = normals
    assert 1e-5 < np.linalg.norm(n1 - n2) < 1e-3   # nearly parallel
    for a, b in ((n1, n2), (n2, n1)):
        target = device + (a @ (p - device)) * a      # the device on the one edge's tangent plane
        assert b @ (target - p) < -1e-12               # a hair below the other's
        start_from(s, int(o.nearest(p)[2][0]))
        hit = s.sweep(*p, *(target - p), r)
        facts = o.check_sweep(p, target - p, r, hit)
        assert hit is None and not facts["into"]
        tilted = target - p - 3e-9 * b
        hit = s.sweep(*p, *tilted, r)
        facts = o.check_sweep(p, tilted, r, hit)
        assert facts["into"] and hit[0] == 0.0


def test_a_sweep_names_the_edge_it_touched():
    """A sphere sliding parallel to edge AB into edge BC touches BC (EDGE_BC), whatever the
    edges before it in the loop did (a sweep parallel to AB skips AB's cylinder): the feature
    decides which neighbour a sweep asks next."""
    a, b, c = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    ab, ac = b - a, c - a
    aa, abac, cc = ab @ ab, ab @ ac, ac @ ac
    row = np.zeros((1, T_COLUMNS))
    row[0, :22] = [*a, *b, *c, *ab, *ac, 0.0, 0.0, 1.0, aa, abac, cc, 1.0 / (aa * cc - abac * abac)]
    for k, (s0, s1) in enumerate(((a, b), (b, c), (c, a))):
        length = float(np.linalg.norm(s1 - s0))
        row[0, T_EDGES + EDGE_WIDTH * k:T_EDGES + EDGE_WIDTH * (k + 1)] = [*s0, *((s1 - s0) / length), length]
    start, move, r = (0.8, 0.8, 0.05), (-0.6, 0.0, 0.0), 0.1
    lam, _, _, _, feature = sweep_triangle(row, 0, Sweep(*start, *move, r, 0.36, GRAZE * 0.6), (r + 0.6 + 1e-9) ** 2)
    assert lam >= 0.0 and feature == EDGE_BC
    x = start[0] + lam * move[0]  # the centre is r from the line x + y = 1 (in 3-d)
    assert math.hypot((x + start[1] - 1.0) / math.sqrt(2.0), start[2]) == pytest.approx(r, abs=1e-12)


# ---------------------------------------------------------------------------------------
# Certificates: the hint's tangent plane never hides a nearer triangle
# ---------------------------------------------------------------------------------------

def studded_ball():
    """A geodesic sphere (2000 triangles, 5 cm) with small things near it that rise above the
    tangent planes of its faces and vertices: a tetrahedron 2 mm over a face, another 3 mm
    over a vertex and off to one side, a 2 mm box 4 mm out beside a third vertex."""
    ball = geodesic_sphere(10, 0.05)
    top = int(np.argmax(ball.triangles_center @ np.array([0.1, 0.2, 0.97])))
    over_face = small_tetra(ball.triangles_center[top] + 0.002 * ball.face_normals[top])
    parts = [ball, over_face]
    for direction, out, side, thing in (([0.2, -0.1, 0.97], 0.003, 0.0025, "tetra"),
                                        ([0.3, 0.2, 0.93], 0.004, 0.003, "box")):
        v = ball.vertices[int(np.argmax(ball.vertices @ np.array(direction)))]
        a = v / np.linalg.norm(v)
        lateral = np.cross(a, (1.0, 0.0, 0.0) if thing == "tetra" else (0.0, 0.0, 1.0))
        at = v + out * a + side * lateral / np.linalg.norm(lateral)
        if thing == "tetra":
            parts.append(small_tetra(at))
        else:
            box = trimesh.creation.box(extents=(0.002, 0.002, 0.002))
            box.apply_translation(at)
            parts.append(box)
    return mesh_model(trimesh.util.concatenate(parts))


def dented_ball():
    """A geodesic sphere (720 triangles) with a dozen vertices pushed 1.5 mm in (concave
    patches round them) and a tetrahedron floating 2 mm over one face."""
    ball = geodesic_sphere(6, 0.05)
    v = ball.vertices.copy()
    v[np.random.default_rng(11).choice(len(v), 12, replace=False)] *= 0.97
    top = int(np.argmax(ball.triangles_center @ np.array([0.3, -0.2, 0.93])))
    tetra = small_tetra(ball.triangles_center[top] + 0.002 * ball.face_normals[top])
    return mesh_model(trimesh.util.concatenate([trimesh.Trimesh(v, ball.faces, process=False), tetra]))


CERTIFIED = {"studded ball": studded_ball, "dented ball": dented_ball, "uv sphere": uv_sphere,
             "L prism": prism, "bowl": bowl, "sheet": sheet, "sphere10k": sphere10k}


@pytest.mark.parametrize("which", sorted(CERTIFIED))
def test_no_certificate_hides_a_nearer_triangle(which):
    """From a hint on or near an edge or a vertex (thin fans at a uv-sphere's poles, concave
    creases, dents, the inside of the bowl, an open sheet's two sides, small objects rising
    above a face or a vertex), every distance and every sweep is the brute force's: a
    certificate never proves a triangle away that is nearer or in the way."""
    m, d, shapes = CERTIFIED[which]()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    rng = np.random.default_rng(17)
    for k, (p, hint) in enumerate(near_features(o, rng, 90)):
        start_from(s, hint)
        check_distance(o, s, [p], (which, k, hint))
        start_from(s, hint)
        u = rng.normal(size=3) * rng.choice([1e-4, 1e-3, 3e-3])
        r = [0.0, 0.001, 0.003][k % 3]
        o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=(which, k, hint))


def test_walk_from_a_vertex_finds_the_nearer_fan_triangle():
    """The hint's nearest point is the uv-sphere's pole, but the query lies over another
    triangle of its fan of ~100: the walk (and the scan after) give the brute force's
    distance, and the sweep its first touch."""
    m, d, shapes = uv_sphere()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    top = int(np.argmax(o.v[:, 2]))
    fan = np.flatnonzero((o.f == top).any(axis=1))
    rng = np.random.default_rng(11)
    for k in range(40):
        a = rng.uniform(0.0, 2.0 * math.pi)
        p = o.v[top] + np.array([0.002 * math.cos(a), 0.002 * math.sin(a), 0.004])
        start_from(s, int(fan[k % len(fan)]))
        check_distance(o, s, [p], k)
        start_from(s, int(fan[(k * 7) % len(fan)]))
        dvec = np.array([-math.cos(a), -math.sin(a), -1.0]) * 0.003
        o.check_sweep(p, dvec, 0.002, s.sweep(*p, *dvec, 0.002), context=k)


def test_held_on_a_pole_is_exact():
    """A proxy pressed onto the pole vertex of a uv-sphere (the vertex certificate holds its
    fan of ~100 thin triangles behind the tangent plane): the distances about the pole and
    the sweeps from there in every direction are the brute force's."""
    m, d, shapes = uv_sphere()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    pole = o.v[np.argmax(o.v[:, 2])]
    r = 0.005
    god = GodObject(shapes, r, 0.5, 0.4, (0.0, 0.0, 0.08))
    for k in range(50):
        god.update(1e-5 * math.sin(0.1 * k), 0.0, pole[2] + r - 0.003)
    assert god.contact
    rng = np.random.default_rng(7)
    check_distance(o, s, pole + np.array([0.0, 0.0, r]) + rng.normal(scale=2e-5, size=(30, 3)))
    start = np.array((god.x, god.y, god.z))
    for u in rng.normal(size=(20, 3)):
        dvec = u / np.linalg.norm(u) * 2e-4
        o.check_sweep(start, dvec, r, s.sweep(*start, *dvec, r))


def test_straight_above_a_peak_the_vertex_certificate_holds_at_its_cone_axis():
    """A point straight above a convex vertex sees it along the cone's axis, where n·axis may
    round to 1 + 2e-16: the certificate's tilt sqrt(1 - c²) must not become NaN (it then
    certified the tip and answered up to 0.5 mm too far). The sheet randomly turned and
    moved, each point asked after one on the tip's fan (the hint there): the brute force's
    distance (the wall, nearer than the tip from ~4 mm up)."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(2)
    base = peak_in_a_wall()
    for trial in range(8):
        turn = Rotation.random(random_state=int(rng.integers(1e9))).as_matrix()
        shift = rng.normal(size=3) * 0.01
        with pytest.warns(UserWarning, match="open mesh"):
            m, d, shapes = mesh_model(trimesh.Trimesh(base.vertices @ turn.T + shift, base.faces, process=False))
        o = oracle(m, d, shapes)
        s = mesh_of(shapes)
        tip, axis = shift, turn @ [0.0, 0.0, 1.0]
        assert np.linalg.norm(o.v - tip, axis=1).min() < 1e-8
        for _ in range(25):
            s.distance(*(tip + axis * 3e-4))
            check_distance(o, s, [tip + axis * rng.uniform(0.0035, 0.0055)], trial)


def ball_with_tetra_over_a_face(height: float):
    """A geodesic sphere (2000 triangles, 5 cm) with `small_tetra` floating `height` (m) over
    its face nearest (0.1, 0.2, 0.97): (model, data, shapes, the face, its unit normal, its
    centre, the tetrahedron's triangles)."""
    ball = geodesic_sphere(10, 0.05)
    top = int(np.argmax(ball.triangles_center @ np.array([0.1, 0.2, 0.97])))
    tetra = small_tetra(ball.triangles_center[top] + height * ball.face_normals[top])
    m, d, shapes = mesh_model(trimesh.util.concatenate([ball, tetra]))
    o = oracle(m, d, shapes)
    return m, d, shapes, top, o.n[top], o.centre[top], set(range(len(ball.faces), len(o.f)))


def test_kept_certificate_lists_the_few_triangles_above_a_face():
    """A tetrahedron (4 triangles) floating 2 mm over a face rises above the face's plane: the
    face's kept certificate lists exactly those, so distances and sweeps from over the face,
    the face as their hint, find the tetrahedron; a face on the far side lists none."""
    m, d, shapes, face, n, centre, tetra = ball_with_tetra_over_a_face(0.002)
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    assert set(s._clear[face][1]) == tetra
    far = int(np.argmin(o.centre @ n))
    assert s._clear[far] == (s._kept, ())
    rng = np.random.default_rng(3)
    pts = centre + rng.uniform(0.0015, 0.004, size=(60, 1)) * n + rng.normal(scale=3e-4, size=(60, 3))
    nearest = o.nearest(pts)[2]
    assert np.isin(nearest, list(tetra)).any()  # the tetrahedron is nearest for some
    for k, p in enumerate(pts):
        start_from(s, face)
        check_distance(o, s, [p], k)
    r = 0.001
    for k, p in enumerate(pts):  # spheres touching the face, swept every way
        p = p - (p - centre) @ n * n + (r + 1e-9) * n
        start_from(s, face)
        dvec = rng.normal(scale=0.0015, size=3)
        o.check_sweep(p, dvec, r, s.sweep(*p, *dvec, r), context=k)


def test_kept_certificate_beyond_its_reach_scans():
    """A tetrahedron floating 17 mm over a face lies beyond the reach the certificates are
    built over at load (a 5 mm proxy): a point 11 mm over the face, nearer the tetrahedron,
    is not certified by the face and finds it; after `prepare` for a 1 cm proxy the face's
    list holds the tetrahedron, and the queries from there are the brute force's."""
    m, d, shapes, face, n, centre, tetra = ball_with_tetra_over_a_face(0.017)
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    assert s._clear[face] == (s._kept, ())  # nothing rises within the load-time reach
    p = centre + 0.011 * n
    assert o.nearest(p)[2][0] in tetra
    start_from(s, face)
    check_distance(o, s, [p])
    shapes.prepare(0.01)
    assert s._kept >= 0.02 and set(s._clear[face][1]) == tetra
    assert shapes.S[s.row].kept == s._kept
    for h in (0.009, 0.01, 0.0105):
        start_from(s, face)
        check_distance(o, s, [centre + h * n], h)


def test_kept_tables_built_at_load_match_brute_force():
    """The certificates built at load for every face and vertex at once agree with a brute
    force over all triangles, on a sphere with dents and a floating tetrahedron: a face's list
    holds every triangle within the reach of it that rises above its plane (or the face is
    marked concave, only where one does), and a vertex's table lists every vertex of the
    triangles within the reach, off its ring, no later than its sin β (β: below the plane
    square to the vertex normal)."""
    m, d, shapes = dented_ball()
    s = mesh_of(shapes)
    k = int(m.geom_dataid[s.geom])
    v = m.mesh_vert[m.mesh_vertadr[k]:m.mesh_vertadr[k] + m.mesh_vertnum[k]].astype(float)  # geom frame
    f = m.mesh_face[m.mesh_faceadr[k]:m.mesh_faceadr[k] + m.mesh_facenum[k]].astype(np.int64)
    assert s.triangles == len(f)
    o = Oracle(v, f, True)
    radius = s._kept
    abc = v[f]
    concave = listed = 0
    # points spread over each triangle: a triangle with one within the reach of another
    # triangle is within the reach (a subset of the triangles the tables must cover)
    weights = np.array([(a, b, 6 - a - b) for a in range(7) for b in range(7 - a)], float) / 6.0
    samples = np.einsum("sk,tkx->tsx", weights, abc)
    for i in range(len(f)):
        near = triangles_near(o, samples, i, radius)
        height = abc[near] @ o.n[i] - o.off[i]
        for side, key in ((1.0, i), (-1.0, -1 - i)):
            rising = set(near[(side * height > ABOVE_TOL).any(axis=1)].tolist())
            reach, few = s._clear[key]
            if few is None:
                assert rising, (i, side)
                concave += side > 0.0
            else:
                assert reach >= radius and rising <= set(few), (i, side)
                listed += bool(few) and side > 0.0
    assert concave > 0 and listed > 0  # the dents and the tetrahedron
    # the vertex normal: the face normals weighted by the face angle at the vertex
    normal = np.zeros_like(v)
    for j in range(3):
        e1, e2 = v[f[:, (j + 1) % 3]] - v[f[:, j]], v[f[:, (j + 2) % 3]] - v[f[:, j]]
        angle = np.arccos(np.clip((e1 * e2).sum(1) / np.linalg.norm(e1, axis=1) / np.linalg.norm(e2, axis=1), -1, 1))
        np.add.at(normal, f[:, j], o.n * angle[:, None])
    normal /= np.linalg.norm(normal, axis=1)[:, None]
    ids = {tuple(p): i for i, p in enumerate(s._vpos.tolist())}  # its vertex ids, by position
    reach, start, sines, table_ids = s._vtable
    assert reach == radius
    for vertex in np.unique(f):
        at = ids[tuple(v[vertex].tolist())]
        assert_vertex_table(o, v, f, vertex, radius, normal[vertex], sines[start[at]:start[at + 1]].tolist(),
                            table_ids[start[at]:start[at + 1]].tolist(), VERTEX_READ,
                            lambda w: ids[tuple(v[w].tolist())])


def patches(shape) -> list[tuple[float, int, tuple]]:
    """(radius (m), count, the capsule found too full: its ends (geom frame) and radius (m),
    -1: none) of each hint slot's patch of a mesh shape."""

    at, C = int(shape.set.S[shape.row].patch), shape.set.C
    return [(C[at + PATCH_WIDTH * k + P_RADIUS], int(C[at + PATCH_WIDTH * k + P_COUNT]),
             tuple(C[at + PATCH_WIDTH * k + P_FULL:at + PATCH_WIDTH * k + P_FULL + 7].tolist()))
            for k in range(HINT_SLOTS)]


def test_a_query_off_the_map_leaves_the_patches_as_they_were():
    """A sweep or a distance asked with NaN or inf in it (a bug upstream) leaves every hint
    slot's patch and capsules as they were, and the queries after it are the brute force's.
    A NaN capsule compares false with everything, and every later query of its slot took the
    patch for holding it (its answers wrong by centimetres)."""
    m, d, shapes = bowl()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    r = 0.005
    p = np.array([0.0, 0.0, 0.04 - 0.035 + r])  # the inner sphere's bottom, r above it
    u = np.array([2e-4, 1e-4, 0.0])
    check_distance(o, s, [p])
    o.check_sweep(p, u, r, s.sweep(*p, *u, r))
    at, C = int(s.set.S[s.row].patch), s.set.C
    before = C[at:at + HINT_SLOTS * PATCH_WIDTH].copy()
    rng = np.random.default_rng(4)
    for bad in (math.nan, math.inf, -math.inf):
        for k in range(3):
            # from places 1-3 mm apart (slots whose patches do not hold them yet)
            q = p + [0.0, 0.0, 0.001] + rng.uniform(-0.003, 0.003, 3)
            s.sweep(*q, *np.where(np.arange(3) == k, bad, u), r)  # a direction off the map
            s.sweep(*np.where(np.arange(3) == k, bad, q), *u, r)  # a start off the map
            s.distance(*np.where(np.arange(3) == k, bad, q))
    assert np.array_equal(C[at:at + HINT_SLOTS * PATCH_WIDTH], before)
    for i in range(40):
        q = p + rng.normal(size=3) * 1e-4
        check_distance(o, s, [q], i)
        o.check_sweep(q, u, r, s.sweep(*q, *u, r), context=i)


def test_a_vanishing_proxy_leaves_the_mesh_queries_exact():
    """A proxy of radius 4e-290 m on a path through the 10k sphere (one Hypothesis found):
    afterwards no hint slot's capsule holds a NaN, and distances about the sphere are the
    brute force's. On that path the god-object's way over a convex patch took the square
    root of a cosine a hair over 1; the NaN became a slot's capsule, and the next test saw
    the proxy 5 mm inside."""
    m, d, shapes = sphere10k()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    path = [(0.45685856922415913, 0.7143948516648635, 0.30240506362864106), (-1e-12, 0.4375847630988343,
            0.10390369545318445), (-0.7356524564917235, 0.25606540817445533, 0.39307825598759893),
            (0.5671780595137692, -4.739848936857893e-255, -0.18862583886117323),
            (0.4265207966122182, 0.8937565580348474, -0.13809541828896), (1e-30, 0.8872793693173153,
            -3.461201039043249e-227)]
    mu = 0.5157880193230583
    god = GodObject(shapes, 4.027865658967583e-290, mu, 0.8 * mu, (0.0, 0.0, 0.09))
    for q in np.array(path) * 0.07:
        god.update(*q)
    at, C = int(s.set.S[s.row].patch), s.set.C
    for k in range(HINT_SLOTS):
        for c in (at + PATCH_WIDTH * k, at + PATCH_WIDTH * k + P_FULL):  # the patch's, the too full one
            assert not np.isnan(C[c:c + 7]).any(), (k, C[c:c + 7])
    check_distance(o, s, around(o, np.random.default_rng(5), 200))


def test_a_query_names_the_triangle_it_answers_from():
    """After a distance query (asked afresh or answered from the kept two) the mesh's feature
    is the triangle of its nearest point, and after a touching sweep the triangle touched: the
    god-object keeps it with a plane, to tell whether that plane's own triangle is still
    under the proxy. Checked by the distance to that one triangle, brute force, on the bowl
    (concave and convex patches) about its floor and rim, sweeps from points clear of it."""
    _, _, shapes = bowl()
    s = mesh_of(shapes)
    T, rng = shapes.T, np.random.default_rng(4)

    def to_triangle(p, row):
        local = np.array(s.to_local(*p))
        return point_triangle(local[None, :], T[row:row + 1, 0:3], T[row:row + 1, 3:6], T[row:row + 1, 6:9])[0][0]

    points = np.concatenate([[0.0, 0.0, 0.01] + rng.normal(size=(40, 3)) * 0.01,
                             [0.0, 0.035, 0.04] + rng.normal(size=(40, 3)) * 0.005])
    touched = 0
    for p in points.tolist():
        beside = (np.array(p) + rng.normal(size=3) * 1e-4).tolist()  # in the same hint slot
        for q in (p, beside, p):  # afresh, afresh, then p's kept answer
            dist = s.distance(*q)[0]
            assert abs(to_triangle(q, int(shapes.S[s.row].feature)) - abs(dist)) <= EXACT, q
        u = rng.normal(size=3) * 0.02
        hit = s.sweep(*p, *u, 0.003) if abs(dist) > 0.003 else None  # from clear of the surface
        if hit is not None:
            touched += 1
            at = np.array(p) + hit[0] * u
            assert abs(to_triangle(at, int(shapes.S[s.row].feature)) - 0.003) <= EXACT, p
    assert touched > 10


def test_patch_answers_match_the_brute_force():
    """On the bowl's concave floor and wall no certificate holds, so a query reads the
    triangles its hint slot's patch gathered (a ball a little larger than the query needs):
    a 5 mm sphere pressed there, sliding and stepping about asks many queries of one patch.
    A long sweep finds its capsule too full to keep (the box tree answers it, the patch held
    is kept), and the next short query reads a small one. Every distance and sweep is the
    brute force's."""
    m, d, shapes = bowl()
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    forget_queries(s)
    rng = np.random.default_rng(21)
    r = 0.005
    p = np.array([0.0, 0.0, 0.04 - 0.035 + r])  # the inner sphere's bottom, r above it
    kept = full = 0
    for i in range(120):
        step = rng.normal(size=3) * [1e-5, 2e-4, 1e-3][i % 3]
        p = p + step
        dist, nx, ny, nz = check_distance(o, s, [p], i)[0]
        n = np.array((nx, ny, nz))
        p = p - n * (dist - r - rng.uniform(-2e-4, 5e-4))  # back near touching, either side
        check_distance(o, s, [p], i)
        long = i % 10 == 9
        for u in (-n * 1e-3, np.cross(n, rng.normal(size=3)) * 2e-3,
                  rng.normal(size=3) * (0.06 if long else 3e-4)):
            o.check_sweep(p, u, r, s.sweep(*p, *u, r), context=i)
        kept += any(c > 0 for _, c, _ in patches(s))
        full += any(f[6] > 0.0 for _, _, f in patches(s))
    assert kept > 100 and full > 0
    # a long sweep from the floor: too full, its capsule noted and the patch held kept; a
    # short one after it reads a small patch
    before = patches(s)
    u = np.array([0.03, 0.02, 0.04])
    o.check_sweep(p, u, r, s.sweep(*p, *u, r))
    after = patches(s)
    slot = [k for k in range(HINT_SLOTS) if after[k][2] != before[k][2]]
    assert slot and all(after[k][:2] == before[k][:2] for k in range(HINT_SLOTS))
    u = np.array([2e-4, 0.0, -1e-4])
    o.check_sweep(p, u, r, s.sweep(*p, *u, r))
    radius, count, _ = patches(s)[slot[0]]
    assert 0 < count <= PATCH_RECORDS and radius < r + 0.003
