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

from mesh_oracle import EXACT, Oracle, l_prism, mesh_model, mesh_of, point_triangle
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
