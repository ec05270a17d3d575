"""The shape queries (`Shape.distance/sweep/on_face/to_local`, i.e. `softproxy.compiled.shapes`)
against oracles written here, independently of the kernels.

- Plane, sphere, capsule, cylinder, box: closed-form signed distance, outward normal and
  support function in the geom frame.
- Ellipsoid: the nearest surface point by brute force, without the kernel's Lagrange
  parameter (nor scipy): a dense sampling of the surface A s (s unit vectors), the best few
  samples descended by Newton's method on the sphere of s (along the most negative curvature
  where it is not convex), in spherical coordinates whose pole is on the longest semi-axis
  (a ring of near-nearest points about it, inside an ellipsoid of two equal shortest
  semi-axes, is then a straight valley) and again with the pole on the shortest one (for
  feet near the tips of the longest). Every answer is the distance to a surface point, so
  it is never below the true distance; the kernel's foot (p - d n) is checked to lie on the
  surface too, so the two agree only at the nearest point.
- Sweep: g(λ) = distance(p0 + λ d) - r is convex on a convex shape; its minimum is found by
  dense sampling, refined, and its first root by bisection (vectorised: each step samples
  the bracket densely). The kernel's hit must lie in the contact window before that root
  (never past the surface), and a miss must be one the sphere could not have gone into by
  more than GRAZE per metre of motion (grazing).

Tolerances (m), all far below anything a finger can feel and below the engine's own
CONTACT_TOL (1e-9 m) where a contact decision depends on them:
- DIST_TOL: 1e-12 m + 1e-14 per metre of the point's distance from the geom. The kernels
  take ~10 float64 roundings of coordinates; points here are within 150 m of a geom.
- ELLIPSOID_TOL: 1e-12 m + 1e-13 per metre: the kernel's root finder stops at its rounding
  and the oracle's descent at f's; observed agreement ~3e-17 m, on the mid-planes and axes too.
- NORMAL_TOL: 1e-9 (unit vectors), compared only where the normal is well conditioned
  (the nearest feature is at least WELL_CONDITIONED away, and no tie within TIE; on an
  ellipsoid, where the minimum pins the foot: STIFF); elsewhere (edges, centres, ties) the
  normal must be a supporting-plane normal at the nearest point, which any tied normal is.
A point within UNDERFLOW (1e-140 m) of a geom's centre is taken as the centre (below it the
squares of its offset underflow and no direction is measurable).
"""

import math

import mujoco
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.spatial.transform import Rotation

from softproxy.compiled.layout import (
    GEOM_BOX, GEOM_CAPSULE, GEOM_CYLINDER, GEOM_ELLIPSOID, GEOM_PLANE, GEOM_SPHERE,
)
from softproxy.compiled import shapes as kernels
from softproxy.compiled.shapes import shape_sweep, shape_to_world
from softproxy.compiled.tolerances import CONTACT_TOL, FACE_PARALLEL, GRAZE, MAX_ADVANCE_STEPS
from softproxy.geometry import BoxShape, PlaneShape, Shape, ShapeSet, shapes_of

DIST_TOL, DIST_TOL_PER_M = 1e-12, 1e-14
ELLIPSOID_TOL_PER_M = 1e-13
NORMAL_TOL = 1e-9
WELL_CONDITIONED = 1e-4
"""A normal is compared to the oracle's only when the feature it points from is this far (m):
its rounding is then below 1e-10 for points within 150 m."""
TIE = 1e-9
"""Two faces (or roots) nearer than this (m) to each other are a tie: either normal is right."""
STIFF = 1e-6
"""An ellipsoid oracle's normal is compared only where ½ |A s - p|², as the foot A s moves on
the surface, curves by at least this times the longest semi-axis squared (per rad² of s):
its descent then pins the foot's direction to far below NORMAL_TOL. Elsewhere (near a ring
of near-nearest points about an axis of two equal shortest semi-axes) the direction is only
as good as f's rounding allows."""
CUTS = 2.0 ** -np.arange(60)
"""The lengths a descent step tries, the whole step first: the first that lowers f is taken."""
MAX_TURN = 0.5
"""The longest descent step (rad of θ or φ)."""

PRIMITIVES = [
    ("ball", 'type="sphere" size=".03"'),
    ("pill", 'type="capsule" size=".02 .03"'),
    ("egg", 'type="ellipsoid" size=".04 .025 .015"'),
    ("round_egg", 'type="ellipsoid" size=".02 .02 .02"'),
    ("long_egg", 'type="ellipsoid" size=".03 .01 .01"'),
    ("can", 'type="cylinder" size=".03 .02"'),
    ("brick", 'type="box" size=".04 .03 .02"'),
    ("plate", 'type="box" size=".05 .04 .0005"'),   # a thin plate, 1 mm thick
]
STATIC_POSES = [(f"{0.2 * i:.1f} -.3 .1", f"{10 * i} {25 - 7 * i} {40 + 3 * i}") for i in range(len(PRIMITIVES))]

SCENE = (
    "<mujoco><worldbody>"
    '<geom name="floor" type="plane" size="1 1 .1" pos="0 0 -.5"/>'
    '<geom name="ramp" type="plane" size="1 1 .1" pos=".1 .2 .3" euler="20 -35 50"/>'
    + "".join(f'<geom name="{n}" {g} pos="{p}" euler="{e}"/>' for (n, g), (p, e) in zip(PRIMITIVES, STATIC_POSES))
    + '<geom name="upright" type="box" size=".02 .02 .02" pos="0 0 .8"/>'   # identity rotation: exact ties
    + '<body mocap="true"><geom name="mocap_plane" type="plane" size="1 1 .1"/></body>'
    + "".join(f'<body pos="{0.2 * i:.1f} .3 0"><freejoint/><geom name="free_{n}" {g}/></body>'
              for i, (n, g) in enumerate(PRIMITIVES))
    + "</worldbody></mujoco>"
)


def _world(xml):
    """(model, data, shapes) of an MJCF string, after mj_forward."""
    m = mujoco.MjModel.from_xml_string(xml)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    return m, d, shapes_of(m, d)


@pytest.fixture(scope="module")
def scene():
    return _world(SCENE)


def pose(scene, seed):
    """Every free body and the mocap plane at a random pose (translated ±0.5 m, any rotation)."""
    m, d, _ = scene
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


# -- the oracles, in the geom frame ------------------------------------------------------------

def kind_and_size(scene, shape):
    m, _, _ = scene
    return int(m.geom_type[shape.geom]), np.array(m.geom_size[shape.geom], dtype=float)


def frame(scene, shape):
    """The geom's centre (m) and rotation (columns: its axes in world), as MuJoCo has them."""
    _, d, _ = scene
    return np.array(d.geom_xpos[shape.geom]), np.array(d.geom_xmat[shape.geom]).reshape(3, 3)


def closed_form_sdf(kind, size, P):
    """Signed distance (m) of local points P (N × 3) from a plane, sphere, capsule, cylinder or box."""
    P = np.atleast_2d(P)
    if kind == GEOM_PLANE:
        return P[:, 2].copy()
    if kind == GEOM_SPHERE:
        return np.linalg.norm(P, axis=1) - size[0]
    if kind == GEOM_CAPSULE:
        axis = np.zeros_like(P)
        axis[:, 2] = np.clip(P[:, 2], -size[1], size[1])
        return np.linalg.norm(P - axis, axis=1) - size[0]
    if kind == GEOM_CYLINDER:
        dr = np.hypot(P[:, 0], P[:, 1]) - size[0]
        dz = np.abs(P[:, 2]) - size[1]
        return np.hypot(np.maximum(dr, 0.0), np.maximum(dz, 0.0)) + np.minimum(np.maximum(dr, dz), 0.0)
    if kind == GEOM_BOX:
        q = np.abs(P) - size[:3]
        return np.linalg.norm(np.maximum(q, 0.0), axis=1) + np.minimum(q.max(axis=1), 0.0)
    raise AssertionError(kind)


def closed_form(kind, size, p):
    """(signed distance, outward normal or None when it is ill-conditioned or tied) at local p."""
    x, y, z = p
    d = float(closed_form_sdf(kind, size, p)[0])
    e = np.eye(3)
    if kind == GEOM_PLANE:
        return d, e[2]
    if kind == GEOM_SPHERE:
        n = np.linalg.norm(p)
        return d, (p / n if n >= WELL_CONDITIONED else None)
    if kind == GEOM_CAPSULE:
        v = p - np.array([0.0, 0.0, np.clip(z, -size[1], size[1])])
        n = np.linalg.norm(v)
        return d, (v / n if n >= WELL_CONDITIONED else None)
    if kind == GEOM_CYLINDER:
        rho = math.hypot(x, y)
        dr, dz = rho - size[0], abs(z) - size[1]
        radial = np.array([x / rho, y / rho, 0.0]) if rho >= WELL_CONDITIONED else None
        axial = math.copysign(1.0, z) * e[2] if abs(z) >= WELL_CONDITIONED else None
        if dr > dz + TIE and (dz <= -TIE or d <= 0.0):
            return d, radial          # the side is nearest (inside), or only the side is out
        if dz > dr + TIE and (dr <= -TIE or d <= 0.0):
            return d, axial           # a cap
        if d >= WELL_CONDITIONED and radial is not None:   # outside the rim
            v = max(dr, 0.0) * radial + max(dz, 0.0) * math.copysign(1.0, z) * e[2]
            return d, v / np.linalg.norm(v)
        return d, None
    if kind == GEOM_BOX:
        q = np.abs(p) - size[:3]
        active = [i for i in range(3) if q[i] > -TIE]
        if d > 0.0:
            if len(active) == 1:                       # off one face
                i = active[0]
                return d, (math.copysign(1.0, p[i]) * e[i] if abs(p[i]) >= WELL_CONDITIONED else None)
            if d >= WELL_CONDITIONED:                  # off an edge or a corner
                o = np.sign(p) * np.maximum(q, 0.0)
                return d, o / np.linalg.norm(o)
            return d, None
        i = int(np.argmax(q))
        if all(q[i] > q[j] + TIE for j in range(3) if j != i) and abs(p[i]) >= TIE:
            return d, math.copysign(1.0, p[i]) * e[i]  # the one nearest face from inside
        return d, None
    raise AssertionError(kind)


def fibonacci_sphere(n):
    """n unit vectors spread evenly over the sphere."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = math.pi * (1.0 + 5.0 ** 0.5) * i
    s = np.sqrt(1.0 - z * z)
    return np.stack([s * np.cos(phi), s * np.sin(phi), z], axis=1)


SAMPLES = fibonacci_sphere(4000)
"""Directions that sample an ellipsoid's surface (as A u): ~0.06 rad apart."""


def on_sphere(angles, axes):
    """Unit vectors s at spherical coordinates (θ, φ) (..., 2) with the pole on local axis
    axes[0], and their derivatives: (s, s_θ, s_φ, s_θθ, s_θφ, s_φφ), each (..., 3)."""
    t, f = angles[..., 0], angles[..., 1]
    ct, st, cf, sf = np.cos(t), np.sin(t), np.cos(f), np.sin(f)
    zero = np.zeros_like(t)

    def put(u, v, w):
        out = np.empty(t.shape + (3,))
        out[..., axes[0]], out[..., axes[1]], out[..., axes[2]] = u, v, w
        return out
    s = put(ct, st * cf, st * sf)
    return s, put(-st, ct * cf, ct * sf), put(zero, -st * sf, st * cf), -s, put(zero, -ct * sf, ct * cf), \
        put(zero, -st * cf, -st * sf)


def descend(abc, p, angles, axes, steps=80):
    """Local minima of f = |A s - p|² over the unit vectors s(θ, φ) (pole on axes[0]), from
    each row of `angles` (k × 2): Newton's step where f is convex in (θ, φ), else a step along
    its most negative curvature; at most MAX_TURN, cut by halves until f decreases (a Newton
    step under 1e-6 rad is taken whole: there f's quadratic model holds, and f's changes fall
    below its rounding long before the step's do).
    Returns (s, |A s - p|) at the ends."""
    x = np.array(angles, dtype=float)
    f = ((on_sphere(x, axes)[0] * abc - p) ** 2).sum(-1)
    rows = np.arange(len(x))
    for _ in range(steps):
        s, st, sf, stt, stf, sff = on_sphere(x, axes)
        r = s * abc - p
        at, af = st * abc, sf * abc
        g1, g2 = (r * at).sum(1), (r * af).sum(1)                      # ½ the gradient
        h11 = (at * at).sum(1) + (r * stt * abc).sum(1)                 # ½ the Hessian
        h12 = (at * af).sum(1) + (r * stf * abc).sum(1)
        h22 = (af * af).sum(1) + (r * sff * abc).sum(1)
        least = 0.5 * (h11 + h22) - np.hypot(0.5 * (h11 - h22), h12)
        v1, v2 = h12, least - h11                                       # its eigenvector
        norm = np.hypot(v1, v2)
        flat = norm == 0.0
        c1 = np.where(flat, (h11 <= h22) * 1.0, v1 / np.where(flat, 1.0, norm))
        c2 = np.where(flat, (h11 > h22) * 1.0, v2 / np.where(flat, 1.0, norm))
        convex = least > 0.0
        det = np.where(convex, h11 * h22 - h12 * h12, 1.0)
        down = np.where(c1 * g1 + c2 * g2 > 0.0, -MAX_TURN, MAX_TURN)
        u = np.where(convex, -(h22 * g1 - h12 * g2) / det, down * c1)
        v = np.where(convex, -(h11 * g2 - h12 * g1) / det, down * c2)
        cap = np.minimum(1.0, MAX_TURN / np.maximum(np.hypot(u, v), 1e-300))
        step = np.stack([u * cap, v * cap], 1)
        if np.abs(step).max() < 1e-15:
            break
        trial = x[:, None, :] + CUTS[None, :, None] * step[:, None, :]
        F = ((on_sphere(trial, axes)[0] * abc - p) ** 2).sum(-1)
        lower = F < f[:, None]
        lower[:, 0] |= convex & (np.hypot(*step.T) < 1e-6)   # Newton's own convergence, below f's rounding
        first = np.argmax(lower, axis=1)
        moved = lower.any(axis=1)
        if not moved.any():
            break   # no step lowers f: every start is at a minimum, to f's rounding
        x = np.where(moved[:, None], trial[rows, first], x)
        f = np.where(moved, F[rows, first], f)
    return on_sphere(x, axes)[0], np.sqrt(f)


def polish(abc, p, s, steps=4):
    """Newton's steps on the sphere from s, in an orthonormal tangent basis (no chart's pole,
    which `descend`'s may sit near), while ½ |A s - p|² is convex there: the minimum found to
    f's rounding, pinned to its gradient's. Returns s and the least curvature of that Hessian
    at the end (m² per rad²): how firmly the minimum pins s."""
    least = 0.0
    for _ in range(steps + 1):
        e1 = np.cross(s, [1.0, 0.0, 0.0] if abs(s[0]) < 0.9 else [0.0, 1.0, 0.0])
        e1 /= np.linalg.norm(e1)
        e2 = np.cross(s, e1)
        ar = (s * abc - p) * abc
        radial = float(s @ ar)
        a1, a2 = e1 * abc, e2 * abc
        h = np.array([[a1 @ a1 - radial, a1 @ a2], [a1 @ a2, a2 @ a2 - radial]])
        least = float(np.linalg.eigvalsh(h)[0])
        if least <= 0.0 or _ == steps:
            break
        u, v = np.linalg.solve(h, -np.array([e1 @ ar, e2 @ ar]))
        if math.hypot(u, v) > 1e-6:   # not at a minimum yet: leave it to the descent
            break
        s = s + u * e1 + v * e2
        s /= np.linalg.norm(s)
    return s, least


def ellipsoid_oracle(abc, p, starts=4, subgradient=False):
    """(signed distance, outward normal or None when tied or not pinned) at local p, by brute
    force: the nearest of 4000 surface samples A s, then from the `starts` best well-separated
    samples a descent on the sphere of s (`descend`) in two charts, the pole on the longest
    then on the shortest semi-axis, the nearest end polished (`polish`). `subgradient`: a normal even where it is not unique (one
    nearest point's)."""
    abc = np.asarray(abc[:3], dtype=float)
    p = np.asarray(p, dtype=float)
    far = np.linalg.norm(SAMPLES * abc - p, axis=1)
    chosen = []
    for i in np.argsort(far):
        if all(SAMPLES[i] @ SAMPLES[j] < math.cos(0.3) for j in chosen):
            chosen.append(i)
            if len(chosen) == starts:
                break
    s0 = SAMPLES[chosen]
    ends = []
    order = np.argsort(-abc, kind="stable")
    for axes in (tuple(order), tuple(order[::-1])):
        angles = np.stack([np.arccos(np.clip(s0[:, axes[0]], -1.0, 1.0)),
                           np.arctan2(s0[:, axes[2]], s0[:, axes[1]])], 1)
        s, dist = descend(abc, p, angles, axes)
        ends += list(zip(dist.tolist(), s))
    ends.sort(key=lambda e: e[0])
    d, s = ends[0]
    assert d <= far.min() + 1e-12, "the oracle's descent lost to its own samples"
    s, least = polish(abc, p, s)
    m = s / abc
    m /= np.linalg.norm(m)
    inside = float(((p / abc) ** 2).sum()) < 1.0
    tied = any(e[0] - d <= TIE and np.linalg.norm(e[1] - s) > 1e-6 for e in ends[1:])
    loose = least < STIFF * float(abc.max()) ** 2
    return (-d if inside else d), (None if (tied or loose) and not subgradient else m)


def oracle(kind, size, p):
    """(signed distance, outward normal or None) at local p, m."""
    if kind == GEOM_ELLIPSOID:
        return ellipsoid_oracle(size, p)
    return closed_form(kind, size, p)


def support(kind, size, n):
    """max over the shape of n·x (m), local unit n: the supporting plane of normal n."""
    nx, ny, nz = n
    if kind == GEOM_SPHERE:
        return size[0]
    if kind == GEOM_CAPSULE:
        return size[0] + size[1] * abs(nz)
    if kind == GEOM_CYLINDER:
        return size[0] * math.hypot(nx, ny) + size[1] * abs(nz)
    if kind == GEOM_BOX:
        return float(np.abs(n) @ size[:3])
    if kind == GEOM_ELLIPSOID:
        return math.sqrt(float(((size[:3] * n) ** 2).sum()))
    raise AssertionError(kind)


def off_surface(kind, size, q):
    """How far (m) local q is from the surface: exact, or to first order for the ellipsoid."""
    if kind == GEOM_ELLIPSOID:
        a2 = size[:3] ** 2
        return abs(float((q * q / a2).sum()) - 1.0) / (2.0 * float(np.linalg.norm(q / a2)))
    return abs(float(closed_form_sdf(kind, size, q)[0]))


def dist_tol(kind, p_local):
    per_m = ELLIPSOID_TOL_PER_M if kind == GEOM_ELLIPSOID else DIST_TOL_PER_M
    return DIST_TOL + per_m * float(np.linalg.norm(p_local))


# -- distance ----------------------------------------------------------------------------------

def check_distance(scene, shape, p):
    """Shape.distance at world p against the oracle: the distance; a unit normal, the oracle's
    where it is well defined; the point it names (p - d n) on the surface with n a supporting
    normal there. Returns the oracle's (local distance, local normal or None)."""
    kind, size = kind_and_size(scene, shape)
    c, R = frame(scene, shape)
    p = np.asarray(p, dtype=float)
    d, nx, ny, nz = shape.distance(*(float(v) for v in p))
    local = R.T @ (p - c)
    want, normal = oracle(kind, size, local)
    tol = dist_tol(kind, local)
    where = (shape.name, tuple(p), tuple(local))
    assert abs(d - want) <= tol, (*where, d, want)
    n = R.T @ np.array([nx, ny, nz])
    assert abs(np.linalg.norm(n) - 1.0) <= 1e-12, (*where, n)
    if normal is not None:
        assert np.linalg.norm(n - normal) <= NORMAL_TOL, (*where, n, normal)
    if kind != GEOM_PLANE:
        q = local - d * n
        assert off_surface(kind, size, q) <= tol, (*where, q)
        assert abs(support(kind, size, n) - n @ q) <= tol, (*where, "not a supporting normal", n, q)
    return want, normal


UNDERFLOW = 1e-140
"""A world point this close (m) to a geom's centre, but not on it, is taken as the centre: the
squares of its offset underflow, so no direction from the centre is measurable. It only
arises where a centre coordinate is 0 (elsewhere such offsets round away in world coordinates)."""


def to_world(scene, shape, local):
    """The world point at `local` in the shape's frame (snapped to the centre within UNDERFLOW)."""
    c, R = frame(scene, shape)
    p = c + R @ np.asarray(local, dtype=float)
    return c if np.linalg.norm(p - c) < UNDERFLOW else p


def scale_of(kind, size):
    """A length per local axis (m): random points are drawn in units of it."""
    if kind == GEOM_PLANE:
        return np.array([0.1, 0.1, 0.1])
    if kind == GEOM_SPHERE:
        return np.full(3, size[0])
    if kind in (GEOM_CAPSULE, GEOM_CYLINDER):
        return np.array([size[0], size[0], size[1] + (size[0] if kind == GEOM_CAPSULE else 0.0)])
    return size[:3].copy()


seeds = st.integers(0, 2**32 - 1)
unit = st.one_of(st.floats(-1.5, 1.5), st.sampled_from([0.0, -0.0, 1.0, -1.0, 0.5, 1e-300]))
local_points = st.tuples(unit, unit, unit)
scales = st.sampled_from([0.0, 1e-12, 0.3, 1.0, 1.0 + 1e-12, 1.5, 3.0, 1e3])


def distance_cases(scene, shape, points):
    """The centre, each point (in units of the shape's size × scale), the surface point the
    kernel names for it and the one the oracle names. Counts (inside, outside) of the points."""
    kind, size = kind_and_size(scene, shape)
    h = scale_of(kind, size)
    c, _ = frame(scene, shape)
    check_distance(scene, shape, c)
    inside = outside = 0
    for u, s in points:
        p = to_world(scene, shape, np.array(u) * s * h)
        want, normal = check_distance(scene, shape, p)
        if want is None:
            continue
        inside, outside = inside + (want < 0.0), outside + (want > 0.0)
        d, nx, ny, nz = shape.distance(*p)
        check_distance(scene, shape, p - d * np.array([nx, ny, nz]))      # on the surface (kernel's foot)
        if normal is not None:
            _, R = frame(scene, shape)
            check_distance(scene, shape, p - want * (R @ normal))         # on the surface (oracle's foot)
    return inside, outside


@settings(max_examples=100, deadline=None)
@given(seeds, st.lists(st.tuples(local_points, scales), min_size=1, max_size=4))
def test_distance_matches_the_closed_forms(scene, seed, points):
    """Plane, sphere, capsule, cylinder, box (static rotated, free at random poses, mocap):
    signed distance and normal equal the closed forms inside, outside, on the surface, at the centre, far away."""
    pose(scene, seed)
    for shape in scene[2]:
        if kind_and_size(scene, shape)[0] != GEOM_ELLIPSOID:
            distance_cases(scene, shape, points)


@pytest.mark.slow  # a long property run
@settings(max_examples=15, deadline=None)
@given(seeds, st.lists(st.tuples(local_points, scales), min_size=1, max_size=3))
def test_ellipsoid_distance_matches_the_brute_force_nearest_point(scene, seed, points):
    """Ellipsoids (round, flat, long; static and free): signed distance and normal equal the
    brute-force nearest point's, inside, outside, on the surface, far away."""
    pose(scene, seed)
    for shape in scene[2]:
        if kind_and_size(scene, shape)[0] == GEOM_ELLIPSOID:
            distance_cases(scene, shape, points)


def test_random_points_inside_and_outside_every_shape(scene):
    """Random points in a box 1.2 sizes wide around each shape, some inside and some outside
    every (non-plane) shape (asserted), get the oracle's sign, distance and normal."""
    rng = np.random.default_rng(7)
    pose(scene, 7)
    for shape in scene[2]:
        kind, size = kind_and_size(scene, shape)
        n = 20 if kind == GEOM_ELLIPSOID else 60
        counts = distance_cases(scene, shape, [(tuple(rng.uniform(-1.2, 1.2, 3)), 1.0) for _ in range(n)])
        if kind != GEOM_PLANE:
            assert counts[0] > 0 and counts[1] > 0, (shape.name, counts)


EGGS = ("<mujoco><worldbody>"
        + "".join(f'<geom name="{name}" type="ellipsoid" size="{size}"/>' for name, size in (
            ("egg", ".04 .025 .015"), ("long_egg", ".03 .01 .01"), ("flat_egg", ".03 .03 .01"),
            ("round_egg", ".02 .02 .02"), ("nearly_long_egg", ".03 .01 .0100001"), ("wafer", ".03 .02 1e-6")))
        + "</worldbody></mujoco>")
"""Ellipsoids at the origin, unrotated (a point given in the geom frame is exact, on a mid-plane
or an axis too): distinct semi-axes, two equal shortest (a ring of nearest points about the
long axis), two equal longest, all equal, two shortest a hair apart, and a 2 µm wafer."""


@pytest.fixture(scope="module")
def eggs():
    return _world(EGGS)


def test_ellipsoid_inside_on_the_mid_plane_of_its_shortest_axis(eggs):
    """Inside an ellipsoid on the mid-plane across its shortest semi-axis (or on the axis of two
    equal shortest ones), or a hair off it, the nearest surface point is off that plane: the
    distance and normal are the brute-force oracle's (these points once gave millimetres)."""
    by_name = {s.name: s for s in eggs[2]}
    for name, local in (("egg", (0.0, 0.003, 0.0)), ("egg", (1e-4, 0.0, 0.0)), ("egg", (0.02, 0.003, 1e-14)),
                        ("egg", (0.02, 0.003, 1e-9)), ("long_egg", (0.005, 0.0, 0.0)),
                        ("long_egg", (0.005, 1e-12, -1e-13)), ("long_egg", (0.0212, 0.0, -1.1e-9)),
                        ("flat_egg", (0.01, -0.02, 0.0)), ("nearly_long_egg", (0.004, 0.0, 0.0))):
        want, _ = check_distance(eggs, by_name[name], np.array(local))
        assert want < -1e-3, (name, local, want)   # deep inside: the nearest point is far off the plane


def egg_points(rng, abc, n):
    """n local points (m) in a box 1.3 semi-axes wide, each put on, or a hair (1e-15 to 1e-3 of
    the semi-axis) off, the mid-plane of a shortest semi-axis, a coordinate plane, an axis or
    the centre, or left where drawn."""
    out = []
    for _ in range(n):
        u = rng.uniform(-1.3, 1.3, 3)
        how = rng.integers(5)
        shortest = np.flatnonzero(abc == abc.min())
        if how == 0:      # on the mid-plane(s) of the shortest semi-axis (its axis, when two are equal)
            u[shortest] = 0.0
        elif how == 1:    # a hair off them
            u[shortest] *= 10.0 ** rng.uniform(-15, -3, len(shortest))
        elif how == 2:    # on (or a hair off) an axis
            others = rng.permutation(3)[:2]
            u[others] = 0.0 if rng.random() < 0.5 else u[others] * 10.0 ** rng.uniform(-15, -3, 2)
        elif how == 3:    # on a coordinate plane
            u[rng.integers(3)] = 0.0
        out.append(u * abc)
    return out


def test_ellipsoid_mid_planes_and_axes_match_the_brute_force(eggs):
    """Random points inside and outside each egg (asserted), on, or a hair off, the mid-planes of
    the shortest semi-axes, the coordinate planes, the axes, and the centre: signed distance,
    normal (where the nearest point is pinned) and the foot on the surface are the oracle's."""
    m, _, shapes = eggs
    rng = np.random.default_rng(29)
    for shape in shapes:
        abc = np.array(m.geom_size[shape.geom], dtype=float)
        inside = outside = 0
        for p in egg_points(rng, abc, 40) + [np.zeros(3)]:
            want, _ = check_distance(eggs, shape, p)
            inside, outside = inside + (want < 0.0), outside + (want > 0.0)
        assert inside > 10 and outside > 10, (shape.name, inside, outside)


def test_the_centre_of_a_sphere_and_of_an_ellipsoid(scene):
    """At the centre a sphere is its radius deep (normal: any unit vector), an ellipsoid its
    shortest semi-axis deep with the normal along that axis; a capsule on its axis is its radius deep."""
    pose(scene, 3)
    for shape in scene[2]:
        kind, size = kind_and_size(scene, shape)
        c, R = frame(scene, shape)
        if kind == GEOM_SPHERE:
            d, *n = shape.distance(*c)
            assert d == -size[0] and abs(np.linalg.norm(n) - 1.0) <= 1e-12
        elif kind == GEOM_ELLIPSOID:
            d, *n = shape.distance(*c)
            shortest = int(np.argmin(size[:3]))
            assert d == -size[shortest], shape.name
            if np.sum(size[:3] == size[shortest]) == 1:   # a unique shortest axis: ± that axis
                assert abs(abs(float(R[:, shortest] @ n)) - 1.0) <= 1e-12, (shape.name, n)
            else:                                        # a sphere-like ellipsoid: any unit normal
                assert abs(np.linalg.norm(n) - 1.0) <= 1e-12
        elif kind == GEOM_CAPSULE:
            for z in (-size[1], -0.3 * size[1], 0.0, 0.7 * size[1], size[1]):
                d, *n = shape.distance(*to_world(scene, shape, (0.0, 0.0, z)))
                assert abs(d + size[0]) <= DIST_TOL, (shape.name, z, d)
                assert abs(np.linalg.norm(n) - 1.0) <= 1e-12
                if abs(z) < size[1]:   # between the ends the nearest points ring the axis
                    assert abs(float(R[:, 2] @ n)) <= 1e-12, (shape.name, z, n)


def test_the_pose_is_mujocos_rotated_and_translated(scene):
    """A static geom's frame is the XML's pos and euler (MuJoCo's intrinsic xyz, degrees, built
    here with scipy): a point given in that frame is at the oracle's distance, `to_local` gives
    it back, `shape_to_world` inverts `to_local`; a moved free body is followed after mj_forward."""
    m, d, shapes = scene
    pose(scene, 11)
    by_name = {s.name: s for s in shapes}
    rng = np.random.default_rng(11)
    for (name, _), (pos, euler) in zip(PRIMITIVES, STATIC_POSES):
        shape = by_name[name]
        kind, size = kind_and_size(scene, shape)
        R = Rotation.from_euler("XYZ", [float(a) for a in euler.split()], degrees=True).as_matrix()
        c = np.array([float(v) for v in pos.split()])
        for _ in range(3):
            u = rng.uniform(-2.0, 2.0, 3) * scale_of(kind, size)
            p = c + R @ u
            d_, *n = shape.distance(*p)
            want, normal = oracle(kind, size, u)
            assert abs(d_ - want) <= 1e-12, (name, u)
            if normal is not None:
                assert np.linalg.norm(R.T @ n - normal) <= NORMAL_TOL, (name, u)
            assert np.allclose(shape.to_local(*p), u, rtol=0.0, atol=1e-15)
            back = shape_to_world(shape.set.S, d.geom_xpos, d.geom_xmat, shape.row, *shape.to_local(*p))
            assert np.allclose(back, p, rtol=0.0, atol=1e-15)
    # a free body moved: the queries read the new pose (no refresh)
    shape = by_name["free_brick"]
    j = m.body_jntadr[shape.body]
    a = m.jnt_qposadr[j]
    d.qpos[a:a + 7] = (0.3, -0.2, 0.4, 1.0, 0.0, 0.0, 0.0)
    mujoco.mj_forward(m, d)
    dist, nx, ny, nz = shape.distance(0.3, -0.2, 0.4 + 0.02 + 0.005)
    assert abs(dist - 0.005) <= 1e-15 and (nx, ny, nz) == (0.0, 0.0, 1.0)
    d.qpos[a:a + 3] = (0.3, -0.2, 0.1)
    mujoco.mj_forward(m, d)
    assert abs(shape.distance(0.3, -0.2, 0.425)[0] - 0.305) <= 1e-15


# -- sweep -------------------------------------------------------------------------------------

DENSE = 257
"""Samples of g per step of the sweep oracle: g is convex, so a step narrows its bracket 128 times."""


class Segment:
    """g(λ) = oracle distance of p0 + λ d from shape, minus r (m), λ in [0, 1]: convex."""

    def __init__(self, scene, shape, p0, d, r):
        self.kind, self.size = kind_and_size(scene, shape)
        self.c, self.R = frame(scene, shape)
        self.p0, self.d, self.r = np.asarray(p0, dtype=float), np.asarray(d, dtype=float), r

    def point(self, lam):
        """p0 + λ d with the kernel's own float operations (x0 + lam * dx per coordinate)."""
        return np.array([self.p0[i] + lam * self.d[i] for i in range(3)])

    def local(self, p):
        return self.R.T @ (p - self.c)

    def at(self, lam):
        """(g, outward normal in world or None, tolerance) at λ."""
        p = self.local(self.point(lam))
        dist, n = oracle(self.kind, self.size, p)
        return dist - self.r, (None if n is None else self.R @ n), dist_tol(self.kind, p)

    def never_below(self, bound):
        """(True, None) when g ≥ bound on all of [0, 1]; else (False, a λ where g < bound).
        Ellipsoid (g convex, its slope d·n at each point): Kelley's cutting planes, the
        tangent lines at the points tried bound g from below until the bound is proved or broken."""
        cuts = []
        lam = 0.0
        for _ in range(60):
            p = self.local(self.point(lam))
            dist, n = ellipsoid_oracle(self.size, p, subgradient=True)
            g = dist - self.r
            if g < bound:
                return False, lam
            cuts.append((lam, g, float((self.R @ n) @ self.d)))
            # the least of the lower envelope max_i (g_i + s_i (λ - λ_i)) on [0, 1]: at 0, 1 or a crossing
            tries = [0.0, 1.0] + [(g1 - g2 + s2 * l2 - s1 * l1) / (s2 - s1)
                                  for i, (l1, g1, s1) in enumerate(cuts) for (l2, g2, s2) in cuts[i + 1:] if s1 != s2]
            envelope = [(max(gi + si * (t - li) for li, gi, si in cuts), t) for t in tries if 0.0 <= t <= 1.0]
            low, lam = min(envelope)
            if low >= bound - 1e-15:
                return True, None
        raise AssertionError(("the cutting planes did not settle", self.p0, self.d, self.r))

    def many(self, lams):
        P = self.p0[None, :] + lams[:, None] * self.d[None, :]
        return closed_form_sdf(self.kind, self.size, (P - self.c) @ self.R) - self.r

    def lowest(self):
        """(λ, g) where g is least on [0, 1] (closed forms): dense sampling, refined around the best sample."""
        lo, hi = 0.0, 1.0
        for _ in range(6):   # to a spacing of 7e-15: the sampled least is above the true one by < 1e-14 L
            lams = np.linspace(lo, hi, DENSE)
            g = self.many(lams)
            i = int(np.argmin(g))   # g convex: its least lies within a sample of the least sample
            lo, hi = lams[max(i - 1, 0)], lams[min(i + 1, DENSE - 1)]
        return float(lams[i]), float(g[i])

    def first_root(self, lowest):
        """The first λ where g ≤ 0 (None if none): bisection of [0, λ_lowest], each step sampling
        the bracket at DENSE points (g decreases on it: convex), to adjacent floats."""
        if self.many(np.array([0.0]))[0] <= 0.0:
            return 0.0
        if lowest[1] > 0.0:
            return None
        lo, hi = 0.0, lowest[0]
        for _ in range(200):  # adjacent floats within ~8 brackets; the bound only guards the loop
            lams = np.linspace(lo, hi, DENSE)
            below = self.many(lams) <= 0.0
            # g of one λ may differ by a rounding from batch to batch (the matrix product's
            # summation order follows the batch's size): at the bracket's ends, trust the last
            if not below.any():
                return float(hi)
            j = int(np.argmax(below))
            if j == 0:
                return float(lo)
            if lams[j - 1] == lo and lams[j] == hi:
                return float(hi)
            lo, hi = lams[j - 1], lams[j]
        raise AssertionError(("the bisection did not settle", self.p0, self.d, self.r))


def check_sweep(scene, shape, p0, d, r, long=False):
    """Shape.sweep against the oracle g(λ); returns the hit (lam, nx, ny, nz) or None.

    A hit: lam in [0, 1); the sphere there is not past the surface (g ≥ -tol, unless it starts
    inside: lam 0) and touches it
    (g ≤ CONTACT_TOL, unless `long`: a segment whose advancement may run out stops short);
    its normal is the oracle's there and the motion goes into it; it is the first touch
    (the dense/bisection root, to the contact window; by convexity for the ellipsoid).
    A miss: the sphere never goes deeper than GRAZE per metre of motion below where it starts."""
    p0 = [float(v) for v in p0]
    d = [float(v) for v in d]
    hit = shape.sweep(*p0, *d, float(r))
    seg = Segment(scene, shape, p0, d, r)
    L = math.hypot(*d)
    where = (shape.name, p0, d, r, hit)
    if L < 1e-150:   # too short to measure (its squares underflow): it moves nothing
        assert hit is None or (L > 0.0 and hit[0] == 0.0 and seg.at(0.0)[0] <= CONTACT_TOL + seg.at(0.0)[2]), where
        return None
    if hit is None:
        g0, _, tol0 = seg.at(0.0)
        slack = GRAZE * L + DIST_TOL + ELLIPSOID_TOL_PER_M * float(np.linalg.norm(seg.local(seg.p0)) + L) \
            + (4.0 * np.finfo(float).eps * L if long else 0.0)
        if seg.kind == GEOM_ELLIPSOID:
            proved, lam_low = seg.never_below(min(g0, 0.0) - slack)
            assert proved, (*where, "missed a touch", lam_low, g0)
        else:
            lam_low, g_low = seg.lowest()
            assert g_low >= min(g0, 0.0) - slack, (*where, "missed a touch", lam_low, g_low, g0)
        return None
    lam, nx, ny, nz = hit
    n = np.array([nx, ny, nz])
    assert 0.0 <= lam < 1.0, where
    assert abs(np.linalg.norm(n) - 1.0) <= 1e-12, where
    # moving in, by its own normal (to the rounding of a dot product: ties at GRAZE are generated)
    assert -(n @ seg.d) > GRAZE * L - 4.0 * np.finfo(float).eps * L, (*where, "a hit must move into the surface")
    g, normal, tol = seg.at(lam)
    if long:
        tol += 4.0 * np.finfo(float).eps * L   # p0 + λ d is rounded to the ulp of L
    assert lam == 0.0 or g >= -tol, (*where, "past the surface", g)   # at 0: where it starts, maybe inside
    if not long:
        assert g <= CONTACT_TOL + tol, (*where, "not touching", g)
    if normal is not None:
        # a long segment's normal is from its last evaluated point, up to one stalled step (1e-8 m) back
        assert np.linalg.norm(n - normal) <= (1e-6 if long else NORMAL_TOL), (*where, normal)
        assert -(normal @ seg.d) > -NORMAL_TOL * L, (*where, "moving out of the surface")
    g0, _, tol0 = seg.at(0.0)
    if g0 < CONTACT_TOL - tol0:
        assert lam == 0.0, (*where, "touching at the start and moving in: a hit at 0", g0)
    if seg.kind != GEOM_ELLIPSOID and not long:
        root = seg.first_root(seg.lowest())
        if root is not None:
            _, at_root, _ = seg.at(root)
            speed = -(at_root @ seg.d) if at_root is not None else 0.0   # m per unit λ
            if speed > 1e-6 * L:
                assert root - (CONTACT_TOL + 2.0 * tol) / speed <= lam <= root + 2.0 * tol / speed, \
                    (*where, "not the first touch", root, speed)
    return hit


radii = st.sampled_from([0.0, 1e-9, 0.001953125, 0.005, 0.02])


def sweep_cases(scene, shape, u, s, v, length, r, inward):
    """Sweeps checked against the oracle: a free segment, a zero-length one, through the centre,
    from touching (tangent, tilted in and out, straight in, each also short), straight through
    along every local axis. Returns the hits."""
    kind, size = kind_and_size(scene, shape)
    h = scale_of(kind, size)
    c, R = frame(scene, shape)
    p0 = to_world(scene, shape, np.array(u) * s * h)
    hits = [check_sweep(scene, shape, p0, R @ (np.array(v) * h * length), r),
            check_sweep(scene, shape, p0, (0.0, 0.0, 0.0), r),
            check_sweep(scene, shape, p0, (c - p0) * 2.0, r)]
    dist, nx, ny, nz = shape.distance(*p0)
    n = np.array([nx, ny, nz])
    t = p0 + (r - dist) * n                                     # touching: r off the nearest point
    tangent = np.cross(n, R @ (np.array(v) * h * length))
    if tangent @ tangent < 1e-30:
        tangent = np.cross(n, (0.0, 0.8, 0.6))
    for e in (tangent, tangent - inward * n, tangent + inward * n, -n):
        hits.append(check_sweep(scene, shape, t, e, r))
        hits.append(check_sweep(scene, shape, t, e * 1e-3, r))
    for axis in range(3):
        e = R[:, axis] * (3.0 * h[axis] + r)
        start = c + R @ (np.array(u) * h * 0.5) + e
        hits.append(check_sweep(scene, shape, start, -2.0 * e, r))
    return [hit for hit in hits if hit is not None]


@pytest.mark.slow  # a long property run: its dense-sampling oracle costs up to a minute an example
@settings(max_examples=15, deadline=None)  # on a loaded 2-core machine 40 took over half an hour
@given(seeds, local_points, st.sampled_from([0.3, 1.0, 2.0, 3.0]), local_points,
       st.sampled_from([0.0, 1e-6, 0.1, 1.0, 3.0, 100.0]), radii,
       st.sampled_from([0.0, 1e-12, 1e-10, 1e-9, 1e-8, 1e-3, 0.3]))
def test_sweep_matches_dense_sampling_and_bisection(scene, seed, u, s, v, length, r, inward):
    """Plane, sphere, capsule, cylinder, box: the sweep's first touch is the oracle's (free,
    in contact, tangent, tilted, through, zero-length), and a miss never skips a touch."""
    pose(scene, seed)
    hits = 0
    for shape in scene[2]:
        if kind_and_size(scene, shape)[0] != GEOM_ELLIPSOID:
            hits += len(sweep_cases(scene, shape, u, s, v, length, r, inward))
    assert hits > 0


def test_ellipsoid_sweep_is_a_first_touch_never_past_the_surface(scene):
    """Ellipsoids: the same sweeps against the brute-force distance (convexity: a hit moving
    in with the oracle's normal at the oracle's contact distance is the first touch)."""
    rng = np.random.default_rng(5)
    hits = 0
    for seed in (5, 6):
        pose(scene, seed)
        for shape in scene[2]:
            if kind_and_size(scene, shape)[0] == GEOM_ELLIPSOID:
                u = tuple(rng.uniform(-1.5, 1.5, 3))
                v = tuple(rng.uniform(-1.0, 1.0, 3))
                hits += len(sweep_cases(scene, shape, u, 2.0, v, float(rng.choice([0.1, 1.0, 3.0])),
                                        float(rng.choice([0.0, 0.001953125, 0.005])), 1e-3))
    assert hits > 0


def test_fast_crossing_of_a_thin_plate_stops_on_the_near_side(scene):
    """A sphere crossing the 1 mm plate in one step (1 m: a thousand plate thicknesses) from
    either side stops on the side it came from, its centre r + hz from the mid-plane."""
    pose(scene, 1)
    for shape in scene[2]:
        if shape.name not in ("plate", "free_plate"):
            continue
        _, size = kind_and_size(scene, shape)
        _, R = frame(scene, shape)
        for r in (0.0, 0.001953125):
            for side in (1.0, -1.0):
                top = to_world(scene, shape, (0.01, -0.02, 0.5 * side))
                bottom = to_world(scene, shape, (0.01, -0.02, -0.5 * side))
                hit = check_sweep(scene, shape, top, bottom - top, r)
                assert hit is not None and 0.0 < hit[0] < 0.5, (shape.name, r, side, hit)
                stop = shape.to_local(*(top + hit[0] * (bottom - top)))
                assert abs(side * stop[2] - (size[2] + r)) <= CONTACT_TOL + DIST_TOL, (shape.name, stop)
                assert np.linalg.norm(np.array(hit[1:]) - side * R[:, 2]) <= NORMAL_TOL


def test_grazing_motion_within_graze_reports_no_hit(scene):
    """A touching sphere moving along the surface, tilted into it by less than GRAZE per metre,
    is not stopped; tilted by more it is stopped at once (lam 0); the exact tie approach ==
    GRAZE · length is no hit, one ulp more is a hit (unrotated box: its normals are exact)."""
    pose(scene, 1)
    for shape in scene[2]:
        kind, size = kind_and_size(scene, shape)
        x0 = to_world(scene, shape, np.array((0.2, 0.1, 1.2)) * scale_of(kind, size))
        dist, nx, ny, nz = shape.distance(*x0)
        n = np.array([nx, ny, nz])
        tangent = np.cross(n, (0.0, 0.8, 0.6))
        tangent -= (tangent @ n) * n
        touching = x0 - (dist - 1e-3) * n                            # centre 1 mm out, r = 1 mm
        _, *m = shape.distance(*touching)
        m = np.array(m)
        along = np.cross(m, (0.0, 0.8, 0.6))
        along -= (along @ m) * m
        for f in (0.5, 0.9, 1.1, 2.0, 1e3):
            e = GRAZE * f
            assert check_sweep(scene, shape, x0, tangent - e * n, 0.0) is None  # from afar: dips 1e-9 m per metre
            d = along - e * m
            hit = check_sweep(scene, shape, touching, d, 1e-3)
            inward = e / np.linalg.norm(d)                           # approach per metre of motion
            if inward < GRAZE * (1.0 - 1e-3):
                assert hit is None, (shape.name, f)
            elif inward > GRAZE * (1.0 + 1e-3):
                assert hit is not None and hit[0] == 0.0, (shape.name, f, hit)
    box = next(s for s in scene[2] if s.name == "upright")
    x0 = (0.02, 0.0, 0.8)   # on the +x face
    assert box.sweep(*x0, -GRAZE, 1.0, 0.0, 0.0) is None
    assert box.sweep(*x0, -math.nextafter(GRAZE, 1.0), 1.0, 0.0, 0.0) == (0.0, 1.0, 0.0, 0.0)


def test_a_gap_of_exactly_contact_tol_is_contact(scene):
    """A sphere exactly CONTACT_TOL from a surface (as the kernel computes it) touches it: moving
    in, the hit is at lam 0; one ulp more radius-gap and it is not yet touching (lam > 0)."""
    pose(scene, 1)
    exact = 0
    for shape in scene[2]:
        kind, size = kind_and_size(scene, shape)
        c, _ = frame(scene, shape)
        for u in ((0.3, 0.2, 1.7), (2.0, -0.4, 0.1), (-1.1, 1.3, -0.9)):
            x0 = to_world(scene, shape, np.array(u) * scale_of(kind, size))
            dist, *n = shape.distance(*x0)
            x0 = x0 + (2.5e-9 - dist) * np.array(n)
            dist, *n = shape.distance(*x0)
            r = dist - CONTACT_TOL
            if dist - r != CONTACT_TOL:
                continue
            exact += 1
            n = np.array(n)
            hit = check_sweep(scene, shape, x0, -0.01 * n, r)
            assert hit is not None and hit[0] == 0.0, (shape.name, hit)
            check_sweep(scene, shape, x0, c - x0, r)
            farther = math.nextafter(r, -math.inf)   # a gap one ulp over CONTACT_TOL
            if dist - farther > CONTACT_TOL:
                hit = check_sweep(scene, shape, x0, -0.01 * n, farther)
                assert hit is not None and hit[0] > 0.0, (shape.name, hit)
    assert exact >= len(scene[2])


def advancement_steps(monkeypatch, shape, *args):
    """How many distances the sweep's advancement evaluates: its own source (`py_func`, the code
    numba compiles) run with a counting `shape_distance`; and what that run answers."""
    calls = []
    compiled = kernels.shape_distance
    monkeypatch.setattr(kernels, "shape_distance", lambda *a: calls.append(a) or compiled(*a))
    s = shape.set
    try:
        result = kernels.shape_sweep.py_func(s.tables, shape.row, *args)
    finally:
        monkeypatch.setattr(kernels, "shape_distance", compiled)
    return len(calls), result


def test_long_segments_that_run_out_of_steps_stop_short(scene, monkeypatch):
    """1e8 m segments through each shape: the advancement stalls (each step below the ulp of
    lam) and runs out of its MAX_ADVANCE_STEPS; it then stops short of the surface, never
    past it. Some do stop short (gap > CONTACT_TOL), and each of those ran all its steps."""
    pose(scene, 1)
    _, d, shapes = scene
    short = 0
    for shape in shapes:
        kind, _ = kind_and_size(scene, shape)
        if kind in (GEOM_PLANE, GEOM_ELLIPSOID):   # the plane is answered in closed form; the ellipsoid below
            continue
        c, _ = frame(scene, shape)
        for length in (5e7, 6.8e7, 9.2e7, 1.26e8, 2.4e8):
            for y in (0.0, 0.005, 0.01):
                p0 = (c[0] - length / 2, c[1] + y, c[2] + 0.001)
                hit = check_sweep(scene, shape, p0, (length, 0.0, 0.0), 0.001, long=True)
                if hit is None:
                    continue
                g, _, _ = Segment(scene, shape, p0, (length, 0.0, 0.0), 0.001).at(hit[0])
                if g > CONTACT_TOL + DIST_TOL:
                    short += 1
                    steps, again = advancement_steps(monkeypatch, shape, *p0, length, 0.0, 0.0, 0.001)
                    assert (steps, again) == (MAX_ADVANCE_STEPS, hit), (shape.name, length, y)
    egg = next(s for s in shapes if s.name == "egg")
    c, _ = frame(scene, egg)
    hit = check_sweep(scene, egg, (c[0] - 5e7, c[1], c[2] + 0.001), (1e8, 0.0, 0.0), 0.001, long=True)
    assert hit is not None
    assert short > 0


# -- on_face -----------------------------------------------------------------------------------

@settings(max_examples=80, deadline=None)
@given(seeds, st.tuples(st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1)))
def test_on_face_of_planes_and_box_faces_only(scene, seed, v):
    """A plane: every normal is on its face. A box: its face normals and normals tilted less than
    acos(FACE_PARALLEL) ≈ 1.4e-6 rad are; more tilted, edge and corner normals are not. Sphere,
    capsule, cylinder, ellipsoid: never (the contact plane is held only on flat faces)."""
    pose(scene, seed)
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    random = [np.array(v) / n] if n > 1e-6 else []
    for shape in scene[2]:
        kind, _ = kind_and_size(scene, shape)
        _, R = frame(scene, shape)
        if kind == GEOM_PLANE:
            for m in random + [R[:, 2], -R[:, 0]]:
                assert shape.on_face(*m) is True
            continue
        cases = [(m, None) for m in random]
        for i in range(3):
            a, b = R[:, i], R[:, (i + 1) % 3]
            for sign in (1.0, -1.0):
                cases.append((sign * a, True))
                for tilt, on in ((1e-9, True), (1e-7, True), (1e-6, True), (2e-6, False), (1e-3, False), (0.3, False)):
                    t = sign * a + tilt * b
                    cases.append((t / np.linalg.norm(t), on))
            e = a + b
            cases.append((e / np.linalg.norm(e), False))
        corner = R.sum(axis=1)
        cases.append((corner / np.linalg.norm(corner), False))
        for m, on in cases:
            got = shape.on_face(*(float(c) for c in m))
            assert type(got) is bool
            if kind != GEOM_BOX:
                assert got is False, (shape.name, m)
                continue
            if on is None:   # a random normal: on a face iff within the cosine of an axis
                cosine = float(np.abs(R.T @ m).max())
                if abs(cosine - FACE_PARALLEL) < 1e-14:
                    continue
                on = cosine > FACE_PARALLEL
            assert got is on, (shape.name, m, on)
    upright = next(s for s in scene[2] if s.name == "upright")
    assert upright.on_face(FACE_PARALLEL, 0.0, 0.0) is False
    assert upright.on_face(0.0, -math.nextafter(FACE_PARALLEL, 1.0), 0.0) is True


# -- NaN ---------------------------------------------------------------------------------------

NAN = math.nan
NAN_KINDS = [
    pytest.param(GEOM_PLANE, id="plane"),
    pytest.param(GEOM_SPHERE, id="sphere"),
    pytest.param(GEOM_CAPSULE, id="capsule"),
    pytest.param(GEOM_ELLIPSOID, id="ellipsoid"),
    pytest.param(GEOM_CYLINDER, id="cylinder"),
    pytest.param(GEOM_BOX, id="box"),  # a NaN point gives n = 0 in the box branch: 0/0 must be NaN, not raise
]


@pytest.mark.parametrize("kind", NAN_KINDS)
def test_nan_inputs_never_crash(scene, kind):
    """A NaN anywhere in a query (point, start, direction, radius) returns, never raises, and a
    sweep never makes up a fraction of motion from it (lam in (0, 1))."""
    pose(scene, 2)
    _, d, shapes = scene
    chosen = [s for s in shapes if kind_and_size(scene, s)[0] == kind]
    assert chosen
    for shape in chosen:
        c = [float(v) for v in frame(scene, shape)[0]]
        for p in ((NAN, c[1], c[2]), (c[0], NAN, c[2]), (c[0], c[1], NAN), (NAN, NAN, NAN)):
            result = shape.distance(*p)
            assert len(result) == 4
            shape.on_face(*p)
            shape.to_local(*p)
        start = (c[0] + 0.5, c[1], c[2])
        for args in ((NAN, c[1], c[2], -1.0, 0.0, 0.0, 0.001), (*start, NAN, 0.0, 0.0, 0.001),
                     (*start, -1.0, NAN, 0.0, 0.001), (*start, -1.0, 0.0, 0.0, NAN),
                     (*start, NAN, NAN, NAN, NAN)):
            hit = shape.sweep(*args)
            assert hit is None or len(hit) == 4
            lam = shape_sweep(shape.set.tables, shape.row, *args)[0]
            assert not (0.0 < lam < 1.0), (shape.name, args, lam)


# -- ShapeSet ----------------------------------------------------------------------------------

def test_shape_table_holds_what_mujoco_says(scene):
    """Each SHAPE record holds the geom's MuJoCo type, id, body, static flag (no joint, not
    mocap), convexity, flatness (plane, box), bound (inf for a plane) and sizes (its geom_size row)."""
    m, _, shapes = scene
    S = shapes.S
    assert len(S) == len(shapes) == m.ngeom
    for k, s in enumerate(shapes):
        g = s.geom
        assert S[k].type == m.geom_type[g] and S[k].geom == g and S[k].body == m.geom_bodyid[g]
        assert bool(S[k].convex) is True
        assert bool(S[k].planar) is (int(m.geom_type[g]) in (GEOM_PLANE, GEOM_BOX))
        assert S[k].rbound == (math.inf if m.geom_type[g] == GEOM_PLANE else m.geom_rbound[g])
        assert tuple(S[k].geom_size) == tuple(m.geom_size[g])
        assert bool(S[k].static) is bool(m.body_jntnum[s.body] == 0 and m.body_mocapid[s.body] < 0)
    assert int(S.static.sum()) == 3 + len(PRIMITIVES)


def test_a_world_without_meshes_has_no_mesh_tables(scene):
    """Primitives only: T = C = None (the mesh kernels are never compiled for it)."""
    shapes = scene[2]
    assert shapes.T is None and shapes.C is None


def test_unsupported_geoms_are_refused_naming_them():
    """A touchable geom of a type fingers cannot touch (SDF) is refused by `shapes_of` with one
    line naming it (by name, or #index) and the fix (exclude it); made untouchable it is skipped.
    A ShapeSet refuses a Shape of no supported type, naming it."""
    sdf = ('<mujoco><extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">'
           '<config key="radius1" value="0.1"/><config key="radius2" value="0.03"/></instance></plugin></extension>'
           '<asset><mesh name="torus"><plugin instance="torus"/></mesh></asset>'
           '<worldbody><geom type="plane" size="1 1 .1"/>{}</worldbody></mujoco>')
    for geom, name in (('<geom name="ground" type="sdf" mesh="torus"><plugin instance="torus"/></geom>', "'ground'"),
                       ('<geom type="sdf" mesh="torus"><plugin instance="torus"/></geom>', "#1")):
        m = mujoco.MjModel.from_xml_string(sdf.format(geom))
        d = mujoco.MjData(m)
        with pytest.raises(ValueError) as err:
            shapes_of(m, d)
        message = str(err.value)
        assert "\n" not in message and name in message and "sdf" in message and "exclude" in message
    m = mujoco.MjModel.from_xml_string(sdf.format(
        '<geom name="ground" type="sdf" mesh="torus" contype="0" conaffinity="0"><plugin instance="torus"/></geom>'))
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    shapes = shapes_of(m, d)
    assert len(shapes) == 1 and isinstance(shapes[0], PlaneShape)
    floor = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom name="stone" type="box" size=".1 .1 .1"/>'
                                           '</worldbody></mujoco>')
    fd = mujoco.MjData(floor)
    with pytest.raises(ValueError, match=r"'stone' \(Shape\)"):
        ShapeSet([Shape(floor, fd, 0, True)])
    assert len(ShapeSet([BoxShape(floor, fd, 0, True)]).S) == 1
    with pytest.raises(ValueError, match="needs the MuJoCo data"):
        ShapeSet([])
