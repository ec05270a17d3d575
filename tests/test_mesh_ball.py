"""The ball certificate (`softproxy.mesh_balls`) against brute force.

On a concave patch finer than the proxy no plane certificate holds (hundreds of triangles
rise above a face's plane within the proxy's reach), but a ball of the proxy's radius
resting on a face reaches only its few neighbours rising above it. These tests check the
lists built at load against brute-force triangle distances, and the queries that read them
against `mesh_oracle.Oracle`, on the inside of a sphere of 4 cm and on a saddle as curved,
0.12 mm facets.
"""

import functools
import warnings

import numpy as np
import pytest
import trimesh

from mesh_oracle import EXACT, mesh_model, mesh_of, oracle, point_triangle
from softproxy.compiled.certificate import ABOVE_TOL, BALL_SLACK
from softproxy.mesh_balls import BALL_ABOVE

R = 0.005
"""The proxy's radius (m): the certificates are built for it at load."""


@functools.cache
def dish(kind: str = "dish"):
    """12 mm across, 100 × 100 vertices (19602 triangles, 0.12 mm apart: too dense for a patch
    to hold a resting 5 mm proxy, so it gets ball certificates), facing up (an open sheet):
    the inside of a sphere of radius 4 cm ("dish"), or a saddle curving as much up along x
    and down along y ("saddle": a sphere sliding along y slides off its face's convex edges)."""
    n, half, big = 100, 0.006, 0.04
    x, y = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n))
    z = big - np.sqrt(big * big - x * x - y * y) if kind == "dish" else (x * x - y * y) / (2.0 * big)
    v = np.column_stack([x.ravel(), y.ravel(), z.ravel()])
    k = np.arange(n * n).reshape(n, n)
    a, b, c, d = k[:-1, :-1].ravel(), k[:-1, 1:].ravel(), k[1:, :-1].ravel(), k[1:, 1:].ravel()
    f = np.concatenate([np.column_stack([a, b, d]), np.column_stack([a, d, c])])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # open on purpose
        return mesh_model(trimesh.Trimesh(v, f, process=False))


def segment_gap(p, q, s, t):
    """Distance (m) between segments p..q and s..t, row by row ((n, 3) arrays): the least of
    the four ends' distances to the other segment and, where the two cross between their ends,
    the gap along their common normal."""
    def point_segment(x, a, b):
        e = b - a
        u = np.clip(((x - a) * e).sum(1) / (e * e).sum(1), 0.0, 1.0)
        return np.linalg.norm(x - (a + u[:, None] * e), axis=1)
    best = np.min([point_segment(p, s, t), point_segment(q, s, t), point_segment(s, p, q), point_segment(t, p, q)], 0)
    d1, d2, w = q - p, t - s, p - s
    a, b, c, d, e = (d1 * d1).sum(1), (d1 * d2).sum(1), (d2 * d2).sum(1), (d1 * w).sum(1), (d2 * w).sum(1)
    den = a * c - b * b
    with np.errstate(all="ignore"):
        u, v = (b * e - c * d) / den, (a * e - b * d) / den
    inner = (den > 1e-30) & (u > 0) & (u < 1) & (v > 0) & (v < 1)
    with np.errstate(all="ignore"):  # parallel pairs: not inner
        gap = np.linalg.norm(w + u[:, None] * d1 - v[:, None] * d2, axis=1)
    return np.where(inner, np.minimum(best, gap), best)


def triangle_gap(a, b):
    """Distance (m) between triangles a[k] and b[k] ((n, 3 corners, 3) arrays) that do not
    cross: the least over each one's corners to the other and over their edges' pairs."""
    out = np.full(len(a), np.inf)
    for x, y in ((a, b), (b, a)):
        for k in range(3):
            out = np.minimum(out, point_triangle(x[:, k], y[:, 0], y[:, 1], y[:, 2])[0])
    for i in range(3):
        for j in range(3):
            out = np.minimum(out, segment_gap(a[:, i], a[:, (i + 1) % 3], b[:, j], b[:, (j + 1) % 3]))
    return out


@pytest.mark.parametrize("kind", ["dish", "saddle"])
def test_a_ball_list_holds_every_triangle_a_resting_ball_reaches(kind):
    """Per face of the dish's (or saddle's) concave side, the triangles a ball of the certificate's radius
    resting on the face reaches: every triangle rising above the face's plane that comes
    within that radius of the face lifted by it, by brute force, is listed, and nothing
    farther. The plane certificate holds on none of those faces, the ball's on nearly all."""
    _, _, shapes = dish(kind)
    t = mesh_of(shapes).tables
    assert abs(t.ball - (R + 1e-5)) < 1e-9
    up = int(np.argmin((t.clear >= 0).mean(axis=0)))  # the concave side (MuJoCo turns a mesh to its inertia frame)
    concave = t.clear[:, up] < 0
    assert concave.mean() > 0.9
    held = t.ball_count[concave, up] >= 0
    assert held.mean() > 0.9
    corners = t.vpos[t.tv]
    rng = np.random.default_rng(5)
    checked = 0
    for i in rng.choice(np.flatnonzero(concave), 120, replace=False):
        n = t.plane[i, :3] * (1.0 if up == 0 else -1.0)
        heights = (corners - corners[i, 0]) @ n
        rising = np.flatnonzero(heights.max(axis=1) > ABOVE_TOL)
        rising = rising[rising != i]
        gap = triangle_gap(np.broadcast_to(corners[i] + t.ball * n, (len(rising), 3, 3)), corners[rising])
        must = set(rising[gap <= t.ball + BALL_SLACK - 1e-12].tolist())
        may = set(rising[gap <= t.ball + BALL_SLACK + 1e-12].tolist())
        count = int(t.ball_count[i, up])
        if count < 0:
            assert len(must) > BALL_ABOVE or len(may) > BALL_ABOVE, (i, len(must))
            continue
        listed = set(t.ball_listed[i, up, :count].tolist())
        assert must <= listed <= may, (i, must - listed, listed - may)
        checked += 1
    assert checked > 100


@pytest.mark.parametrize("kind", ["dish", "saddle"])
def test_queries_a_resting_ball_holds_match_the_brute_force(kind):
    """A 5 mm sphere resting on the dish (or floating 2 nm or 1 µm above it), sliding
    towards a point on its face's rim and beyond (so that it runs into the neighbour rising
    there) or lifting off: distances at its centre and sweeps of it, against brute force. Most
    start and end (at the touch) inside a ball resting on their nearest face (checked here,
    by brute force: the ball certificate answers those), the rest run past it, where the
    box tree answers."""
    m, d, shapes = dish(kind)
    o = oracle(m, d, shapes)
    s = mesh_of(shapes)
    ball = s.tables.ball
    rng = np.random.default_rng(8)
    held = 0
    for i in range(300):
        foot = np.array([*rng.uniform(-0.003, 0.003, 2), 0.0])
        _, q, tri = o.nearest(foot + [0.0, 0.0, 0.01])
        q, f = q[0], tri[0]
        n = o.n[f] if o.n[f, 2] > 0 else -o.n[f]
        p = q + n * (R + rng.choice([0.0, 2e-9, 1e-6]))
        got = s.distance(*p)
        want, _, _ = o.nearest(p)
        assert abs(got[0] - want[0]) <= EXACT, (i, got[0], want[0])
        corners = (o.a[f], o.b[f], o.c[f])
        w = rng.dirichlet([1.0, 1.0, 1.0])
        w[rng.integers(3)] = 0.0  # a point on the rim
        rim = sum(x * c for x, c in zip(w / w.sum(), corners))
        u = (rim - q) * rng.uniform(0.5, 3.0) + n * rng.choice([0.0, 0.0, 1e-6])
        hit = s.sweep(*p, *u, R)
        o.check_sweep(p, u, R, hit, context=i)
        # did the ball certificate's test hold at both ends (the centre within ball - r of
        # the face lifted by the ball's radius), the end being the touch?
        end = p + (hit[0] if hit is not None else 1.0) * u
        gaps = point_triangle(np.array([p, end]) - ball * n, *(np.broadcast_to(c, (2, 3)) for c in corners))[0]
        held += bool((gaps <= ball - R - 1e-9).all())
    assert held > 80  # 97 (dish) and 91 (saddle) of these 300
