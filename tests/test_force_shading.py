"""Force shading on meshes: a scene option that makes a faceted mesh feel smooth."""

import math

import mujoco
import numpy as np
import pytest
import trimesh

from mesh_oracle import TOL, geodesic_sphere, mesh_model, mesh_of, oracle
from softproxy.proxy import GodObject
from softproxy.scene import SceneError, load_scene
from softproxy.world import World


def _ball_model(subdivisions: int = 2, radius: float = 0.05) -> mujoco.MjModel:
    ball = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    verts = " ".join(f"{v:.9g}" for v in ball.vertices.ravel())
    faces = " ".join(str(i) for i in ball.faces.ravel())
    return mujoco.MjModel.from_xml_string(
        f'<mujoco><asset><mesh name="ball" vertex="{verts}" face="{faces}"/></asset>'
        f'<worldbody><geom name="ball" type="mesh" mesh="ball"/></worldbody></mujoco>')


def _normal_error_deg(shading: bool, direction) -> float:
    """Press a 5 mm proxy toward the ball's centre along `direction`; the angle (deg) between
    the contact normal and the radial direction through the proxy (the smooth sphere's)."""
    world = World(_ball_model(), force_shading=shading)
    dx, dy, dz = direction
    god = GodObject(world.shapes, 0.005, 0.0, 0.0, (0.1 * dx, 0.1 * dy, 0.1 * dz))
    god.update(0.047 * dx, 0.047 * dy, 0.047 * dz)  # 3 mm under the faceted surface
    assert god.contact
    n = math.sqrt(god.x ** 2 + god.y ** 2 + god.z ** 2)
    cos = (god.nx * god.x + god.ny * god.y + god.nz * god.z) / n
    return math.degrees(math.acos(min(1.0, cos)))


@pytest.mark.parametrize("direction", [(0.3, 0.5, 0.81), (-0.62, 0.2, 0.76), (0.1, -0.9, 0.42)])
def test_shaded_normal_follows_the_smooth_surface(direction):
    """On a 320-face icosphere the faceted normal is off the radial by up to ~10°; the
    interpolated (shaded) normal is much closer to it."""
    norm = math.sqrt(sum(v * v for v in direction))
    direction = tuple(v / norm for v in direction)
    faceted = _normal_error_deg(False, direction)
    shaded = _normal_error_deg(True, direction)
    assert faceted > 1.0  # the probe points are off the face centres: the facets show
    assert shaded < 0.5 * faceted


def test_scene_switches_shading_on_for_its_meshes(tmp_path):
    mjcf = load_scene("mesh_object").mjcf
    text = load_scene("mesh_object").path.read_text()
    for value, expect in (("true", True), ("false", False)):
        toml = tmp_path / f"shaded_{value}.toml"
        toml.write_text(text.replace('mjcf = "mesh_object.xml"', f'mjcf = "{mjcf}"\nforce_shading = {value}'))
        scene = load_scene(str(toml))
        assert scene.force_shading is expect
        world = World(scene.load_model(), force_shading=scene.force_shading)
        meshes = [s for s in world.shapes if hasattr(s, "shading")]
        assert meshes and all(s.shading is expect for s in meshes)
    bad = tmp_path / "bad.toml"
    bad.write_text(text.replace('mjcf = "mesh_object.xml"', f'mjcf = "{mjcf}"\nforce_shading = "yes"'))
    with pytest.raises(SceneError, match="force_shading must be true or false"):
        load_scene(str(bad))


def test_shading_changes_the_normal_only():
    """On a faceted sphere (2000 triangles) the shaded normal is never farther from the true
    radial direction than the faceted one, and is a unit vector; the distance is the same to
    the bit, and a sweep stops at the same fraction with a normal still against the motion;
    a proxy stroked round it stays outside (brute force)."""
    ball = geodesic_sphere(10, 0.05)
    m, d, plain = mesh_model(ball)
    shaded = mesh_model(ball, shading=True)[2]
    a, b = mesh_of(shaded), mesh_of(plain)
    assert a.shading and not b.shading
    rng = np.random.default_rng(3)
    worse = differs = 0
    for p in rng.normal(size=(50, 3)):
        p = p / np.linalg.norm(p) * 0.052
        radial = p / np.linalg.norm(p)
        got, faceted = np.array(a.distance(*p)), np.array(b.distance(*p))
        assert got[0] == faceted[0] and abs(np.linalg.norm(got[1:]) - 1.0) < 1e-9
        worse += np.arccos(min(1.0, got[1:] @ radial)) > np.arccos(min(1.0, faceted[1:] @ radial)) + 1e-12
        differs += got[1:] @ faceted[1:] < 1.0 - 1e-6
        u = -radial * 0.004 + rng.normal(size=3) * 0.001
        hit, flat = a.sweep(*p, *u, 0.001), b.sweep(*p, *u, 0.001)
        assert (hit is None) == (flat is None)
        if hit is not None:
            assert hit[0] == flat[0] and np.dot(hit[1:], u) < 0.0
    assert worse == 0 and differs > 40
    o = oracle(m, d, shaded)
    god = GodObject(shaded, 0.005, 0.0, 0.0, (0.0, 0.0, 0.09))
    proxy = []
    for k in range(200):
        t = 0.01 * k
        god.update(0.053 * math.sin(t), 0.0, 0.053 * math.cos(t))
        proxy.append((god.x, god.y, god.z))
        assert god.contact
    assert (0.005 - o.distance(np.array(proxy))).max() <= TOL
