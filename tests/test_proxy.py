"""The 3-DOF god-object against MuJoCo primitives: never inside, reaches free targets, friction."""

import math
from pathlib import Path

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from softproxy.geometry import shapes_of
from softproxy.mesh import MeshShape
from softproxy import proxy as proxy_module
from softproxy.proxy import GodObject

TOL = 1e-6  # the promise: never more than 1 µm inside anything


def world(body_xml: str):
    xml = f"<mujoco><worldbody>{body_xml}</worldbody></mujoco>"
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, shapes_of(m, d)


def deepest(god):
    return max(god.radius - s.distance(god.x, god.y, god.z)[0] for s in god.shapes)


GEOMS = {
    "box": 'type="box" size=".04 .03 .02"',
    "sphere": 'type="sphere" size=".03"',
    "capsule": 'type="capsule" size=".02 .03"',
    "cylinder": 'type="cylinder" size=".03 .02"',
    "ellipsoid": 'type="ellipsoid" size=".04 .025 .015"',
}

coord = st.floats(-0.08, 0.08)
point = st.tuples(coord, coord, coord)


@settings(max_examples=60, deadline=None)
@given(
    st.sampled_from(sorted(GEOMS)),
    st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)).filter(lambda q: sum(v * v for v in q) > 0.1),
    st.floats(0.0, 0.01),
    st.lists(point, min_size=2, max_size=25),
    st.floats(0.0, 1.0),
)
def test_never_inside_any_primitive(kind, quat, radius, path, mu):
    """Random shape, pose, proxy radius, friction and device path: the proxy stays outside (< 1e-6 m)."""
    q = np.array(quat) / np.linalg.norm(quat)
    m, d, shapes = world(f'<geom {GEOMS[kind]} quat="{q[0]} {q[1]} {q[2]} {q[3]}"/>')
    god = GodObject(shapes, radius, mu, 0.8 * mu, (0.0, 0.0, 0.2))
    for p in path:
        god.update(*p)
        assert deepest(god) <= TOL


@settings(max_examples=40, deadline=None)
@given(st.sampled_from(sorted(GEOMS)), point, st.floats(0.0, 0.01))
def test_reaches_device_outside_objects(kind, target, radius):
    """With the device outside every object (by the proxy radius) the proxy goes to it."""
    m, d, shapes = world(f'<geom {GEOMS[kind]}/>')
    if shapes[0].distance(*target)[0] < radius + 1e-4:
        return
    # approach along the ray from the shape's centre: for a convex shape it never crosses it
    n = math.sqrt(sum(v * v for v in target))
    god = GodObject(shapes, radius, 0.0, 0.0, tuple(0.3 * v / n for v in target))
    god.update(*target)
    assert not god.contact
    assert math.dist((god.x, god.y, god.z), target) < 1e-9


@pytest.mark.parametrize("speed", [1.0, 10.0, 100.0])
def test_thin_plate_never_popped_through(speed):
    """A 1 mm plate crossed at up to 100 m/s at 1 kHz (10 cm per tick): the proxy stays on the near side."""
    m, d, shapes = world('<geom type="box" size=".05 .05 .0005"/>')
    for radius in (0.0, 0.005):
        god = GodObject(shapes, radius, 0.5, 0.4, (0.0, 0.0, 0.01))
        step = speed * 1e-3
        z = 0.01
        for _ in range(40):
            z -= step
            god.update(0.001, 0.0, z)
            assert god.z >= 0.0005 + radius - TOL
            assert deepest(god) <= TOL
        assert god.contact


def test_convex_corner_holds_on_the_rounded_corner():
    """Pushing diagonally into a box corner: a sphere proxy rests on the corner, force along the diagonal."""
    m, d, shapes = world('<geom type="box" size=".05 .05 .05"/>')
    r = 0.005
    god = GodObject(shapes, r, 0.0, 0.0, (0.1, 0.1, 0.1))
    for depth in (0.01, 0.02):
        god.update(*(0.05 - depth,) * 3)
        expected = 0.05 + r / math.sqrt(3)
        assert (god.x, god.y, god.z) == pytest.approx((expected,) * 3, abs=1e-8)
        assert (god.nx, god.ny, god.nz) == pytest.approx((1 / math.sqrt(3),) * 3, abs=1e-9)


def test_concave_corner_is_three_planes():
    """Into the corner of a room (floor and two walls): three constraint planes solved in one tick."""
    walls = ('<geom type="plane" size="1 1 .1"/>'
             '<geom type="box" pos="0.1 0 0.1" size=".1 .3 .1"/>'
             '<geom type="box" pos="0 0.1 0.1" size=".3 .1 .1"/>')
    m, d, shapes = world(walls)
    r = 0.005
    god = GodObject(shapes, r, 0.0, 0.0, (-0.05, -0.05, 0.05))
    god.update(0.02, 0.03, -0.01)  # one tick, from free space deep into the corner
    assert (god.x, god.y, god.z) == pytest.approx((-r, -r, r), abs=1e-8)
    assert len(god.planes) == 3
    # the force k(x_p - x_d) points out of all three surfaces
    assert god.x - 0.02 < 0 and god.y - 0.03 < 0 and god.z + 0.01 > 0
    assert deepest(god) <= TOL


def test_concave_crease_two_boxes():
    """Device pushed into the crease between a floor and a wall: proxy sits in the crease, on both."""
    m, d, shapes = world('<geom type="plane" size="1 1 .1"/><geom type="box" pos="0.1 0 0" size=".1 .1 .1"/>')
    r = 0.005
    god = GodObject(shapes, r, 0.0, 0.0, (-0.05, 0.0, 0.05))
    god.update(0.01, 0.0, -0.01)
    assert god.x == pytest.approx(-r, abs=1e-8) and god.z == pytest.approx(r, abs=1e-8)
    assert god.contact and len(god.planes) == 2


@pytest.mark.parametrize("mu_s", [0.0, 0.3, 1.0])
def test_static_friction_holds_below_cone_and_releases_above(mu_s):
    """Tangential push below μ_s·depth keeps the proxy put; above it the proxy slides (μ = 0 slides freely)."""
    m, d, shapes = world('<geom type="plane" size="1 1 .1"/>')
    god = GodObject(shapes, 0.0, mu_s, 0.5 * mu_s, (0.0, 0.0, 0.01))
    god.update(0.0, 0.0, -0.01)  # press 1 cm in
    assert god.contact and god.x == 0.0
    depth = 0.01
    god.update(0.9 * mu_s * depth, 0.0, -0.01)
    if mu_s > 0:
        assert god.sticking and god.x == pytest.approx(0.0, abs=1e-12)
    god.update(1.2 * mu_s * depth + 1e-4, 0.0, -0.01)
    assert not god.sticking
    # sliding: the proxy trails the device by μ_d·depth (dynamic cone edge)
    assert god.x == pytest.approx(1.2 * mu_s * depth + 1e-4 - 0.5 * mu_s * depth, abs=1e-9)
    assert god.z == pytest.approx(0.0, abs=1e-8)


def test_nan_device_leaves_proxy_in_place():
    m, d, shapes = world('<geom type="plane" size="1 1 .1"/>')
    god = GodObject(shapes, 0.0, 0.0, 0.0, (0.0, 0.0, 0.01))
    god.update(0.0, 0.0, -0.01)
    before = (god.x, god.y, god.z)
    for bad in (math.nan, math.inf, -math.inf, 1e300):
        assert god.update(bad, 0.0, 0.0) is False
        assert (god.x, god.y, god.z) == before


def test_moving_object_carries_and_pushes_out():
    """The proxy is held in the touched body's frame; a body moving into a free proxy pushes it out."""
    m, d, _ = world('<body name="b" mocap="true"><geom type="box" size=".05 .05 .05"/></body>')
    shapes = shapes_of(m, d)
    god = GodObject(shapes, 0.0, 1.0, 0.8, (0.0, 0.0, 0.1))
    god.update(0.0, 0.0, 0.04)
    assert god.z == pytest.approx(0.05)
    d.mocap_pos[0] = (0.01, 0.0, 0.0)  # slide the box sideways: the stuck proxy goes along
    mujoco.mj_forward(m, d)
    shapes[0].refresh()
    god.update(0.0, 0.0, 0.04)
    assert god.x == pytest.approx(0.01, abs=1e-9) or not god.sticking
    god.reset(0.0, 0.0, 0.06)  # free proxy just above the box top
    d.mocap_pos[0] = (0.0, 0.0, 0.02)  # box rises 2 cm into it
    mujoco.mj_forward(m, d)
    shapes[0].refresh()
    god.update(0.0, 0.0, 0.2)
    assert deepest(god) <= TOL


def test_bad_parameters():
    m, d, shapes = world('<geom type="plane" size="1 1 .1"/>')
    with pytest.raises(ValueError, match="radius"):
        GodObject(shapes, -0.01)
    with pytest.raises(ValueError, match="mu_d"):
        GodObject(shapes, 0.01, 0.2, 0.5)


def test_unsupported_geom_is_named():
    xml = '<mujoco><asset><hfield name="h" nrow="3" ncol="3" size="1 1 .1 .1"/></asset><worldbody><geom name="terrain" type="hfield" hfield="h"/></worldbody></mujoco>'
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    with pytest.raises(ValueError, match="terrain.*hfield"):
        shapes_of(m, d)


class _ColdGodObject(GodObject):
    """The same solver with no warm start: every tick's planes are found from scratch."""

    __slots__ = ()

    def _solve(self, x, y, z, gx, gy, gz):
        return self._move(x, y, z, gx, gy, gz)


class _UnhurriedGodObject(GodObject):
    """The same solver without the hold fast path (`_still_stuck`) and with the friction
    slide always swept again from the first contact point."""

    __slots__ = ()

    def _move(self, x, y, z, gx, gy, gz, warm=None):
        return GodObject._move(self, x, y, z, gx, gy, gz, warm)[:4] + (False,)

    def _still_stuck(self, xd, yd, zd):
        return False


SCENERY = (
    '<geom type="plane" size="1 1 .01"/>'
    '<geom type="box" size=".03 .03 .03" pos="-.03 0 .03" quat="0.9659 0 0 0.2588"/>'
    '<geom type="box" size=".05 .02 .04" pos="0 -.05 .04"/>'
)


CURVED = (  # apart: no crease of two curved surfaces, where the solver converges to ~1e-5 m
    '<geom type="sphere" size=".03" pos="-.03 0 0"/>'
    '<geom type="capsule" size=".015 .03" pos=".04 .01 0" quat="0.7071 0.7071 0 0"/>'
)


def _in_small_steps(god, path):
    """Device positions: each point of `path` reached in five steps from wherever `god`'s
    proxy is then, so faces are held and slid on, not only jumped at."""
    for p in path:
        sx, sy, sz = god.x, god.y, god.z
        for k in range(1, 6):
            yield tuple(a + (b - a) * k / 5 for a, b in zip((sx, sy, sz), p))


# Derandomized: the same examples on every run. In a crease of a face and a box's rounded
# edge the solver converges within MAX_ITERATIONS to ~1e-5 m, and a warm start, one sweep
# ahead, can end there differently (seen once in 1500 random examples): a known limit of
# the iteration, not of the shortcuts these tests check. Positions agree within TOL: a
# proxy may sit up to LIFT_TOL (1e-7 m) off a surface it slides on.
@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(-0.06, 0.06), st.floats(-0.06, 0.06), st.floats(-0.02, 0.08)),
                min_size=2, max_size=30), st.floats(0.0, 1.0), st.floats(0.001, 0.01))
@pytest.mark.parametrize("scenery", [SCENERY, CURVED], ids=["planar", "curved"])
@pytest.mark.parametrize("reference", [_ColdGodObject, _UnhurriedGodObject], ids=["cold", "unhurried"])
def test_shortcuts_end_where_the_full_solve_ends(reference, scenery, path, mu, radius):
    """The solver's shortcuts end where solving without them ends, with the same force
    direction and depth, on faces, creases, corners, past edges and on curved shapes, and
    never inside: starting from last tick's planes (`_solve`: faces' planes as they were,
    convex shapes' tangent planes under the proxy now; against a cold solve);
    the hold on a face and in a corner (`_still_stuck`) and the friction slide kept on the
    segment already swept (against the unhurried solver)."""
    _, _, shapes = world(scenery)
    fast = GodObject(shapes, radius, mu, 0.8 * mu, (0.02, 0.02, 0.1))
    slow = reference(shapes, radius, mu, 0.8 * mu, (0.02, 0.02, 0.1))
    for q in _in_small_steps(fast, path):
        fast.update(*q)
        slow.update(*q)
        assert deepest(fast) <= TOL
        assert math.dist((fast.x, fast.y, fast.z), (slow.x, slow.y, slow.z)) < TOL
        # a device within 1e-12 m of the proxy moves nothing: contact or not is then rounding
        assert fast.contact == slow.contact or max(fast.depth, slow.depth) <= 1e-12
        if fast.contact:  # the force the finger feels: depth along n
            assert fast.depth == pytest.approx(slow.depth, abs=TOL)
            if slow.depth > 1e-4:
                assert math.dist((fast.nx, fast.ny, fast.nz), (slow.nx, slow.ny, slow.nz)) < 1e-3


def test_hold_in_a_corner_takes_the_fast_path():
    """A device wiggling inside a concave three-face corner keeps the proxy pinned at the
    corner through `_still_in_corner`, with the force along the device's offset."""
    _, _, shapes = world('<geom type="plane" size="1 1 .01"/>'
                         '<geom type="box" size=".05 .2 .1" pos="-.05 0 .1"/>'
                         '<geom type="box" size=".2 .05 .1" pos="0 -.05 .1"/>')
    god = GodObject(shapes, 0.005, 0.0, 0.0, (0.03, 0.03, 0.03))
    god.update(0.0, 0.0, 0.003)
    assert len(god.planes) == 3 and god.x == pytest.approx(0.005, abs=1e-9)
    taken = 0
    for i in range(50):
        xd, yd, zd = 0.002 * math.sin(i * 0.3), 0.002 * math.cos(i * 0.3), 0.003
        taken += god._still_in_corner(xd, yd, zd)  # what update is about to find
        god.update(xd, yd, zd)
        assert (god.x, god.y, god.z) == pytest.approx((0.005, 0.005, 0.005), abs=1e-9)
        d = math.dist((god.x, god.y, god.z), (xd, yd, zd))
        assert god.depth == pytest.approx(d, abs=1e-12)
        assert god.nx == pytest.approx((god.x - xd) / d, abs=1e-9)
    assert taken == 50


def test_warm_start_leaves_a_face_past_its_edge():
    """A proxy slid along a box's top past its edge drops around the edge toward the device
    instead of floating on the face's extended plane."""
    _, _, shapes = world('<geom type="box" size=".02 .02 .02"/>')
    god = GodObject(shapes, 0.005, 0.0, 0.0, (0.0, 0.0, 0.05))
    god.update(0.0, 0.0, 0.023)
    assert god.contact and god.z == pytest.approx(0.025, abs=1e-9)
    for k in range(1, 41):
        god.update(0.001 * k, 0.0, 0.023 - 0.0005 * k)  # out over the +x edge and down
    assert god.x > 0.02 and god.z < 0.02  # around the edge, on the side face
    assert deepest(god) <= TOL


@pytest.mark.parametrize("geom, centre, radius, out, along", [
    ('type="box" size=".02 .02 .02"', lambda q: (0.02, q[1], 0.02), 0.005, (1.0, 0.0, 1.0), 0.0003),  # rounded edge
    ('type="box" size=".02 .02 .02"', lambda q: (0.02, 0.02, 0.02), 0.005, (1.0, 1.0, 1.0), 0.0),  # rounded corner
    ('type="sphere" size=".02"', lambda q: (0.0, 0.0, 0.0), 0.025, (0.0, 0.0, 1.0), 0.0),          # sphere
], ids=["edge", "corner", "sphere"])
def test_a_proxy_pressed_on_a_convex_shape_is_never_swept_against_it(monkeypatch, geom, centre, radius, out, along):
    """Pressed into a rounded edge or corner, or a sphere, harder and softer (and along the
    edge), the proxy starts each tick from its tangent plane there (`_solve`) and moves on or
    above it, where the convex shape cannot be entered (`_sweep`): once it rests on the
    shape, the shape is asked for distances only, never swept. It stays at the point of the
    inflated surface (`radius` from `centre`: the edge's axis, the corner, the sphere's
    centre) nearest the device."""
    _, _, shapes = world(f"<geom {geom}/>")
    cls = type(shapes[0])
    swept = []
    sweep = cls.sweep
    monkeypatch.setattr(cls, "sweep", lambda self, *args: swept.append(args) or sweep(self, *args))
    r = 0.005
    norm = math.sqrt(sum(v * v for v in out))
    c0 = centre((0.0, 0.0, 0.0))
    god = GodObject(shapes, r, 0.0, 0.0, tuple(c + radius * v / norm for c, v in zip(c0, out)))
    for i in range(60):
        # 0.5 to 1.5 mm in; along the edge's axis (y) too
        q = tuple(c + (radius - 0.001 - 0.0005 * math.sin(0.2 * i)) * v / norm for c, v in zip(c0, out))
        q = (q[0], q[1] + along * math.sin(0.1 * i), q[2])
        swept.clear()
        god.update(*q)
        assert god.contact and deepest(god) <= TOL
        c = centre(q)
        d = math.dist(q, c)
        exact = tuple(a + radius * (b - a) / d for a, b in zip(c, q))
        assert math.dist((god.x, god.y, god.z), exact) < TOL
        if i >= 2:  # resting on the shape since the tick before
            assert swept == []


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1), st.floats(-0.05, 0.05)),
                min_size=3, max_size=3).filter(lambda ps: all(a * a + b * b + c * c > 0.01 for a, b, c, _ in ps)),
       point)
def test_corner_shortcut_is_the_projection(raw, p):
    """The corner tried first for three planes (`_corner`) is the point the full active-set
    enumeration finds whenever it answers (KKT: on all planes, every multiplier ≥ 0)."""
    planes = []
    for a, b, c, off in raw:
        n = math.sqrt(a * a + b * b + c * c)
        planes.append((a / n, b / n, c / n, off, None))
    corner = proxy_module._corner(*p, planes)
    if corner is None:
        return
    full = proxy_module._project_by_enumeration(*p, planes)
    assert full is not None and math.dist(corner, full) < 1e-9


@pytest.mark.parametrize("mu", [0.0, 0.5])
def test_rolls_round_a_rounded_edge_to_a_free_device(mu):
    """A device moving from a box's edge into the edge's tangent half-space, yet clear of the
    box, is free: the proxy rolls round the rounded edge and reaches it in the same tick,
    with no force, instead of stopping on the edge's tangent plane."""
    _, _, shapes = world('<geom type="box" size=".02 .02 .02"/>')
    r = 0.005
    e = 0.02 + r / math.sqrt(2.0)
    god = GodObject(shapes, r, mu, 0.8 * mu, (e, e, 0.0))
    assert god.shapes[0].distance(e, e, 0.0)[0] == pytest.approx(r, abs=1e-12)  # on the edge
    god.update(0.005, 0.03, 0.0)  # into the edge's tangent plane, 5 mm clear of the +y face
    assert not god.contact
    assert (god.x, god.y, god.z) == pytest.approx((0.005, 0.03, 0.0), abs=1e-9)
    assert deepest(god) <= TOL


def test_creases_of_flat_and_curved_shapes_converge_within_the_sweep_budget(monkeypatch):
    """A device wandering in 4 mm steps round the foot of a sphere resting on a floor (their
    crease, deep inside both): on at least nine ticks in ten the solve's MAX_ITERATIONS
    sweeps end within 1e-6 m of where 200 sweeps end. A plane the proxy lifted off is
    replaced by its shape's tangent plane under the proxy and the floor's plane is kept, so
    the crease is followed along both surfaces at once."""
    _, _, shapes = world('<geom type="plane" size="1 1 .01"/><geom type="sphere" size=".03" pos="0 0 .01"/>'
                         '<geom type="capsule" size=".01 .05" pos=".06 0 0" quat="0.7071 0 0.7071 0"/>'
                         '<geom type="box" size=".02 .02 .02" pos="-.05 .04 .01" quat="0.9659 0 0 0.2588"/>')
    rng = np.random.default_rng(0)
    god = GodObject(shapes, 0.005, 0.0, 0.0, (0.0, -0.05, 0.05))
    budget = proxy_module.MAX_ITERATIONS
    apart = ticks = 0
    device = np.zeros(3)
    for tick in range(1500):
        if tick % 250 == 0:  # somewhere new by the sphere's foot, not counted: a jump is no tick's motion
            a = rng.uniform(0.0, 2.0 * math.pi)
            device = np.array((0.035 * math.cos(a), 0.035 * math.sin(a), 0.0))
        device = device + rng.uniform(-0.004, 0.004, 3)
        device[2] = min(0.02, max(-0.01, device[2]))
        state = (god.x, god.y, god.z, list(god.planes), god.shape, god.lx, god.ly, god.lz, god.sticking, god.contact)
        monkeypatch.setattr(proxy_module, "MAX_ITERATIONS", 200)
        god.update(*device)
        converged = (god.x, god.y, god.z)
        (god.x, god.y, god.z, god.planes, god.shape, god.lx, god.ly, god.lz, god.sticking, god.contact) = state
        monkeypatch.setattr(proxy_module, "MAX_ITERATIONS", budget)
        god.update(*device)
        assert deepest(god) <= TOL
        if tick % 250:
            ticks += 1
            apart += math.dist(converged, (god.x, god.y, god.z)) > 1e-6
    assert apart < 0.1 * ticks  # 5 % here; 20 % when a lifted plane was dropped


class _BallCheckedGodObject(GodObject):
    """Records how far any sweep started or ended outside the ball whose shapes were gathered."""

    __slots__ = ()
    outside = [0.0]

    def _sweep(self, x, y, z, dx, dy, dz, planes=()):
        for px, py, pz in ((x, y, z), (x + dx, y + dy, z + dz)):
            d = math.dist((px, py, pz), (self._bx, self._by, self._bz)) - self._room
            _BallCheckedGodObject.outside[0] = max(_BallCheckedGodObject.outside[0], d)
        return GodObject._sweep(self, x, y, z, dx, dy, dz, planes)


MIXED = SCENERY + ('<geom type="sphere" size=".02" pos=".04 .04 .02"/>'
                   '<geom type="capsule" size=".01 .03" pos="-.04 .05 .02" quat="0.7071 0.7071 0 0"/>'
                   '<geom type="ellipsoid" size=".03 .02 .015" pos=".05 -.04 .02"/>')


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(-0.06, 0.06), st.floats(-0.06, 0.06), st.floats(-0.02, 0.08)),
                min_size=2, max_size=30), st.floats(0.0, 1.0), st.floats(0.001, 0.01))
def test_every_sweep_stays_where_the_shapes_were_gathered(path, mu, radius):
    """The broad phase gathers the shapes near the ball holding the proxy and the device; a
    slide projected onto planes, or round a curved surface, can leave that ball (on ~1 tick
    in 60 of these paths), and then the ball is widened before the sweep: no sweep ever
    starts or ends where a shape may not have been gathered."""
    _, _, shapes = world(MIXED)
    god = _BallCheckedGodObject(shapes, radius, mu, 0.8 * mu, (0.02, 0.02, 0.1))
    _BallCheckedGodObject.outside[0] = 0.0
    for q in _in_small_steps(god, path):
        god.update(*q)
        assert deepest(god) <= TOL
    assert _BallCheckedGodObject.outside[0] <= 1e-12


def test_a_slide_down_a_bowl_meets_the_floor_it_did_not_start_near():
    """A 2 mm proxy on the outside of the mesh bowl, its device jumping to the bowl's centre,
    slides down and round the bowl toward the floor, out of the ball gathered at the start
    of the tick: it stops on the floor, not 3 mm inside it (hypothesis found this)."""
    m = mujoco.MjModel.from_xml_path(str(Path(__file__).parents[1] / "scenes" / "mesh_object.xml"))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    god = GodObject(shapes_of(m, d, mesh_shape=MeshShape), 0.001953125, 0.0, 0.0, (0.0, 0.0, 0.09))
    god.update(0.05, 0.025, 0.0425)
    god.update(0.0, 0.0, 0.03)
    assert deepest(god) <= TOL
