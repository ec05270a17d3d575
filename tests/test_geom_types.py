"""Every geom type a model can hold: felt as MuJoCo collides with it, refused by name, or named as not felt.

Height fields and a mesh's convex hull become triangle meshes that must match what MuJoCo
collides with (checked against MuJoCo's own `mj_geomDistance`); SDF geoms are refused in one
line naming all of them with the exclusion that keeps them in MuJoCo's physics; flexes are
named by one warning; the scene's [haptics] table reaches the world.
"""

import warnings

import mujoco
import numpy as np
import pytest
import trimesh

from softproxy import World
from softproxy.devices.simulated import SimulatedDevice
from softproxy.geometry import (
    FlexWarning, convex_hull, exclusions, hfield_triangles, hull_triangles, shapes_of,
)
from softproxy.mesh import MeshShape
from softproxy.run import build
from softproxy.scene import SceneError, load_scene

PROBE = 0.001  # radius (m) of the probe sphere MuJoCo measures from
PROBE_BODY = (f'<body name="probe" mocap="true"><geom name="probe" type="sphere" size="{PROBE}" '
              'contype="0" conaffinity="0"/></body>')
# a 3 x 4 height field whose cells include saddles (the diagonal a cell is split along matters)
HFIELD = f"""<mujoco><asset><hfield name="t" nrow="3" ncol="4" size="0.2 0.1 0.05 0.02"
 elevation="0 1 0 0.5  0 0 1 0  0.2 0.9 0.1 0.3"/></asset>
<worldbody><geom name="terrain" type="hfield" hfield="t" pos="0.1 -0.05 0.02" euler="10 0 30"/>{PROBE_BODY}
</worldbody></mujoco>"""
# an L-shaped prism (1 cm thick): not convex, its hull covers the notch
_L = np.array([[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]], dtype=float) * 0.01
_L_VERTS = np.vstack([np.c_[_L, np.zeros(6)], np.c_[_L, np.full(6, 0.01)]])
_L_FACES = [(0, 2, 1), (0, 3, 2), (0, 5, 3), (3, 5, 4), (6, 7, 8), (6, 8, 9), (6, 9, 11), (9, 10, 11)]
_L_FACES += [f for i in range(6) for f in ((i, (i + 1) % 6, (i + 1) % 6 + 6), (i, (i + 1) % 6 + 6, i + 6))]
L_MESH = f"""<mujoco><asset><mesh name="L" vertex="{' '.join(map(str, _L_VERTS.ravel()))}"
 face="{' '.join(map(str, np.ravel(_L_FACES)))}"/></asset>
<worldbody><geom name="ell" type="mesh" mesh="L" euler="0 20 40" pos="0.01 0 0"/>{PROBE_BODY}</worldbody></mujoco>"""
SDF_ASSETS = """<extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">
  <config key="radius1" value="0.1"/><config key="radius2" value="0.03"/></instance></plugin></extension>
  <asset><mesh name="torus"><plugin instance="torus"/></mesh></asset>"""


def mujoco_distance(m, d, geom, point) -> float:
    """MuJoCo's distance (m) from `point` to `geom`: its distance from the probe sphere there, plus its radius."""
    d.mocap_pos[0] = point
    mujoco.mj_kinematics(m, d)
    probe = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "probe")
    return mujoco.mj_geomDistance(m, d, probe, geom, 1.0, np.zeros(6)) + PROBE


def test_a_height_field_is_the_solid_mujoco_collides_with():
    """A tilted, turned height field: its mesh is watertight with positive volume; at 300 points
    outside it the engine's distance equals MuJoCo's to 1e-12 m (the wrong diagonal in a
    saddle cell would be centimetres off); points under its surface and above its base are
    inside (negative), a point under the base is outside by its depth below the base."""
    m = mujoco.MjModel.from_xml_string(HFIELD)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    vertices, faces = hfield_triangles(m, 0)
    tm = trimesh.Trimesh(vertices, faces, process=False)
    assert tm.is_watertight and tm.is_winding_consistent and tm.volume > 0.0
    (shape,) = shapes_of(m, d)
    assert isinstance(shape, MeshShape) and shape.signed and not shape.defects
    R, origin = d.geom_xmat[0].reshape(3, 3), d.geom_xpos[0]
    rng = np.random.default_rng(7)
    compared = 0
    while compared < 300:
        local = rng.uniform([-0.19, -0.09, 0.0], [0.19, 0.09, 0.08])
        world = origin + R @ local
        ours = shape.distance(*world)[0]
        if ours < 2 * PROBE:  # MuJoCo's distance is a contact depth once the probe touches
            continue
        assert abs(ours - mujoco_distance(m, d, 0, world)) < 1e-12
        compared += 1
    # inside: under the surface (elevation >= 0 everywhere), above the base at -0.02
    for local in ([0.0, 0.0, -0.005], [-0.15, 0.05, -0.015], [0.19, -0.09, -0.001]):
        assert shape.distance(*(origin + R @ np.array(local)))[0] < 0.0
    assert abs(shape.distance(*(origin + R @ np.array([0.0, 0.0, -0.03])))[0] - 0.01) < 1e-12


def test_a_mesh_hull_is_the_one_mujoco_collides_with():
    """The hull of an L-shaped prism, from MuJoCo's compiled hull and from scipy (used when the
    model has none: the same vertices), gives MuJoCo's own distance at 200 points outside it;
    the true surface does not: in the notch a point outside the L is inside the hull. A mesh
    with no hull (flat) is refused in one line naming the geom."""
    m = mujoco.MjModel.from_xml_string(L_MESH)
    d = mujoco.MjData(m)
    mujoco.mj_forward(m, d)
    assert m.mesh_graphadr[0] >= 0  # MuJoCo compiled a hull
    hull = shapes_of(m, d, mesh_surface="hull")[0]
    own = shapes_of(m, d, mesh_surface="true")[0]
    assert hull.signed and own.signed
    mesh = int(m.geom_dataid[0])
    verts = np.array(m.mesh_vert[m.mesh_vertadr[mesh]:m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh]], dtype=np.float64)
    scipy_hull = MeshShape(m, d, 0, True, triangles=convex_hull(verts))
    v, f = hull_triangles(m, 0)
    assert len(v) == 10 and hull.triangles == len(f)  # the notch's two corner vertices are not on the hull
    R, origin = d.geom_xmat[0].reshape(3, 3), d.geom_xpos[0]
    rng = np.random.default_rng(3)
    compared = 0
    while compared < 200:
        world = origin + R @ rng.uniform(-0.03, 0.03, 3)
        ours = hull.distance(*world)[0]
        if ours < 2 * PROBE:
            continue
        theirs = mujoco_distance(m, d, 0, world)
        assert abs(ours - theirs) < 1e-9 and abs(scipy_hull.distance(*world)[0] - theirs) < 1e-9
        compared += 1
    probe = _notch_point()
    assert own.distance(*probe)[0] > 0.001 and hull.distance(*probe)[0] < -0.001
    # a model without a compiled hull: scipy's, the same triangles' vertices; a flat one has none
    m.mesh_graphadr[mesh] = -1
    fallback, _ = hull_triangles(m, 0)
    assert sorted(map(tuple, fallback)) == sorted(map(tuple, v))
    m.mesh_vert[m.mesh_vertadr[mesh]:m.mesh_vertadr[mesh] + m.mesh_vertnum[mesh], 2] = 0.0
    with pytest.raises(ValueError) as err:
        shapes_of(m, d, mesh_surface="hull")
    assert "\n" not in str(err.value) and "'ell' (mesh)" in str(err.value) and "no convex hull" in str(err.value)


def _notch_point() -> np.ndarray:
    """World point in the L's notch (the square the L lacks, 1-2 cm in the asset's x and y):
    (1.2, 1.2, 0.5) cm, 2 mm from the L and 4.2 mm inside its hull. The geom's pose as written
    (pos, euler in degrees) maps asset coordinates to the world (MuJoCo moves the geom frame
    with the mesh it centres)."""
    quat, rot = np.zeros(4), np.zeros(9)
    mujoco.mju_euler2Quat(quat, np.radians([0.0, 20.0, 40.0]), "xyz")
    mujoco.mju_quat2Mat(rot, quat)
    return np.array([0.01, 0.0, 0.0]) + rot.reshape(3, 3) @ np.array([0.012, 0.012, 0.005])


def test_sdf_geoms_are_refused_together_and_can_be_excluded():
    """Touchable SDF geoms, named or not, are refused in one line naming every one with the fix
    (exclude by name, by group for an unnamed one); excluded that way the world loads without
    them, and MuJoCo still collides with them (a ball dropped in the ring's tube touches it)."""
    xml = f"""<mujoco>{SDF_ASSETS}<worldbody><geom name="floor" type="plane" size="1 1 .1"/>
      <geom name="ring" type="sdf" mesh="torus" pos="0 0 0.2"><plugin instance="torus"/></geom>
      <geom name="halo" type="sdf" mesh="torus" pos="0.5 0 0.2"><plugin instance="torus"/></geom>
      <geom type="sdf" mesh="torus" pos="-0.5 0 0.2" group="3"><plugin instance="torus"/></geom>
      <body name="ball" pos="0.1 0 0.2"><freejoint/><geom type="sphere" size="0.02"/></body>
    </worldbody></mujoco>"""
    m = mujoco.MjModel.from_xml_string(xml)
    with pytest.raises(ValueError) as err:
        World(m)
    message = str(err.value)
    assert "\n" not in message
    for word in ("'ring' (sdf)", "'halo' (sdf)", "#3 (sdf)", "exclude=['ring', 'halo']", "exclude_groups=[3]"):
        assert word in message, (word, message)
    world = World(m, exclude=["ring", "halo"], exclude_groups=[3])
    kept = {mujoco.mjtGeom(int(m.geom_type[s.geom])).name for s in world.shapes}
    assert len(world.shapes) == 2 and kept == {"mjGEOM_PLANE", "mjGEOM_SPHERE"}
    mujoco.mj_forward(m, world.data)
    ring = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "ring")
    touching = {(int(c.geom1), int(c.geom2)) for c in world.data.contact[:world.data.ncon]}
    assert any(ring in pair for pair in touching), "MuJoCo still collides with an excluded geom"


def test_exclusions_name_what_is_wrong():
    """An exclusion that names nothing in the model, a group out of 0-5, or a bare string: one
    line saying which, listing the model's geoms for a wrong name."""
    m = mujoco.MjModel.from_xml_string('<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/>'
                                       '<geom name="rock" type="sphere" size=".1" group="2"/></worldbody></mujoco>')
    for kwargs, words in (({"exclude": ["rok"]}, ["'rok'", "floor, rock"]),
                          ({"exclude": "rock"}, ["exclude", "list"]),
                          ({"exclude_groups": [6]}, ["exclude_groups", "0 to 5", "[6]"]),
                          ({"exclude_groups": [True]}, ["exclude_groups"])):
        with pytest.raises(ValueError) as err:
            exclusions(m, **kwargs)
        assert "\n" not in str(err.value) and all(w in str(err.value) for w in words), (kwargs, str(err.value))
    assert exclusions(m, ["rock"]) == ({1}, set()) and exclusions(m, exclude_groups=[2]) == ({1}, set())
    with pytest.raises(ValueError, match="mesh_surface"):
        shapes_of(m, mujoco.MjData(m), mesh_surface="convex")


def test_flexes_the_fingers_do_not_feel_are_named_once():
    """Two colliding flexes: one warning, one line, naming both; a flex that collides with
    nothing in MuJoCo either is not named; excluded by name or group, none is."""
    def flex(name, z, extra=""):
        return (f'<flexcomp name="{name}" type="grid" count="3 3 1" spacing="0.05 0.05 0.05" pos="0 0 {z}" '
                f'radius="0.002" dim="2" {extra}><edge equality="true"/></flexcomp>')
    xml = ('<mujoco><worldbody><geom name="floor" type="plane" size="1 1 .1"/>{}</worldbody></mujoco>')
    m = mujoco.MjModel.from_xml_string(xml.format(flex("sheet", 0.2) + flex("net", 0.4, 'group="4"') +
                                                  flex("ghost", 0.6, '><contact contype="0" conaffinity="0"/')))
    with pytest.warns(FlexWarning) as caught:
        shapes_of(m, mujoco.MjData(m))
    messages = [str(w.message) for w in caught if issubclass(w.category, FlexWarning)]
    assert len(messages) == 1 and "\n" not in messages[0]
    assert "'sheet'" in messages[0] and "'net'" in messages[0] and "ghost" not in messages[0]
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlexWarning)
        shapes = shapes_of(m, mujoco.MjData(m), exclude=["sheet"], exclude_groups=[4])
    assert [s.name for s in shapes] == ["floor"]


SCENE = """
[scene]
mjcf = "w.xml"
[[finger]]
name = "a"
[device]
type = "sim"
"""


def _scene(tmp_path, haptics: str, xml: str):
    (tmp_path / "w.xml").write_text(xml)
    (tmp_path / "s.toml").write_text(SCENE + haptics)
    return str(tmp_path / "s.toml")


@pytest.mark.parametrize("haptics, words", [
    ('[haptics]\nmesh_surface = "convex"\n', ["s.toml", "haptics.mesh_surface", "'hull'", "'convex'"]),
    ('[haptics]\nexclude = "ring"\n', ["s.toml", "haptics.exclude", "list"]),
    ('[haptics]\nexclude_groups = [7]\n', ["s.toml", "haptics.exclude_groups", "0 to 5"]),
    ('[haptics]\nexclud = ["ring"]\n', ["s.toml", "haptics has unknown field(s) ['exclud']", "exclude_groups"]),
])
def test_a_bad_haptics_table_names_the_file_and_field(tmp_path, haptics, words):
    """A malformed [haptics] table: one SceneError line naming the file and the field."""
    with pytest.raises(SceneError) as err:
        load_scene(_scene(tmp_path, haptics, "<mujoco/>"))
    message = str(err.value)
    assert "\n" not in message and all(w in message for w in words), message


def test_the_haptics_table_reaches_the_world(tmp_path):
    """A scene with an SDF ring it excludes, a mesh felt as its hull: the run's world holds the
    hull (MuJoCo's) and no ring; excluding a name the model lacks is refused at load naming the
    file, the field and the model's geoms; without the exclusion the SDF is refused naming the
    [haptics] fix."""
    xml = f"""<mujoco>{SDF_ASSETS}<asset><mesh name="L" vertex="{' '.join(map(str, _L_VERTS.ravel()))}"
      face="{' '.join(map(str, np.ravel(_L_FACES)))}"/></asset><worldbody>
      <geom name="floor" type="plane" size="1 1 .1"/><geom name="ell" type="mesh" mesh="L" pos="0 0 0.1"/>
      <geom name="ring" type="sdf" mesh="torus" pos="0.5 0 0.2"><plugin instance="torus"/></geom>
    </worldbody></mujoco>"""
    scene = load_scene(_scene(tmp_path, '[haptics]\nexclude = ["ring"]\nmesh_surface = "hull"\n', xml))
    loop = build(scene, SimulatedDevice([[(0.0, 0.0, 0.0, 0.3, 0.0)]]), realtime=False)
    try:
        names = [s.name for s in loop.world.shapes]
        assert names == ["floor", "ell"]
        assert loop.world.shapes[1].triangles == len(hull_triangles(loop.world.model, 1)[1])
    finally:
        loop.close()
    with pytest.raises(SceneError) as err:
        load_scene(_scene(tmp_path, '[haptics]\nexclude = ["rng"]\n', xml)).load_model()
    assert all(w in str(err.value) for w in ("s.toml", "[haptics]", "'rng'", "floor, ell, ring")), str(err.value)
    with pytest.raises(SceneError) as err:
        load_scene(_scene(tmp_path, "", xml)).load_model()
    assert all(w in str(err.value) for w in ("w.xml", "'ring' (sdf)", 'exclude = ["ring"]', "[haptics]"))
