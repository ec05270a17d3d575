"""The numba shape queries (softproxy.compiled.shapes) against softproxy.geometry: bit for bit."""

import math
import struct

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from softproxy.compiled.layout import (
    GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_PLANE, GEOM_SPHERE,
    S_A, S_B, S_BODY, S_C, S_COLUMNS, S_CONVEX, S_FLAT, S_GEOM, S_RBOUND, S_STATIC, S_TYPE,
)
from softproxy.compiled.shapes import (
    shape_distance, shape_on_face, shape_sweep, shape_tables, shape_to_local, shape_to_world,
)
from softproxy.geometry import CONTACT_TOL, FACE_PARALLEL, GRAZE, MAX_ADVANCE_STEPS, shapes_of

PRIMITIVES = [
    'type="sphere" size=".03"',
    'type="capsule" size=".02 .03"',
    'type="ellipsoid" size=".04 .025 .015"',
    'type="ellipsoid" size=".02 .02 .02"',
    'type="ellipsoid" size=".03 .01 .01"',
    'type="cylinder" size=".03 .02"',
    'type="box" size=".04 .03 .02"',
    'type="box" size=".05 .04 .0005"',   # a thin plate
]

SCENE = (
    "<mujoco><worldbody>"
    '<geom type="plane" size="1 1 .1" pos="0 0 -.5"/>'
    '<geom type="plane" size="1 1 .1" pos=".1 .2 .3" euler="20 -35 50"/>'
    + "".join(f'<geom {g} pos="{0.2 * i:.1f} -.3 .1" euler="{10 * i} {25 - 7 * i} {40 + 3 * i}"/>'
              for i, g in enumerate(PRIMITIVES))
    + '<geom name="upright" type="box" size=".02 .02 .02" pos="0 0 .8"/>'   # identity rotation: exact ties
    + '<body mocap="true"><geom type="plane" size="1 1 .1"/></body>'
    + "".join(f'<body pos="{0.2 * i:.1f} .3 0"><freejoint/><geom {g}/></body>' for i, g in enumerate(PRIMITIVES))
    + "</worldbody></mujoco>"
)


@pytest.fixture(scope="module")
def scene():
    m = mujoco.MjModel.from_xml_string(SCENE)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    shapes = shapes_of(m, d)
    S, T, C = shape_tables(shapes)
    assert T.shape[0] == 0  # primitives only: empty mesh tables
    return m, d, shapes, S


NO_MESH = shape_tables([])[1:]
"""The (empty) mesh tables T and C every shape query takes along."""


def pose(scene, seed):
    """Put every free body and the mocap plane at a random pose; refresh the Python shapes."""
    m, d, shapes, _ = scene
    rng = np.random.default_rng(seed)
    for j in range(m.njnt):
        a = m.jnt_qposadr[j]
        d.qpos[a:a + 3] = rng.uniform(-0.5, 0.5, 3)
        q = rng.normal(size=4)
        d.qpos[a + 3:a + 7] = q / np.linalg.norm(q)
    d.mocap_pos[0] = rng.uniform(-0.5, 0.5, 3)
    q = rng.normal(size=4)
    d.mocap_quat[0] = q / np.linalg.norm(q)
    mujoco.mj_forward(m, d)
    for s in shapes:
        s.refresh()


def bits(values):
    """The exact bit patterns of a tuple of floats (so -0.0 ≠ 0.0 and NaN == NaN)."""
    return tuple(struct.pack("<d", float(v)) for v in values)


def outcome(fn, *args):
    """fn(*args) as bit patterns, or the exception type it raised."""
    try:
        return bits(fn(*args))
    except ArithmeticError as e:
        return type(e)


def sizes(S, k):
    """A length scale per local axis of shape k (m): points are drawn in units of it."""
    t = int(S[k, S_TYPE])
    if t == GEOM_PLANE:
        return (0.1, 0.1, 0.1)
    if t == GEOM_SPHERE:
        return (S[k, S_A],) * 3
    if t in (GEOM_CAPSULE, GEOM_CYLINDER):
        return (S[k, S_A], S[k, S_A], S[k, S_B] + (S[k, S_A] if t == GEOM_CAPSULE else 0.0))
    return (S[k, S_A], S[k, S_B], S[k, S_C])


def world_point(scene, k, u):
    """The world point at local coordinates u (in units of `sizes`) of shape k."""
    m, d, _, S = scene
    h = sizes(S, k)
    return shape_to_world(S, d.geom_xpos, d.geom_xmat, k, u[0] * h[0], u[1] * h[1], u[2] * h[2])


seeds = st.integers(0, 2**32 - 1)
unit = st.one_of(st.floats(-1.5, 1.5), st.sampled_from([0.0, -0.0, 1.0, -1.0, 0.5, 1e-300]))
local = st.tuples(unit, unit, unit)
scales = st.sampled_from([0.0, 1e-12, 0.3, 1.0, 1.0 + 1e-12, 1.5, 3.0, 1e3])
radii = st.sampled_from([0.0, 1e-9, 0.001953125, 0.005, 0.02])
EXAMPLES = settings(max_examples=120, deadline=None)


def check_distance(scene, k, x, y, z):
    """The Python and compiled distance of shape k at (x, y, z) agree bit for bit."""
    _, d, shapes, S = scene
    x, y, z = float(x), float(y), float(z)
    py = outcome(shapes[k].distance, x, y, z)
    nb = outcome(shape_distance, S, *NO_MESH, d.geom_xpos, d.geom_xmat, k, x, y, z)
    assert nb == py, (shapes[k].name, x, y, z)


@EXAMPLES
@given(seeds, st.lists(st.tuples(local, scales), min_size=1, max_size=4))
def test_distance_is_bit_identical(scene, seed, points):
    """shape_distance equals Shape.distance exactly: outside, inside, on the surface, centre, far."""
    pose(scene, seed)
    _, d, shapes, S = scene
    for k in range(len(shapes)):
        g = int(S[k, S_GEOM])
        check_distance(scene, k, *(float(v) for v in d.geom_xpos[g]))   # the centre
        for u, s in points:
            x, y, z = world_point(scene, k, (u[0] * s, u[1] * s, u[2] * s))
            check_distance(scene, k, x, y, z)
            dist, nx, ny, nz = shapes[k].distance(x, y, z)
            check_distance(scene, k, x - dist * nx, y - dist * ny, z - dist * nz)  # on the surface


def check_sweep(scene, k, x0, y0, z0, dx, dy, dz, r):
    """The Python and compiled sweep of shape k agree bit for bit (None as lam = -1)."""
    _, d, shapes, S = scene
    x0, y0, z0, dx, dy, dz, r = (float(v) for v in (x0, y0, z0, dx, dy, dz, r))
    try:
        hit = shapes[k].sweep(x0, y0, z0, dx, dy, dz, r)
        py = bits((-1.0, 0.0, 0.0, 0.0) if hit is None else hit)
    except ArithmeticError as e:
        py = type(e)
    nb = outcome(shape_sweep, S, *NO_MESH, d.geom_xpos, d.geom_xmat, k, x0, y0, z0, dx, dy, dz, r)
    assert nb == py, (shapes[k].name, x0, y0, z0, dx, dy, dz, r)
    return hit if not isinstance(py, type) else None


@EXAMPLES
@given(seeds, local, st.sampled_from([0.3, 1.0, 2.0, 3.0]), st.tuples(unit, unit, unit),
       st.sampled_from([0.0, 1e-6, 0.1, 1.0, 3.0, 100.0]), radii,
       st.sampled_from([0.0, 1e-12, 1e-10, 1e-9, 1e-8, 1e-3, 0.3]))
def test_sweep_is_bit_identical(scene, seed, u, s, v, length, r, inward):
    """shape_sweep equals Shape.sweep exactly: free, in contact, tangent, grazing, through plates, zero-length."""
    pose(scene, seed)
    _, d, shapes, S = scene
    hits = 0
    for k in range(len(shapes)):
        h = sizes(S, k)
        x0, y0, z0 = world_point(scene, k, (u[0] * s, u[1] * s, u[2] * s))
        lx, ly, lz = v[0] * h[0] * length, v[1] * h[1] * length, v[2] * h[2] * length
        dx, dy, dz = shape_to_world(S, d.geom_xpos, d.geom_xmat, k, lx, ly, lz)
        g = int(S[k, S_GEOM])
        dx, dy, dz = dx - d.geom_xpos[g, 0], dy - d.geom_xpos[g, 1], dz - d.geom_xpos[g, 2]
        hits += check_sweep(scene, k, x0, y0, z0, dx, dy, dz, r) is not None   # free segment
        check_sweep(scene, k, x0, y0, z0, 0.0, 0.0, 0.0, r)                     # zero length
        g0 = (float(d.geom_xpos[g, 0]), float(d.geom_xpos[g, 1]), float(d.geom_xpos[g, 2]))
        hits += check_sweep(scene, k, x0, y0, z0, *((c - p) * 2.0 for c, p in zip(g0, (x0, y0, z0))), r) is not None
        # start touching: the sphere's centre r off the surface point nearest x0
        dist, nx, ny, nz = shapes[k].distance(x0, y0, z0)
        tx, ty, tz = x0 + (r - dist) * nx, y0 + (r - dist) * ny, z0 + (r - dist) * nz
        # a tangent direction (n × v, or n × a fixed axis), then tilted into the surface by `inward`
        cx, cy, cz = ny * dz - nz * dy, nz * dx - nx * dz, nx * dy - ny * dx
        if cx * cx + cy * cy + cz * cz < 1e-30:
            cx, cy, cz = ny * 0.6 - nz * 0.8, nz * 0.0 - nx * 0.6, nx * 0.8 - ny * 0.0
        for a, b, c in ((cx, cy, cz), (cx - inward * nx, cy - inward * ny, cz - inward * nz),
                        (cx + inward * nx, cy + inward * ny, cz + inward * nz), (-nx, -ny, -nz)):
            check_sweep(scene, k, tx, ty, tz, a, b, c, r)
            check_sweep(scene, k, tx, ty, tz, a * 1e-3, b * 1e-3, c * 1e-3, r)
        # straight through along every local axis, from outside to the far side
        for axis in range(3):
            e = [0.0, 0.0, 0.0]
            e[axis] = 3.0 * h[axis] + r
            ax, ay, az = shape_to_world(S, d.geom_xpos, d.geom_xmat, k, e[0], e[1], e[2])
            ex, ey, ez = ax - g0[0], ay - g0[1], az - g0[2]
            ox, oy, oz = (u[0] * h[0] * 0.5, u[1] * h[1] * 0.5, u[2] * h[2] * 0.5)
            sx, sy, sz = shape_to_world(S, d.geom_xpos, d.geom_xmat, k, ox, oy, oz)
            sx, sy, sz = sx - g0[0], sy - g0[1], sz - g0[2]
            hits += check_sweep(scene, k, g0[0] + sx + ex, g0[1] + sy + ey, g0[2] + sz + ez,
                                -2.0 * ex, -2.0 * ey, -2.0 * ez, r) is not None
    assert hits > 0


def test_sweep_through_a_thin_plate_and_grazing_by_hand(scene):
    """Hand-picked sweeps agree bit for bit: a fast crossing of the thin plate, grazes near GRAZE, exact ties at
    CONTACT_TOL, GRAZE and FACE_PARALLEL, and 1e8 m segments that run out of MAX_ADVANCE_STEPS."""
    pose(scene, 1)
    _, d, shapes, S = scene
    plates = [k for k in range(len(shapes)) if int(S[k, S_TYPE]) == GEOM_BOX and S[k, S_C] < 0.001]
    assert plates
    for k in plates:
        for r in (0.0, 0.001953125):
            top = shape_to_world(S, d.geom_xpos, d.geom_xmat, k, 0.01, -0.02, 0.5)
            bottom = shape_to_world(S, d.geom_xpos, d.geom_xmat, k, 0.01, -0.02, -0.5)
            hit = check_sweep(scene, k, *top, *(b - t for b, t in zip(bottom, top)), r)
            assert hit is not None and 0.0 < hit[0] < 0.5
    for k in range(len(shapes)):
        x0, y0, z0 = world_point(scene, k, (0.2, 0.1, 1.2))
        dist, nx, ny, nz = shapes[k].distance(x0, y0, z0)
        cx, cy, cz = ny * 0.6 - nz * 0.8, nz * 0.0 - nx * 0.6, nx * 0.8 - ny * 0.0
        for f in (0.5, 1.0, 1.0 + 1e-7, 2.0, 1e3):
            e = GRAZE * f
            check_sweep(scene, k, x0, y0, z0, cx - e * nx, cy - e * ny, cz - e * nz, 0.0)
            check_sweep(scene, k, x0 - (dist - 1e-3) * nx, y0 - (dist - 1e-3) * ny, z0 - (dist - 1e-3) * nz,
                        cx - e * nx, cy - e * ny, cz - e * nz, 1e-3)
    # a gap of exactly CONTACT_TOL is contact (`<=`): 2.5e-9 m out, d - (d - 1e-9) is exact
    exact = 0
    for k in range(len(shapes)):
        g0 = [float(c) for c in d.geom_xpos[int(S[k, S_GEOM])]]
        for u in ((0.3, 0.2, 1.7), (2.0, -0.4, 0.1), (-1.1, 1.3, -0.9)):
            x0, y0, z0 = world_point(scene, k, u)
            dist, nx, ny, nz = shapes[k].distance(x0, y0, z0)
            x0, y0, z0 = x0 + (2.5e-9 - dist) * nx, y0 + (2.5e-9 - dist) * ny, z0 + (2.5e-9 - dist) * nz
            dist, nx, ny, nz = shapes[k].distance(x0, y0, z0)
            r = dist - CONTACT_TOL
            if dist - r == CONTACT_TOL:
                exact += 1
                hit = check_sweep(scene, k, x0, y0, z0, -nx * 0.01, -ny * 0.01, -nz * 0.01, r)
                assert hit is not None and hit[0] == 0.0
                check_sweep(scene, k, x0, y0, z0, g0[0] - x0, g0[1] - y0, g0[2] - z0, r)
    assert exact >= len(shapes)
    # exact ties at GRAZE and FACE_PARALLEL on the unrotated box: its normals are exact axes
    k = next(k for k, s in enumerate(shapes) if s.name == "upright")
    assert shapes[k].on_face(FACE_PARALLEL, 0.0, 0.0) is False
    assert shape_on_face(S, d.geom_xmat, k, FACE_PARALLEL, 0.0, 0.0) is False
    assert shape_on_face(S, d.geom_xmat, k, 0.0, -math.nextafter(FACE_PARALLEL, 1.0), 0.0) is True
    x0 = (0.02, 0.0, 0.8)   # on the +x face
    assert check_sweep(scene, k, *x0, -GRAZE, 1.0, 0.0, 0.0) is None                   # approach == graze
    assert check_sweep(scene, k, *x0, -math.nextafter(GRAZE, 1.0), 1.0, 0.0, 0.0) == (0.0, 1.0, 0.0, 0.0)
    # segments of 1e8 m: lam stops moving (gap / approach below its ulp) and the loop runs out
    exhausted = 0
    for k in range(len(shapes)):
        if int(S[k, S_TYPE]) == GEOM_PLANE:
            continue
        g = int(S[k, S_GEOM])
        gx, gy, gz = (float(c) for c in d.geom_xpos[g])
        for length in (5e7, 6.8e7, 9.2e7, 1.26e8, 2.4e8):
            for y in (0.0, 0.005, 0.01):
                args = (gx - length / 2, gy + y, gz + 0.001, length, 0.0, 0.0, 0.001)
                check_sweep(scene, k, *args)
                calls = []
                counting = type("Counting", (), {"distance": staticmethod(
                    lambda *p, s=shapes[k]: calls.append(p) or s.distance(*p))})()
                type(shapes[k]).sweep(counting, *args)
                exhausted += len(calls) == MAX_ADVANCE_STEPS
    assert exhausted > 0


@EXAMPLES
@given(seeds, st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)),
       st.sampled_from([0.0, 1e-13, 1e-12, 2e-12, 1e-6, 1e-3, 1.0]))
def test_on_face_is_bit_identical(scene, seed, v, tilt):
    """shape_on_face equals Shape.on_face for face normals, tilted face normals, edge normals, random unit vectors."""
    pose(scene, seed)
    _, d, shapes, S = scene
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    normals = [(v[0] / n, v[1] / n, v[2] / n)] if n > 0.0 else []
    for k in range(len(shapes)):
        g = int(S[k, S_GEOM])
        R = d.geom_xmat[g].reshape(3, 3)
        axes = [tuple(float(c) for c in R[:, i]) for i in range(3)]
        faces = []
        for i in range(3):
            a, b = axes[i], axes[(i + 1) % 3]
            for sign in (1.0, -1.0):
                faces.append(tuple(sign * c for c in a))
                t = [sign * ca + tilt * cb for ca, cb in zip(a, b)]
                tn = math.sqrt(sum(c * c for c in t))
                faces.append(tuple(c / tn for c in t))
            e = [ca + cb for ca, cb in zip(a, b)]
            en = math.sqrt(sum(c * c for c in e))
            faces.append(tuple(c / en for c in e))
        corner = [sum(col) for col in zip(*axes)]
        cn = math.sqrt(sum(c * c for c in corner))
        faces.append(tuple(c / cn for c in corner))
        for nx, ny, nz in normals + faces:
            py = shapes[k].on_face(nx, ny, nz)
            nb = shape_on_face(S, d.geom_xmat, k, nx, ny, nz)
            assert type(nb) is bool and nb == py, (shapes[k].name, nx, ny, nz)


@EXAMPLES
@given(seeds, st.tuples(st.floats(-2, 2), st.floats(-2, 2), st.floats(-2, 2)))
def test_to_local_and_to_world(scene, seed, p):
    """shape_to_local equals Shape.to_local exactly; shape_to_world is its written formula and inverts it to rounding."""
    pose(scene, seed)
    _, d, shapes, S = scene
    for k, s in enumerate(shapes):
        local = shape_to_local(S, d.geom_xpos, d.geom_xmat, k, *p)
        assert bits(local) == bits(s.to_local(*p))
        lx, ly, lz = local
        back = shape_to_world(S, d.geom_xpos, d.geom_xmat, k, lx, ly, lz)
        assert bits(back) == bits((s.r00 * lx + s.r01 * ly + s.r02 * lz + s.px,
                                   s.r10 * lx + s.r11 * ly + s.r12 * lz + s.py,
                                   s.r20 * lx + s.r21 * ly + s.r22 * lz + s.pz))
        assert np.allclose(back, p, rtol=0.0, atol=1e-14)


def test_shape_table_columns(scene):
    """shape_tables hold each shape's type, geom, body, flags, bound and sizes."""
    m, _, shapes, S = scene
    assert S.shape == (len(shapes), S_COLUMNS) and S.dtype == np.float64
    kinds = {"PlaneShape": GEOM_PLANE, "SphereShape": GEOM_SPHERE, "CapsuleShape": GEOM_CAPSULE,
             "EllipsoidShape": GEOM_ELLIPSOID, "CylinderShape": GEOM_CYLINDER, "BoxShape": GEOM_BOX}
    for k, s in enumerate(shapes):
        assert S[k, S_TYPE] == kinds[type(s).__name__] == m.geom_type[s.geom]
        assert (S[k, S_GEOM], S[k, S_BODY], S[k, S_RBOUND]) == (s.geom, s.body, s.rbound)
        assert (S[k, S_STATIC], S[k, S_CONVEX], S[k, S_FLAT]) == (float(s.static), 1.0, float(s.flat))
        size = m.geom_size[s.geom]
        want = {GEOM_PLANE: (0.0, 0.0, 0.0), GEOM_SPHERE: (size[0], 0.0, 0.0),
                GEOM_CAPSULE: (size[0], size[1], 0.0), GEOM_CYLINDER: (size[0], size[1], 0.0)}.get(
            int(S[k, S_TYPE]), tuple(size))
        assert tuple(S[k, [S_A, S_B, S_C]]) == tuple(want)
    assert S[:, S_STATIC].sum() == 3 + len(PRIMITIVES)


def test_shape_tables_reject_a_shape_they_do_not_know():
    """A Shape subclass (which may answer differently from its compiled twin) is refused
    with an error naming it; the same world without it packs."""
    from softproxy.geometry import SphereShape

    class PaddedSphere(SphereShape):
        pass

    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/>'
                                       '<geom name="padded" type="sphere" size=".02"/></worldbody></mujoco>')
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    shapes = shapes_of(m, d)
    with pytest.raises(ValueError, match="'padded' \\(PaddedSphere\\)"):
        shape_tables(shapes[:1] + [PaddedSphere(m, d, 1, True)])
    assert shape_tables(shapes)[0].shape == (2, S_COLUMNS)
