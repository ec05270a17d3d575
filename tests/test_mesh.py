"""Triangle-mesh contact: exact distance and sweep, the proxy never inside, the bowl's dent, validation."""

import contextlib
import functools
import math
import warnings
from pathlib import Path

import mujoco
import numpy as np
import pytest
import trimesh
from hypothesis import example, given, settings, strategies as st

from softproxy.geometry import shapes_of
from softproxy.mesh import ABOVE_TOL, POINT_RADIUS, VERTEX_READ, MeshShape, MeshWarning, validate_mesh
from softproxy.proxy import GodObject

TOL = 1e-6  # the promise: never more than 1 µm inside anything
SCENES = Path(__file__).resolve().parent.parent / "scenes"
BOWL_XML = SCENES / "mesh_object.xml"


def deepest(god):
    return max(god.radius - s.distance(god.x, god.y, god.z)[0] for s in god.shapes)


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


def mesh_model(path: Path, mesh: trimesh.Trimesh, body: str = "", geom: str = "", extra: str = ""):
    """A model with one mesh geom named 'g' (asset 'm', file `path`), shapes built with MeshShape."""
    path.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_texture=False, digits=10))
    xml = (f'<mujoco><asset><mesh name="m" file="{path}"/></asset><worldbody>'
           f'<body name="b" {body}><geom name="g" type="mesh" mesh="m" {geom}/></body>{extra}</worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, shapes_of(m, d, mesh_shape=MeshShape)


@functools.cache
def sphere10k(tmp: str):
    """The 10k-triangle sphere (radius 5 cm, 9680 triangles) at the origin."""
    return mesh_model(Path(tmp) / "sphere10k.obj", geodesic_sphere(22, 0.05))


@functools.cache
def bowl():
    m = mujoco.MjModel.from_xml_path(str(BOWL_XML))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, shapes_of(m, d, mesh_shape=MeshShape)


@functools.cache
def tilted_ball(tmp: str):
    """An icosphere (1280 triangles) in a rotated, offset body, itself offset and rotated in it."""
    return mesh_model(Path(tmp) / "ball.obj", trimesh.creation.icosphere(3, radius=0.03),
                      body='pos="0.1 -0.05 0.2" euler="20 -35 50"', geom='pos="0.01 0.02 -0.01" euler="10 0 -70"')


@pytest.fixture(scope="module")
def tmp(tmp_path_factory):
    return str(tmp_path_factory.mktemp("meshes"))


def world_mesh(m, d, geom=None):
    """The geom's triangles in the world frame, as MuJoCo compiled them: (vertices, faces)."""
    g = geom if geom is not None else int(np.flatnonzero(m.geom_type == mujoco.mjtGeom.mjGEOM_MESH)[0])
    k = m.geom_dataid[g]
    v = m.mesh_vert[m.mesh_vertadr[k]:m.mesh_vertadr[k] + m.mesh_vertnum[k]].astype(float)
    f = m.mesh_face[m.mesh_faceadr[k]:m.mesh_faceadr[k] + m.mesh_facenum[k]]
    return v @ d.geom_xmat[g].reshape(3, 3).T + d.geom_xpos[g], f


def winding_number(points, v, f):
    """Generalised winding number of a closed mesh at each point (1 inside, 0 outside)."""
    a, b, c = (v[f[:, k]][None] - points[:, None] for k in range(3))
    la, lb, lc = (np.linalg.norm(x, axis=2) for x in (a, b, c))
    det = np.einsum("pij,pij->pi", a, np.cross(b, c))
    den = la * lb * lc + np.einsum("pij,pij->pi", a, b) * lc + np.einsum("pij,pij->pi", b, c) * la \
        + np.einsum("pij,pij->pi", c, a) * lb
    return np.arctan2(det, den).sum(axis=1) / (2.0 * np.pi)


def textbook_distance(points, v, f):
    """Distance from each point to the nearest triangle, the textbook way: the plane when the
    foot falls inside the triangle (barycentric coordinates >= 0), else the nearest edge."""
    a, b, c = v[f[:, 0]], v[f[:, 1]], v[f[:, 2]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n, axis=1)[:, None]
    out = []
    for p in points:
        h = ((p - a) * n).sum(1)
        foot = p - h[:, None] * n
        # barycentric coordinates of the foot by sub-triangle areas, signed along n
        wa = (np.cross(b - foot, c - foot) * n).sum(1)
        wb = (np.cross(c - foot, a - foot) * n).sum(1)
        wc = (np.cross(a - foot, b - foot) * n).sum(1)
        inside = (wa >= 0) & (wb >= 0) & (wc >= 0)
        best = np.full(len(f), np.inf)
        best[inside] = np.abs(h[inside])
        for s0, s1 in ((a, b), (b, c), (c, a)):
            e = s1 - s0
            t = np.clip(((p - s0) * e).sum(1) / (e * e).sum(1), 0.0, 1.0)
            best = np.minimum(best, np.linalg.norm(p - (s0 + t[:, None] * e), axis=1))
        out.append(best.min())
    return np.array(out)


def reference_distance(points, v, f):
    """The nearest triangle's distance: trimesh's closest point, checked by the textbook formula
    (trimesh 5's per-triangle closest point can land on an edge when the foot is just inside)."""
    _, dist, _ = trimesh.proximity.closest_point_naive(trimesh.Trimesh(v, f, process=False), points)
    return np.minimum(dist, textbook_distance(points, v, f))


def mesh_shape(shapes):
    return next(s for s in shapes if isinstance(s, MeshShape))


# ---------------------------------------------------------------------------------------
# Frame and exactness
# ---------------------------------------------------------------------------------------

def test_vertices_are_in_the_geom_frame(tmp):
    """MuJoCo recentres a mesh; mesh_vert is in the frame of geom_xpos/geom_xmat: every vertex of
    the file, placed by the body and geom poses written in the XML, lies on the MeshShape surface."""
    m, d, shapes = tilted_ball(tmp)
    s = mesh_shape(shapes)
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
    # and the centre of the ball is 3 cm inside
    centre = rb @ pg + pb
    assert s.distance(*centre)[0] == pytest.approx(-0.03, abs=5e-4)


coord = st.floats(-1.0, 1.0)


@settings(max_examples=25, deadline=None)
@given(st.sampled_from(["ball", "bowl"]), st.lists(st.tuples(coord, coord, coord), min_size=5, max_size=20))
@example("bowl", [(0.0, 0.0, 0.0)] * 4 + [(0.0, 0.0, -0.5)])  # 0.9 nm over the bowl's floor
def test_distance_and_normal_match_trimesh(tmp, which, unit_points):
    """Exact distance and outward normal against trimesh's closest point on random points, in
    the world frame; the sign says inside (winding number) wherever the point is not on the surface."""
    m, d, shapes = tilted_ball(tmp) if which == "ball" else bowl()
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    lo, hi = v.min(0), v.max(0)
    pts = (lo + hi) / 2 + np.array(unit_points) * 0.75 * (hi - lo)
    dist = reference_distance(pts, v, f)
    inside = winding_number(pts, v, f) > 0.5
    feet = []
    for p, dd, ins in zip(pts, dist, inside):
        sd, nx, ny, nz = s.distance(*p)
        assert abs(abs(sd) - dd) < 1e-9
        assert math.isclose(nx * nx + ny * ny + nz * nz, 1.0, abs_tol=1e-9)
        if dd > 1e-7:
            assert (sd < 0) == ins
        feet.append(p - sd * np.array((nx, ny, nz)))  # back along the outward normal
    # the foot of the normal is a nearest point (ties allowed): on the surface
    assert reference_distance(np.array(feet), v, f).max() < 1e-9


def test_distance_far_from_the_mesh_is_exact(tmp):
    """Far queries (an audit of a free finger) rebuild the neighbourhood and stay exact."""
    m, d, shapes = bowl()
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    pts = np.array([[0.0, 0.0, 0.09], [0.0, 0.0, 0.04], [0.3, 0.1, -0.2], [0.0, 0.0, 0.0405], [0.05, 0.0, 0.0401]])
    dist = reference_distance(pts, v, f)
    for p, dd in zip(pts, dist):
        assert abs(abs(s.distance(*p)[0]) - dd) < 1e-9


def distances_along(v, f, a, dvec, samples=200):
    """Exact distances to the mesh at samples along the segment from a by dvec."""
    t = np.linspace(0.0, 1.0, samples)
    return t, reference_distance(a + t[:, None] * dvec, v, f)


@contextlib.contextmanager
def recording_distances():
    """Record (x, y, z, signed distance) for every `MeshShape.distance` answer the block gets,
    to compare them afterwards with the brute force."""
    distance = MeshShape.distance
    answers = []

    def recorded(self, x, y, z):
        out = distance(self, x, y, z)
        answers.append((x, y, z, out[0]))
        return out

    MeshShape.distance = recorded
    try:
        yield answers
    finally:
        MeshShape.distance = distance


def check_sweep(hit, v, f, a, dvec, r, samples, skip_touching=False):
    """Asserts a sweep's answer against exact distances along its segment: a miss stays out of
    reach, a hit touches where it stops and nothing nearer before. Returns False, checking
    nothing, when `skip_touching` and the sphere starts within r."""
    t, along = distances_along(v, f, a, dvec, samples=samples)
    if skip_touching and along[0] < r:
        return False
    if hit is None:
        assert along.min() >= r - 1e-9
    else:
        assert along[t < hit[0]].min(initial=math.inf) >= r - 1e-9
        assert reference_distance((a + hit[0] * dvec)[None], v, f)[0] == pytest.approx(r, abs=1e-9)
    return True


@settings(max_examples=30, deadline=None)
@given(st.tuples(coord, coord, coord), st.tuples(coord, coord, coord), st.floats(0.0, 0.012), st.floats(0.002, 0.06))
def test_sweep_finds_the_first_touch(tmp, start, direction, r, length):
    """A sphere swept along a random segment: where the sweep stops the sphere touches; before it
    the sphere was never within r of any triangle; a miss stays out of reach all along."""
    m, d, shapes = tilted_ball(tmp)
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    centre = v.mean(0)
    a = centre + np.array(start) * 0.06
    u = np.array(direction)
    if np.linalg.norm(u) < 1e-3:
        return
    dvec = u / np.linalg.norm(u) * length
    if reference_distance(a[None], v, f)[0] < r + 1e-6:
        return  # starts touching: covered by the tangent/into tests
    hit = s.sweep(*a, *dvec, r)
    r = max(r, POINT_RADIUS)  # a point proxy is swept as a 10 nm sphere (see softproxy.mesh)
    t, dist = distances_along(v, f, a, dvec)
    if hit is None:
        assert dist.min() >= r - 1e-9
        return
    lam = hit[0]
    assert 0.0 <= lam < 1.0
    assert reference_distance((a + lam * dvec)[None], v, f)[0] == pytest.approx(r, abs=1e-9)
    assert dist[t < lam].min(initial=math.inf) >= r - 1e-9
    # the normal opposes the motion and points from the mesh to the sphere's centre
    n = np.array(hit[1:])
    assert n @ dvec < 0 and abs(np.linalg.norm(n) - 1.0) < 1e-9


def test_sweep_touching_sphere_slides_and_lifts_freely(tmp):
    """A sphere resting on a face and moving along or away from it is not stopped; into it, at once."""
    m, d, shapes = sphere10k(tmp)
    s = mesh_shape(shapes)
    r = 0.005
    god = GodObject(shapes, r, 0.0, 0.0, (0.0, 0.0, 0.08))
    god.update(0.0, 0.0, 0.05)
    assert god.contact
    x = (god.x, god.y, god.z)
    _, nx, ny, nz = s.distance(*x)
    n = np.array([nx, ny, nz])
    tangent = np.cross(n, [1.0, 0.0, 0.0])
    tangent *= 1e-4 / np.linalg.norm(tangent)
    assert s.sweep(*x, *(n * 1e-3), r) is None
    hit = s.sweep(*x, *(-n * 1e-3), r)
    assert hit is not None and hit[0] == 0.0 and np.allclose(hit[1:], n, atol=1e-6)
    hit = s.sweep(*x, *tangent, r)
    assert hit is None or hit[0] > 0.0  # a neighbour face may rise in the way, never the one touched


# ---------------------------------------------------------------------------------------
# The god-object on meshes
# ---------------------------------------------------------------------------------------

def random_path(rng_points, centre, scale):
    return [tuple(float(c) for c in centre + np.array(p) * scale) for p in rng_points]


@settings(max_examples=20, deadline=None)
@given(st.sampled_from(["sphere10k", "bowl"]), st.floats(0.0, 0.01), st.floats(0.0, 1.0),
       st.lists(st.tuples(coord, coord, coord), min_size=2, max_size=30))
def test_never_inside_on_a_random_device_path(tmp, which, radius, mu, points):
    """Random proxy radius, friction and device path through a 10k-triangle sphere and the bowl:
    the proxy never sits more than 1e-6 m inside."""
    if which == "sphere10k":
        m, d, shapes = sphere10k(tmp)
        centre, scale, start = np.zeros(3), 0.07, (0.0, 0.0, 0.09)
    else:
        m, d, shapes = bowl()
        centre, scale, start = np.array([0.0, 0.0, 0.03]), 0.05, (0.0, 0.0, 0.09)
    god = GodObject(shapes, radius, mu, 0.8 * mu, start)
    for p in random_path(points, centre, scale):
        god.update(*p)
        assert deepest(god) <= TOL


def test_never_inside_sliding_on_the_10k_sphere(tmp):
    """Pressed 2 mm in and dragged around a great circle and back: always outside, always touching."""
    m, d, shapes = sphere10k(tmp)
    r = 0.008
    god = GodObject(shapes, r, 0.3, 0.2, (0.0, 0.0, 0.09))
    u, v = np.array([0.31, 0.17, -0.93]), np.array([0.48, -0.87, 0.0])
    u /= np.linalg.norm(u)
    v -= (v @ u) * u
    v /= np.linalg.norm(v)
    rad = 0.05 + r - 0.002
    for k in range(600):
        a = 0.004 * k
        god.update(*(rad * (math.cos(a) * u + math.sin(a) * v)).tolist())
        assert deepest(god) <= TOL
        if k > 5:
            assert god.contact


def test_finger_rests_in_the_bowl_below_the_hull():
    """Pressed into the bowl, the finger rests on the inner bottom (z = 5 mm + r), far below the
    plane of the rim (z = 40 mm) where MuJoCo's convex hull would hold it."""
    m, d, shapes = bowl()
    r = 0.008
    god = GodObject(shapes, r, 0.0, 0.0, (0.0, 0.0, 0.09))
    for z in np.linspace(0.09, 0.011, 40):
        god.update(0.0, 0.0, float(z))
        assert deepest(god) <= TOL
    assert god.contact and god.shape.name == "bowl"
    assert god.z == pytest.approx(0.005 + r, abs=1e-4)  # faceted: a hair above the sphere
    assert god.z < 0.04
    assert (god.nx, god.ny, god.nz) == pytest.approx((0.0, 0.0, 1.0), abs=1e-6)
    # stroked across the inside, it follows the concave wall up
    for a in np.linspace(0.0, math.radians(60), 60):
        god.update(0.029 * math.sin(a), 0.0, 0.04 - 0.029 * math.cos(a))
        assert deepest(god) <= TOL and god.contact
    assert math.hypot(god.x, god.z - 0.04) == pytest.approx(0.027, abs=1e-4)


def plate(open_sheet: bool) -> trimesh.Trimesh:
    """A 10 cm square, 1 mm thick (a closed box about z = 0), or a zero-thickness sheet at z = 0
    with a flap bent down along one side (MuJoCo needs a volume for the hull it collides with)."""
    if open_sheet:
        v = [[-0.05, -0.05, 0.0], [0.05, -0.05, 0.0], [0.05, 0.05, 0.0], [-0.05, 0.05, 0.0], [0.06, 0.0, -0.01]]
        return trimesh.Trimesh(np.array(v), np.array([[0, 1, 2], [0, 2, 3], [1, 4, 2]]), process=False)
    return trimesh.creation.box(extents=(0.1, 0.1, 0.001))


@pytest.mark.parametrize("open_sheet", [False, True])
@pytest.mark.parametrize("speed", [1.0, 10.0, 100.0])
def test_thin_mesh_plate_never_popped_through(tmp_path, open_sheet, speed):
    """A 1 mm mesh plate (and a zero-thickness sheet) crossed at up to 100 m/s at 1 kHz: the
    proxy stays on the near side."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        m, d, shapes = mesh_model(tmp_path / "plate.obj", plate(open_sheet))
    assert any("open mesh" in str(w.message) for w in caught) == open_sheet
    top = 0.0 if open_sheet else 0.0005
    for radius in (0.0, 0.005):
        god = GodObject(shapes, radius, 0.5, 0.4, (0.001, 0.0, 0.01))
        z = 0.01
        for _ in range(40):
            z -= speed * 1e-3
            god.update(0.001, 0.0, z)
            assert god.z >= top + radius - TOL
            assert deepest(god) <= TOL
        assert god.contact


def test_moving_mesh_carries_and_pushes_out(tmp_path):
    """The proxy rides a moving mesh body and is pushed out when the mesh moves into it."""
    xml_box = trimesh.creation.box(extents=(0.1, 0.1, 0.1))
    m, d, shapes = mesh_model(tmp_path / "box.obj", xml_box, body='mocap="true"')
    s = mesh_shape(shapes)
    assert not s.static
    god = GodObject(shapes, 0.0, 1.0, 0.8, (0.0, 0.0, 0.1))
    god.update(0.0, 0.0, 0.04)
    assert god.z == pytest.approx(0.05 + POINT_RADIUS, abs=1e-9)  # a point proxy rests 10 nm off
    d.mocap_pos[0] = (0.01, 0.0, 0.0)
    mujoco.mj_forward(m, d)
    s.refresh()
    god.update(0.0, 0.0, 0.04)
    assert god.x == pytest.approx(0.01, abs=1e-9) or not god.sticking
    god.reset(0.0, 0.0, 0.06)
    d.mocap_pos[0] = (0.0, 0.0, 0.02)  # the box rises 2 cm into the free proxy
    mujoco.mj_forward(m, d)
    s.refresh()
    god.update(0.0, 0.0, 0.2)
    assert deepest(god) <= TOL


def test_force_shading_smooths_the_normal(tmp):
    """With shading the normal follows the interpolated vertex normals: on a faceted sphere it is
    closer to the true radial direction than the face normal, and the proxy still stays outside."""
    m, d, _ = sphere10k(tmp)
    shaded = shapes_of(m, d, mesh_shape=functools.partial(MeshShape, shading=True))
    plain = shapes_of(m, d, mesh_shape=MeshShape)
    rng = np.random.default_rng(3)
    worse = 0
    for p in rng.normal(size=(50, 3)):
        p = p / np.linalg.norm(p) * 0.052
        radial = p / np.linalg.norm(p)
        a = np.array(shaded[0].distance(*p)[1:])
        b = np.array(plain[0].distance(*p)[1:])
        assert abs(np.linalg.norm(a) - 1.0) < 1e-9
        worse += np.arccos(min(1.0, a @ radial)) > np.arccos(min(1.0, b @ radial)) + 1e-12
    assert worse == 0
    god = GodObject(shaded, 0.005, 0.0, 0.0, (0.0, 0.0, 0.09))
    for k in range(200):
        a = 0.01 * k
        god.update(0.053 * math.sin(a), 0.0, 0.053 * math.cos(a))
        assert deepest(god) <= TOL


def test_neighbourhood_is_reused_while_sliding(tmp):
    """Bounded work: sliding 0.1 mm per tick on the 10k sphere rebuilds the cached
    neighbourhood on few ticks (the scans read a handful of triangles in between)."""
    m, d, shapes = sphere10k(tmp)
    s = mesh_shape(shapes)
    r = 0.008
    god = GodObject(shapes, r, 0.0, 0.0, (0.0, 0.0, 0.09))
    god.update(0.0, 0.0, 0.05 + r - 0.002)
    before = s.rebuilds
    n = 1000
    for k in range(n):
        a = k * 1e-4 / 0.056
        god.update(0.056 * math.sin(a), 0.0, 0.056 * math.cos(a))
    assert god.contact
    assert (s.rebuilds - before) / n < 0.1


def test_bowl_slide_rebuilds_rarely_and_answers_exactly():
    """Sliding round the inside of the bowl (concave: every scan reads the rising wall), the
    drifted neighbourhood is re-centred only once the scans have paid for a rebuild: few
    rebuilds over 1500 ticks, and every distance the god-object was given along the way equals
    the brute force over all triangles."""
    m, d, shapes = bowl()
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d, geom=s.geom)
    r = 0.005
    god = GodObject(shapes, r, 0.3, 0.24, (0.0, 0.0, 0.03))
    rho = 0.035 - r + 0.002
    def device(k):
        a = 0.3 + 0.5 * math.sin(0.004 * k)
        return rho * math.sin(a), 0.0, 0.04 - rho * math.cos(a)

    for k in range(300):
        god.update(*device(k))
    before = s.rebuilds
    with recording_distances() as answers:
        for k in range(300, 1800):
            god.update(*device(k))
            assert deepest(god) <= TOL
    assert god.contact
    assert len(answers) > 1500
    assert s.rebuilds - before < 0.08 * 1500
    pts = np.array([a[:3] for a in answers[::7]])
    ref = reference_distance(pts, v, f)
    signed = np.where(winding_number(pts, v, f) > 0.5, -ref, ref)
    assert np.abs(np.array([a[3] for a in answers[::7]]) - signed).max() < 1e-9


# ---------------------------------------------------------------------------------------
# The scene
# ---------------------------------------------------------------------------------------

def test_mesh_object_scene_strokes_inside_the_bowl():
    """The shipped scene: one finger strokes the inside of the bowl; with mesh contact it stays
    out of the triangles and goes down into the dent, below the rim's plane."""
    from softproxy.finger import SoftFingerProxy
    from softproxy.fingertip import model as fingertip_model
    from softproxy.run import open_device
    from softproxy.scene import load_scene
    from softproxy.servo import ServoLoop
    from softproxy.world import World

    scene = load_scene("mesh_object")
    world = World(scene.load_model(), mesh_shape=MeshShape)
    fingers = [SoftFingerProxy(p, world.shapes, fingertip_model(p.model)) for p in scene.fingers]
    loop = ServoLoop(world, fingers, open_device("sim", scene), scene.rate_hz, audit=True, overrun_watchdog=False)
    lowest, touched = math.inf, 0
    for _ in range(int(scene.duration_s * scene.rate_hz)):
        loop.tick()
        god = fingers[0].god
        if god.contact:
            touched += 1
            lowest = min(lowest, god.z)
    assert fingers[0].penetration_max <= TOL
    assert touched > 1500
    assert lowest == pytest.approx(0.013, abs=2e-4)


# ---------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------

@pytest.fixture
def good():
    ico = trimesh.creation.icosphere(1, radius=0.03)
    return np.array(ico.vertices), np.array(ico.faces)


def volume(v, f):
    return trimesh.Trimesh(v, f, process=False).volume


def test_clean_mesh_has_no_defects(good):
    v, f, defects = validate_mesh(*good, "ico")
    assert defects == [] and len(f) == len(good[1])


def test_degenerate_triangles_are_dropped(good):
    v, f = good
    v2 = np.vstack([v, [[0.1, 0.0, 0.0], [0.2, 0.0, 0.0], [0.3, 0.0, 0.0]]])  # collinear
    n = len(v)
    f2 = np.vstack([f, [[0, 0, 1], [n, n + 1, n + 2]]])
    with pytest.warns(MeshWarning, match="mesh ico: 2 degenerate \\(zero-area\\) triangles dropped"):
        _, out, defects = validate_mesh(v2, f2, "ico")
    assert len(out) == len(f) and any("degenerate" in x for x in defects)


def test_duplicate_triangles_are_dropped(good):
    v, f = good
    f2 = np.vstack([f, f[:3], f[3:4, ::-1]])  # the same triangles again, one of them flipped
    with pytest.warns(MeshWarning, match="4 duplicate triangles dropped"):
        _, out, _ = validate_mesh(v, f2, "ico")
    assert len(out) == len(f)


def test_open_mesh_is_kept_and_reported(good):
    v, f = good
    with pytest.warns(MeshWarning, match="open mesh .*boundary edges"):
        _, out, defects = validate_mesh(v, f[:-4], "ico")
    assert len(out) == len(f) - 4


def test_inverted_normals_are_flipped(good):
    v, f = good
    with pytest.warns(MeshWarning, match="inverted normals"):
        v2, out, _ = validate_mesh(v, f[:, ::-1], "ico")
    assert volume(v2, out) > 0.0


def test_inconsistent_winding_is_made_consistent(good):
    v, f = good
    f2 = f.copy()
    f2[:7] = f2[:7, ::-1]
    with pytest.warns(MeshWarning, match="inconsistent winding"):
        v2, out, _ = validate_mesh(v, f2, "ico")
    t = trimesh.Trimesh(v2, out, process=False)
    assert t.is_winding_consistent and t.volume > 0.0


def test_non_manifold_edges_are_reported(good):
    v, f = good
    a, b = f[0, 0], f[0, 1]
    v2 = np.vstack([v, [[0.0, 0.0, 0.2]]])
    with pytest.warns(MeshWarning, match="non-manifold"):
        validate_mesh(v2, np.vstack([f, [[a, b, len(v)]]]), "ico")


def test_unusable_meshes_raise_naming_the_mesh(good):
    v, f = good
    with pytest.raises(ValueError, match="mesh lump: no usable triangles"):
        validate_mesh(v, np.array([[0, 0, 1], [1, 1, 2]]), "lump", warn=False)
    with pytest.raises(ValueError, match="mesh lump: face indices out of range"):
        validate_mesh(v, np.array([[0, 1, 999]]), "lump", warn=False)


def test_warning_names_geom_mesh_and_file(tmp_path, good):
    """Loading a bad mesh through MuJoCo: the warning says which geom, which mesh asset, which
    file, and what was wrong; the shape works on the repaired mesh (signed: inside is negative)."""
    v, f = good
    bad = trimesh.Trimesh(v, np.vstack([f, f[:2]])[:, ::-1], process=False)  # duplicates, inverted
    with pytest.warns(MeshWarning) as caught:
        m, d, shapes = mesh_model(tmp_path / "crafted.obj", bad)
    text = [str(w.message) for w in caught]
    assert any("2 duplicate triangles dropped" in t for t in text)
    assert any("inverted normals" in t for t in text)
    for t in text:
        assert "'m'" in t and "geom 'g'" in t and "crafted.obj" in t
    s = mesh_shape(shapes)
    assert s.defects and s.signed
    assert s.distance(0.0, 0.0, 0.0)[0] < -0.02  # the centre is inside
    assert s.distance(0.0, 0.0, 0.05)[0] > 0.0


# ---------------------------------------------------------------------------------------
# Cheap paths: they must give the answers of the full scans
# ---------------------------------------------------------------------------------------

@functools.cache
def uv_sphere(tmp: str):
    """trimesh's uv-sphere (radius 5 cm, ~10k triangles): ~100 thin triangles meet at each pole."""
    mesh = trimesh.creation.uv_sphere(radius=0.05, count=[51, 51])
    mesh.merge_vertices()
    mesh.update_faces(mesh.nondegenerate_faces())
    return mesh_model(Path(tmp) / "uv.obj", mesh)


@contextlib.contextmanager
def counting_closest_calls():
    """Count, in the list's one item, the exact point-triangle queries (`mesh._closest`) the
    block makes: how many triangles a query really read."""
    from softproxy import mesh as mesh_module

    closest = mesh_module._closest
    calls = [0]

    def counted(*args):
        calls[0] += 1
        return closest(*args)

    mesh_module._closest = counted
    try:
        yield calls
    finally:
        mesh_module._closest = closest


def test_held_on_a_pole_is_exact_and_cheap(tmp):
    """A proxy pressed onto the pole vertex of a uv-sphere: the vertex certificate skips the
    fan, and the answers agree with the reference, for points about the pole and sweeps from
    there in every direction."""
    m, d, shapes = uv_sphere(tmp)
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    pole = v[np.argmax(v[:, 2])]
    r = 0.005
    god = GodObject(shapes, r, 0.5, 0.4, (0.0, 0.0, 0.08))
    for k in range(50):
        god.update(1e-5 * math.sin(0.1 * k), 0.0, pole[2] + r - 0.003)
        assert deepest(god) <= TOL
    assert god.contact
    rng = np.random.default_rng(7)
    pts = pole + np.array([0.0, 0.0, r]) + rng.normal(scale=2e-5, size=(30, 3))
    dist = reference_distance(pts, v, f)
    with counting_closest_calls() as calls:
        for p, dd in zip(pts, dist):
            assert abs(s.distance(*p)[0] - dd) < 1e-9
    assert calls[0] <= 3 * len(pts)  # the hint (and its neighbour), not the ~100 triangles of the fan
    start = np.array((god.x, god.y, god.z))
    for u in rng.normal(size=(20, 3)):
        dvec = u / np.linalg.norm(u) * 2e-4
        hit = s.sweep(*start, *dvec, r)
        check_sweep(hit, v, f, start, dvec, r, 50)


def test_distance_answer_kept_only_for_the_same_point_and_pose(tmp_path):
    """The last distance is kept for a repeated query; a moved mesh (refresh) answers anew."""
    m, d, shapes = mesh_model(tmp_path / "box.obj", trimesh.creation.box(extents=(0.1, 0.1, 0.1)),
                              body='mocap="true"')
    s = mesh_shape(shapes)
    p = (0.01, 0.02, 0.08)
    first = s.distance(*p)
    assert first[0] == pytest.approx(0.03, abs=1e-7)
    assert s.distance(*p) == first
    d.mocap_pos[0] = (0.0, 0.0, 0.01)
    mujoco.mj_forward(m, d)
    s.refresh()
    assert s.distance(*p)[0] == pytest.approx(0.02, abs=1e-7)
    d.mocap_quat[0] = (math.cos(math.pi / 8), math.sin(math.pi / 8), 0.0, 0.0)  # 45° about x
    mujoco.mj_forward(m, d)
    s.refresh()
    dd, nx, ny, nz = s.distance(*p)
    # the box's +z face turned to face (0, -1, 1)/√2, its -y face to (0, -1, -1)/√2 ...: the
    # corner-free answer from the rotated frame
    local = np.array(p) - d.geom_xpos[0]
    local = d.geom_xmat[0].reshape(3, 3).T @ local
    q = np.clip(local, -0.05, 0.05)
    assert dd == pytest.approx(np.linalg.norm(local - q), abs=1e-7)


def test_on_face_only_for_faces_held(tmp):
    """on_face: true for the normal of a face sweeps stopped on twice at the same point (a held
    proxy), false once it stopped elsewhere on it (sliding), for an edge's normal, and for a
    face nothing stopped on."""
    m, d, shapes = sphere10k(tmp)
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    a, b, c = v[f[123]]
    n = np.cross(b - a, c - a)
    n /= np.linalg.norm(n)
    centre = (a + b + c) / 3.0
    assert not s.on_face(*n)
    start = centre + 0.01 * n
    hit = s.sweep(*start, *(-0.02 * n), 0.001)
    assert hit is not None and np.allclose(hit[1:], n, atol=1e-9)
    assert not s.on_face(*n)  # stopped there once: maybe sliding
    assert s.sweep(*start, *(-0.02 * n), 0.001) == hit
    assert s.on_face(*n) and s.on_face(*-n)  # held
    assert s.sweep(*(start + 1e-5 * (b - a)), *(-0.02 * n), 0.001) is not None
    assert not s.on_face(*n)  # stopped elsewhere on it: sliding
    edge = (a + b) / 2.0
    out = edge / np.linalg.norm(edge)
    hit = s.sweep(*(edge + 0.01 * out), *(-0.02 * out), 0.001)
    assert hit is not None
    assert not s.on_face(*hit[1:])


def test_walk_from_a_vertex_finds_the_nearer_fan_triangle(tmp):
    """The hint's nearest point is the pole, but the query lies over another triangle of the
    fan: the walk (and the scan after) give the reference distance, for the sweep too."""
    m, d, shapes = uv_sphere(tmp)
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    top = int(np.argmax(v[:, 2]))
    fan = np.flatnonzero((f == top).any(axis=1))
    rng = np.random.default_rng(11)
    for k in range(40):
        s._hint = int(fan[k % len(fan)])
        s._dkey = None
        a = rng.uniform(0.0, 2.0 * math.pi)
        p = v[top] + np.array([0.002 * math.cos(a), 0.002 * math.sin(a), 0.004])
        assert abs(s.distance(*p)[0] - reference_distance(p[None], v, f)[0]) < 1e-9
        s._hint = int(fan[(k * 7) % len(fan)])
        dvec = np.array([-math.cos(a), -math.sin(a), -1.0]) * 0.003
        hit = s.sweep(*p, *dvec, 0.002)
        check_sweep(hit, v, f, p, dvec, 0.002, 60)


def test_vertex_certificate_off_the_fan(tmp_path, tmp):
    """Over a vertex, triangles off its fan are left unread only when they lie behind the
    tangent plane: a small box floating beside a vertex of a geodesic sphere is found (the
    distance and the sweep agree with the reference), while over a vertex of the uv-sphere's
    anisotropic rings, where no triangle rises above that plane, the hint alone is read."""
    ball = geodesic_sphere(10, 0.05)
    v0 = ball.vertices
    top = int(np.argmax(v0 @ np.array([0.3, 0.2, 0.93])))
    a = v0[top] / np.linalg.norm(v0[top])
    side = np.cross(a, (0.0, 0.0, 1.0))
    side /= np.linalg.norm(side)
    box = trimesh.creation.box(extents=(0.002, 0.002, 0.002))
    box.apply_translation(v0[top] + 0.004 * a + 0.003 * side)
    m, d, shapes = mesh_model(tmp_path / "ball_box.obj", trimesh.util.concatenate([ball, box]))
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    # the chosen vertex as compiled (MuJoCo moves the mesh into its own frame; the ball's
    # faces come first): the farthest along the same direction from the ball's centre
    centre = v[f[:len(ball.faces)]].reshape(-1, 3).mean(0)
    vertex = int(f[:len(ball.faces)].reshape(-1)[np.argmax((v[f[:len(ball.faces)]].reshape(-1, 3) - centre) @ a)])
    fan = np.flatnonzero((f == vertex).any(axis=1))
    out = (v[vertex] - centre) / np.linalg.norm(v[vertex] - centre)
    assert out @ a > 1.0 - 1e-9
    tables = 0
    table = MeshShape._vertex_table

    def counted(self, *args):
        nonlocal tables
        tables += 1
        return table(self, *args)

    rng = np.random.default_rng(5)
    MeshShape._vertex_table = counted
    try:
        for k in range(60):
            p = v[vertex] + rng.uniform(0.001, 0.007) * out + rng.normal(scale=2e-4, size=3)
            s._hint = int(fan[k % len(fan)])
            s._dkey = None
            assert abs(s.distance(*p)[0] - reference_distance(p[None], v, f)[0]) < 1e-9
            s._hint = int(fan[(k * 3) % len(fan)])
            dvec = rng.normal(scale=0.002, size=3)
            r = 0.001
            hit = s.sweep(*p, *dvec, r)
            check_sweep(hit, v, f, p, dvec, r, 60, skip_touching=True)
    finally:
        MeshShape._vertex_table = table
    assert tables > 0

    # the uv-sphere: a ring vertex ~25° from the pole, its edges 0.9 mm along the ring, 3 mm across
    m, d, shapes = uv_sphere(tmp)
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    vertex = int(np.argmin(np.linalg.norm(v - 0.05 * np.array([math.sin(0.44), 0.0, math.cos(0.44)]), axis=1)))
    fan = np.flatnonzero((f == vertex).any(axis=1))
    out = v[vertex] / np.linalg.norm(v[vertex])
    pts = v[vertex] + 0.005 * out + rng.normal(scale=3e-6, size=(30, 3))
    dist = reference_distance(pts, v, f)
    s.distance(*pts[0])  # the neighbourhood and the vertex's table, built once
    with counting_closest_calls() as calls:
        for p, dd in zip(pts, dist):
            s._hint = int(fan[0])
            s._dkey = None
            assert abs(s.distance(*p)[0] - dd) < 1e-9
    assert calls[0] <= 3 * len(pts)


def small_tetra(at) -> trimesh.Trimesh:
    """A tetrahedron (4 triangles, 0.6 mm legs) centred at `at` (m)."""
    tetra = trimesh.Trimesh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float) * 6e-4,
                            np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]]), process=False)
    tetra.apply_translation(at - tetra.vertices.mean(0))
    return tetra


def ball_with_tetra_over_a_face(path: Path, height: float):
    """A geodesic sphere (2000 triangles, 5 cm) with `small_tetra` floating `height` (m) over
    its face nearest (0.1, 0.2, 0.97): (shape, world vertices, faces, the ball's faces, that face
    and its unit normal as compiled, the ball's face centres)."""
    ball = geodesic_sphere(10, 0.05)
    top = int(np.argmax(ball.triangles_center @ np.array([0.1, 0.2, 0.97])))
    normal = ball.face_normals[top]
    tetra = small_tetra(ball.triangles_center[top] + height * normal)
    m, d, shapes = mesh_model(path, trimesh.util.concatenate([ball, tetra]))
    v, f = world_mesh(m, d)
    # the chosen face as compiled (MuJoCo moves the mesh into its own frame): the ball's face
    # whose centre lies farthest along the same direction
    ball_f = f[:len(ball.faces)]
    centres = v[ball_f].mean(1)
    face = int(np.argmax((centres - v[ball_f].reshape(-1, 3).mean(0)) @ normal))
    n = np.cross(v[f[face, 1]] - v[f[face, 0]], v[f[face, 2]] - v[f[face, 0]])
    return mesh_shape(shapes), v, f, ball_f, face, n / np.linalg.norm(n), centres


def test_kept_certificate_reads_the_few_triangles_above_a_face(tmp_path):
    """A tetrahedron (4 triangles) floating 2 mm over a face of a geodesic sphere rises above
    the face's plane: the face's kept certificate lists exactly those few, so distances and
    sweeps from over the face find the tetrahedron (they agree with the reference), without a
    neighbourhood rebuild, while a face far from it has an empty list."""
    s, v, f, ball_f, face, n, centres = ball_with_tetra_over_a_face(tmp_path / "ball_tetra.obj", 0.002)
    rng = np.random.default_rng(3)
    s.distance(*(centres[face] + 0.006 * n))  # a neighbourhood, built once
    before = s.rebuilds
    pts = centres[face] + rng.uniform(0.0015, 0.004, size=(60, 1)) * n + rng.normal(scale=3e-4, size=(60, 3))
    dist = reference_distance(pts, v, f)
    assert (dist < reference_distance(pts, v, ball_f)).any()  # the tetrahedron is nearest for some
    for p, dd in zip(pts, dist):
        s._hint, s._dkey, s._skey = face, None, None
        assert abs(abs(s.distance(*p)[0]) - dd) < 1e-9  # (negative inside the tetrahedron)
    assert s.rebuilds == before  # the kept certificate answered them all
    r = 0.001
    for p in pts:  # spheres touching the face, swept every way
        p = p - (p - centres[face]) @ n * n + (r + 1e-9) * n
        s._hint = face
        dvec = rng.normal(scale=0.0015, size=3)
        hit = s.sweep(*p, *dvec, r)
        check_sweep(hit, v, f, p, dvec, r, 80, skip_touching=True)
    tetra_ids = set(range(len(ball_f), len(f)))
    kept = s._clear[face][1]
    assert kept is not None and set(kept) == tetra_ids
    far = int(np.argmin(centres @ n))  # the opposite side of the ball: nothing rises above it
    assert s._face_clear(far, 1.0, 0.01) == ()


def test_sliding_on_a_convex_mesh_needs_no_neighbourhood(tmp):
    """Sliding round the 10k sphere, the kept certificates answer every query: the cached
    neighbourhood is (almost) never rebuilt, and every distance the god-object was given equals
    the brute force over all triangles."""
    m, d, shapes = sphere10k(tmp)
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    r = 0.005
    god = GodObject(shapes, r, 0.3, 0.24, (0.0, 0.0, 0.09))
    god.update(0.0, 0.0, 0.05 + r - 0.002)
    before = s.rebuilds
    with recording_distances() as answers:
        for k in range(1500):
            a = 0.3 + 0.5 * math.sin(0.004 * k)
            god.update(0.053 * math.sin(a), 0.01 * math.sin(0.003 * k), 0.053 * math.cos(a))
            assert deepest(god) <= 1e-9
    assert god.contact
    assert s.rebuilds - before <= 8  # the neighbourhood's certificates alone: 24-51 over this path
    assert len(answers) > 1500
    pts = np.array([a[:3] for a in answers[::5]])
    assert np.abs(np.array([a[3] for a in answers[::5]]) - reference_distance(pts, v, f)).max() < 1e-9


def test_kept_vertex_certificate_reads_the_few_triangles_above(tmp_path):
    """A tetrahedron floating 3 mm over a vertex of a geodesic sphere, off to one side: from
    points over the vertex, the vertex's kept table hands over the tetrahedron's triangles (a
    few that rise above the tangent plane) and the distances agree with the reference."""
    ball = geodesic_sphere(10, 0.05)
    top = int(np.argmax(ball.vertices @ np.array([0.2, -0.1, 0.97])))
    out = ball.vertices[top] / np.linalg.norm(ball.vertices[top])
    side = np.cross(out, (1.0, 0.0, 0.0))
    side /= np.linalg.norm(side)
    tetra = small_tetra(ball.vertices[top] + 0.003 * out + 0.0025 * side)
    m, d, shapes = mesh_model(tmp_path / "ball_tetra_v.obj", trimesh.util.concatenate([ball, tetra]))
    s = mesh_shape(shapes)
    v, f = world_mesh(m, d)
    ball_f = f[:len(ball.faces)]
    centre = v[ball_f].reshape(-1, 3).mean(0)
    vertex = int(ball_f.reshape(-1)[np.argmax((v[ball_f].reshape(-1, 3) - centre) @ out)])
    fan = np.flatnonzero((ball_f == vertex).any(axis=1))
    normal = (v[vertex] - centre) / np.linalg.norm(v[vertex] - centre)
    rng = np.random.default_rng(7)
    pts = v[vertex] + rng.uniform(0.001, 0.004, size=(40, 1)) * normal + rng.normal(scale=2e-6, size=(40, 3))
    dist = reference_distance(pts, v, f)
    static = MeshShape._static_clear
    handed = []

    def kept(self, hint, feature, *args):
        few = static(self, hint, feature, *args)
        if feature >= 4 and few:
            handed.append(set(few))
        return few

    MeshShape._static_clear = kept
    try:
        for k, (p, dd) in enumerate(zip(pts, dist)):
            s._hint, s._dkey, s._skey = int(fan[k % len(fan)]), None, None
            assert abs(abs(s.distance(*p)[0]) - dd) < 1e-9
    finally:
        MeshShape._static_clear = static
    tetra_ids = set(range(len(ball.faces), len(f)))
    assert handed and all(h <= tetra_ids for h in handed)


def dented_ball_with_tetra(tmp_path):
    """A geodesic sphere (720 triangles) with a dozen vertices pushed 1.5 mm in (concave
    patches round them) and a tetrahedron floating 2 mm over one face: a MeshShape in it."""
    ball = geodesic_sphere(6, 0.05)
    v = ball.vertices.copy()
    v[np.random.default_rng(11).choice(len(v), 12, replace=False)] *= 0.97
    top = int(np.argmax(ball.triangles_center @ np.array([0.3, -0.2, 0.93])))
    tetra = small_tetra(ball.triangles_center[top] + 0.002 * ball.face_normals[top])
    mesh = trimesh.util.concatenate([trimesh.Trimesh(v, ball.faces, process=False), tetra])
    return mesh_shape(mesh_model(tmp_path / "dented.obj", mesh)[2])


def test_kept_tables_built_at_load_match_brute_force(tmp_path):
    """The certificates built at load for every face and vertex at once (numpy, from the
    vertices near each) agree with a brute force over all triangles, on a sphere with dents and
    a floating tetrahedron: a face's list holds every triangle within the radius that rises above
    its plane (or the face is marked concave only where one does), and a vertex's table lists
    every vertex of the triangles within the radius, off its ring, no later than its sin β."""
    s = dented_ball_with_tetra(tmp_path)
    radius = s._kept
    abc, n, off, centre, rhos = s._abc, s._fn, s._off, s._centre, s._rhos
    concave = listed = 0
    for i in range(s.triangles):
        near = np.flatnonzero(np.linalg.norm(centre - centre[i], axis=1) - rhos - rhos[i] <= radius)
        height = abc[near] @ n[i] - off[i]
        for side, key in ((1.0, i), (-1.0, -1 - i)):
            rising = set(near[(side * height > ABOVE_TOL).any(axis=1)].tolist())
            kept_radius, few = s._clear[key]
            if few is None:
                assert rising
                concave += side > 0.0
            else:
                assert kept_radius >= radius and rising <= set(few)
                listed += bool(few) and side > 0.0
    assert concave > 0 and listed > 0  # the dents and the tetrahedron
    faces = s._faces
    for vertex in np.unique(faces):
        fan = (faces == vertex).any(axis=1)
        ring = set(faces[fan].reshape(-1).tolist())
        near = (np.linalg.norm(centre - s._vpos[vertex], axis=1) - rhos <= radius) & ~fan
        others = sorted(set(faces[near].reshape(-1).tolist()) - ring)
        u = s._vpos[others] - s._vpos[vertex]
        sines = -(u @ s._vaxis[vertex]) / np.linalg.norm(u, axis=1)
        kept_radius, table, ids, _ = s._vertex_clear(int(vertex), radius)
        assert kept_radius >= radius and table == sorted(table)
        cut = table[-1] if len(table) > VERTEX_READ else math.inf
        kept = dict(zip(ids, table))
        for w, sine in zip(others, sines):
            if sine < cut:
                assert kept[w] <= sine


def test_kept_certificate_beyond_its_radius_is_built_for_the_query(tmp_path):
    """A tetrahedron floating 17 mm over a face lies beyond the radius the kept certificates
    are built over at load (a 5 mm proxy): a point 11 mm over the face, nearer the tetrahedron,
    builds that face's certificate over its own reach and finds it; after `prepare` for a
    1 cm proxy the table built then already lists it, and no query builds one."""
    path = tmp_path / "ball_far_tetra.obj"
    s, v, f, ball_f, face, n, centres = ball_with_tetra_over_a_face(path, 0.017)
    tetra_ids = set(range(len(ball_f), len(f)))
    assert s._clear[face] == (s._kept, ())  # nothing rises within the load radius
    p = centres[face] + 0.011 * n
    truth = reference_distance(p[None], v, f)[0]
    assert truth < 0.0065  # the tetrahedron is nearest
    s._hint, s._dkey, s._skey = face, None, None
    assert abs(abs(s.distance(*p)[0]) - truth) < 1e-9
    assert set(s._clear[face][1]) == tetra_ids

    s = ball_with_tetra_over_a_face(path, 0.017)[0]
    s.prepare(0.01)
    assert s._kept >= 0.02 and set(s._clear[face][1]) == tetra_ids
    built = []
    tables = MeshShape._face_tables
    MeshShape._face_tables = lambda self, *args: built.append(args) or tables(self, *args)
    try:
        for p in centres[face] + np.array([0.009, 0.01, 0.0105])[:, None] * n:
            s._hint, s._dkey, s._skey = face, None, None
            assert abs(abs(s.distance(*p)[0]) - reference_distance(p[None], v, f)[0]) < 1e-9
    finally:
        MeshShape._face_tables = tables
    assert not built


def test_a_god_object_prepares_the_mesh_for_its_radius(tmp_path):
    """Making a god-object of 8 mm radius builds the mesh's kept certificates over its reach
    (`Shape.prepare`), so the face under the tetrahedron 17 mm up already lists it before
    any query, and the proxy's ticks pressed on that face build no table."""
    path = tmp_path / "ball_far_tetra.obj"
    s, v, f, ball_f, face, n, centres = ball_with_tetra_over_a_face(path, 0.017)
    tetra_ids = set(range(len(ball_f), len(f)))
    assert set(s._clear[face][1] or ()) != tetra_ids  # not within the load-time radius
    god = GodObject([s], 0.008, 0.5, 0.4, tuple(centres[face] + 0.0085 * n))
    assert set(s._clear[face][1]) == tetra_ids
    built = []
    tables = MeshShape._face_tables
    MeshShape._face_tables = lambda self, *args: built.append(args) or tables(self, *args)
    try:
        along = (v[f[face, 1]] - v[f[face, 0]]) / np.linalg.norm(v[f[face, 1]] - v[f[face, 0]])
        for k in range(20):  # pressed 1 mm in, wiggled along the face
            q = centres[face] + 0.007 * n + 2e-4 * math.sin(0.3 * k) * along
            god.update(*q)
            assert god.contact and deepest(god) <= 1e-6
    finally:
        MeshShape._face_tables = tables
    assert not built


def test_a_sweep_names_the_edge_it_touched():
    """A sphere sliding parallel to edge AB into edge BC touches BC (feature 2), whatever the
    edges before it in the loop did (a sweep parallel to AB skips AB's cylinder)."""
    from softproxy.mesh import _sweep_triangle
    v = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    a, b, c = v
    n = np.array([0.0, 0.0, 1.0])
    ab, ac = b - a, c - a
    aa, abac, cc = ab @ ab, ab @ ac, ac @ ac
    tri = (*a, *b, *c, *ab, *ac, *n, aa, abac, cc, 1.0 / (aa * cc - abac * abac))
    edges = []
    for s, e in ((a, b), (b, c), (c, a)):
        length = float(np.linalg.norm(e - s))
        edges.append((*s, *((e - s) / length), length))
    start, move, r = (0.8, 0.8, 0.05), (-0.6, 0.0, 0.0), 0.1
    dd = sum(m * m for m in move)
    hit = _sweep_triangle(tri, edges, *start, *move, r, dd, (r + 0.6 + 1e-9) ** 2, 1e-9 * 0.6)
    assert hit is not None and hit[4] == 2
    # the touch is on BC's cylinder: the centre is r from the line x + y = 1 (in 3-d)
    x = start[0] + hit[0] * move[0]
    assert math.hypot((x + start[1] - 1.0) / math.sqrt(2.0), start[2]) == pytest.approx(r, abs=1e-12)
