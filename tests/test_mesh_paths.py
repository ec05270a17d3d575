"""The god-object moved along device paths over meshes, tick by tick against brute force.

`mesh_oracle.Oracle` measures every proxy position over every triangle (the distance to the
nearest, signed by the winding number or the face planes of a convex mesh): the proxy never
sits more than TOL (1 µm) inside, and it follows the device: to it, exactly, whenever the
device is free (farther than the proxy's radius from the mesh), and otherwise as near to it
as the mesh lets a sphere of that radius come.
"""

import numpy as np
import pytest

from mesh_oracle import TOL, bowl, oracle, sphere10k
from softproxy.proxy import GodObject

RADIUS = 0.005
"""The proxy's radius (m): a fingertip's."""
SPHERE = 0.05
"""The 10k-triangle sphere's radius (m); its vertices lie on it, its faces up to 0.14 mm inside."""


def free_and_blocked(o, device, radius):
    """Which device positions are free (farther than `radius` from the mesh by more than a
    µm, so a proxy there touches nothing) and which are blocked (nearer than `radius` by more
    than a µm: no proxy can be there), by brute force."""
    d = o.distance(np.asarray(device))
    return d > radius + 1e-6, d < radius - 1e-6


def run(god, device):
    """Update the god-object at each device position; (proxy positions, contact flags), the
    proxy's start first (a row of its own in the positions)."""
    proxy, contact = [(god.x, god.y, god.z)], []
    for p in device:
        god.update(*p)
        proxy.append((god.x, god.y, god.z))
        contact.append(god.contact)
    return np.array(proxy), np.array(contact)


def check_follows(o, device, proxy, contact, radius):
    """Never more than TOL inside (brute force); in contact wherever the device is blocked; at
    the device, exactly, wherever it is free and the proxy could sweep there straight from
    where it was (the brute force's sweep: no touch on the way); and at it from the third
    tick of every stretch of free ticks on, wherever it was (a device that went through the
    sphere comes out on the far side of the proxy, which slides round to it). Returns the
    counts (free, blocked)."""
    start, proxy = proxy[0], proxy[1:]
    depth = radius - o.distance(proxy)
    worst = int(np.argmax(depth))
    assert depth[worst] <= TOL, ("inside the mesh", worst, device[worst], proxy[worst], depth[worst])
    free, blocked = free_and_blocked(o, device, radius)
    lost = np.flatnonzero(blocked & ~contact)
    assert len(lost) == 0, ("no contact with the device inside", lost[:5])
    late = free & (proxy != device).any(axis=1)
    for i in np.flatnonzero(late):
        was = proxy[i - 1] if i else start
        facts = o.sweep_facts(was, device[i] - was, radius)
        assert facts["into"] or facts["first"] is not None, ("left behind a free device in reach", i, device[i], was)
        assert i >= 2 and not (free[i - 1] and free[i - 2]), ("left behind a free device", i, device[i], proxy[i])
    return int(free.sum()), int(blocked.sum())


def test_a_frictionless_proxy_rolls_off_the_bowls_rim_toward_the_device():
    """Resting on the bowl's inner rim, where two rim edges meet at a vertex at nearly the same
    tangent plane, with the device 2 mm into the inner wall below: the frictionless proxy
    rolls over the rim toward the device at once and settles where no free point is nearer to
    it (its distance from the device the least the mesh allows, to a µm; no point LIFT_TOL
    nearer, about it, is free: the solver follows the two rim edges' round surfaces until
    they lift by no more than that); never inside."""
    from softproxy.compiled.godobject import LIFT_TOL

    m, d, shapes = bowl()
    o = oracle(m, d, shapes)
    god = GodObject(shapes, RADIUS, 0.0, 0.0, (0.03497532562938234, 0.0, 0.04499993828562851))
    device = np.array([0.03289387, 0.0, 0.0421364])
    start = np.array([god.x, god.y, god.z])
    # no free point is nearer to the device than this (the distance is 1-Lipschitz)
    least = RADIUS - float(o.distance(device[None])[0])
    assert least > 1.9e-3 and np.linalg.norm(start - device) > least + 1e-3
    proxy, contact = run(god, [device] * 20)
    proxy = proxy[1:]
    assert contact.all()
    assert RADIUS - o.distance(proxy).min() <= TOL
    reach = np.linalg.norm(proxy - device, axis=1)
    assert reach[0] <= least + 5e-6        # rolled over the rim in the first tick
    assert reach[4] <= least + 1e-6 and reach[-1] <= reach[4]
    # settled: points a hair nearer to the device, all about the proxy, are all blocked
    rng = np.random.default_rng(3)
    out = (proxy[-1] - device) / reach[-1]
    side = rng.normal(size=(400, 3))
    side -= (side @ out)[:, None] * out
    side /= np.linalg.norm(side, axis=1)[:, None]
    turn = rng.uniform(0.0, 0.05, (400, 1))
    nearer = device + (reach[-1] - LIFT_TOL) * (np.cos(turn) * out + np.sin(turn) * side)
    assert o.nearest(nearer)[0].max() < RADIUS


@pytest.mark.parametrize("mu", [0.0, 0.6])
def test_fast_strokes_through_the_10k_sphere(mu):
    """Strokes of 1 cm a tick (10 m/s) along random chords through the 10k-triangle sphere and
    out the other side, some grazing it: the proxy is never inside (brute force), stays in
    contact while the device is inside, and is at the device whenever the device is free."""
    m, d, shapes = sphere10k()
    o = oracle(m, d, shapes)
    rng = np.random.default_rng(41)
    god = GodObject(shapes, RADIUS, mu, 0.8 * mu, (0.0, 0.0, 0.09))
    device = []
    for k in range(12):
        u = rng.normal(size=3)
        u /= np.linalg.norm(u)
        side = np.cross(u, rng.normal(size=3))
        side /= np.linalg.norm(side)
        miss = (SPHERE + RADIUS) * [0.0, 0.5, 0.9, 1.0][k % 4]     # through the middle ... grazing
        start = -0.09 * u + miss * side
        device += [start + t * u for t in np.arange(0.0, 0.18, 0.01)]
    device = np.array(device)
    proxy, contact = run(god, device)
    free, blocked = check_follows(o, device, proxy, contact, RADIUS)
    assert free > 60 and blocked > 40, (free, blocked)


def test_random_walk_through_the_10k_sphere():
    """A device wandering in, through and out of the 10k-triangle sphere in random steps of up
    to 1 cm a tick: the frictionless proxy is never inside (brute force), stays in contact
    while the device is inside, and is at the device whenever the device is free."""
    m, d, shapes = sphere10k()
    o = oracle(m, d, shapes)
    rng = np.random.default_rng(43)
    god = GodObject(shapes, RADIUS, 0.0, 0.0, (0.0, 0.0, 0.09))
    device, p = [], np.array([0.0, 0.0, 0.09])
    for _ in range(400):
        step = rng.normal(size=3)
        p = np.clip(p + step / np.linalg.norm(step) * rng.uniform(0.0, 0.01), -0.065, 0.065)
        device.append(p)
    device = np.array(device)
    proxy, contact = run(god, device)
    free, blocked = check_follows(o, device, proxy, contact, RADIUS)
    assert free > 50 and blocked > 100, (free, blocked)
