"""Scene files: every shipped scene loads; malformed ones fail naming the file and the field."""

import pytest

from softproxy.scene import SceneError, list_scenes, load_scene

GOOD_XML = '<mujoco><worldbody><geom type="plane" size="1 1 .1"/></worldbody></mujoco>'
GOOD = """
[scene]
mjcf = "w.xml"
[[finger]]
name = "a"
[device]
type = "sim"
"""


def write(tmp_path, toml, xml=GOOD_XML):
    (tmp_path / "w.xml").write_text(xml)
    p = tmp_path / "s.toml"
    p.write_text(toml)
    return str(p)


def test_every_shipped_scene_loads_and_compiles():
    names = {p.stem for p in list_scenes()}
    assert {"two_finger_grasp", "knob", "thin_plate", "corner", "friction_ramp", "shapes_tour"} <= names
    for p in list_scenes():
        scene = load_scene(str(p))
        scene.load_model()
        assert scene.fingers


def test_good_minimal_scene(tmp_path):
    s = load_scene(write(tmp_path, GOOD))
    assert s.rate_hz == 1000.0 and s.fingers[0].name == "a" and s.fingers[0].model == "CH"


@pytest.mark.parametrize(
    "toml, words",
    [
        (GOOD.replace('mjcf = "w.xml"', ""), ["mjcf is required"]),
        (GOOD.replace('"w.xml"', '"nope.xml"'), ["nope.xml", "does not exist"]),
        (GOOD.replace('name = "a"', 'name = "a"\nmodel = "HUMAN"'), ["finger[0].model", "HUMAN", "CH"]),
        (GOOD.replace('name = "a"', 'name = "a"\nstiffness = -5.0'), ["finger[0].stiffness", "between 10 and 1e+08 N/m"]),
        (GOOD.replace('name = "a"', 'name = "a"\nstifness = 5.0'), ["finger[0]", "stifness"]),
        (GOOD.replace('name = "a"', 'name = "a"\nradius = "big"'), ["finger[0].radius", "number"]),
        (GOOD.replace("[[finger]]\nname = \"a\"", ""), ["[[finger]]"]),
        (GOOD.replace("[scene]", "[scene]\nrate_hz = 0"), ["scene.rate_hz", "between 10 and 100000 Hz"]),
        (GOOD + "\n[measure]\nobject = \"box\"\naxis = [0, 0]\n", ["measure.axis"]),
        (GOOD + "\n[extras]\n", ["unknown table", "extras"]),
        ("[scene\nmjcf=", ["not valid TOML"]),
        ("[scene]\nmjcf = " + "[" * 5000 + "]" * 5000, ["not valid TOML", "nested too deeply"]),
        (GOOD.replace("[scene]", "[scene]\nduration_s = 1e7"), ["scene.duration_s", "86400"]),
        (GOOD.replace("[scene]", "[scene]\nrate_hz = 5"), ["scene.rate_hz", "10", "100000"]),
        (GOOD.replace('name = "a"', 'name = "a"\ndamping = 1e308'), ["finger[0]", "damping", "at most"]),
        (GOOD.replace('name = "a"', 'name = "a"\nstiffness = 1e400'), ["finger[0].stiffness", "finite"]),
        (GOOD.replace('name = "a"', 'name = "a"\ntactile = { cells = 100000 }'), ["finger[0].tactile", "cells"]),
    ],
)
def test_malformed_scene_names_file_and_field(tmp_path, toml, words):
    with pytest.raises(SceneError) as err:
        load_scene(write(tmp_path, toml))
    message = str(err.value)
    assert "s.toml" in message
    for w in words:
        assert w in message


def test_bad_mjcf_names_the_file(tmp_path):
    s = load_scene(write(tmp_path, GOOD, xml="<mujoco><worldbody><geom type='box'/></worldbody>"))
    with pytest.raises(SceneError, match="w.xml.*does not compile"):
        s.load_model()


def test_unknown_scene_lists_the_known_ones():
    with pytest.raises(SceneError, match="two_finger_grasp"):
        load_scene("no_such_scene")


SDFS = """<mujoco><extension><plugin plugin="mujoco.sdf.torus"><instance name="torus"><config key="radius1" value="0.1
  "/><config key="radius2" value="0.03"/></instance></plugin></extension>
  <asset><mesh name="torus"><plugin instance="torus"/></mesh></asset><worldbody>
  <geom name="floor" type="plane" size="1 1 .1"/>
  <geom name="hill" type="sdf" mesh="torus" pos="0.3 0 0"><plugin instance="torus"/></geom>
  <geom name="dune" type="sdf" mesh="torus" pos="-0.3 0 0"><plugin instance="torus"/></geom>
  <geom name="backdrop" type="sdf" mesh="torus" pos="0 0.3 0" contype="0" conaffinity="0">
    <plugin instance="torus"/></geom>
</worldbody></mujoco>"""


@pytest.mark.parametrize(
    "toml, xml, words, absent",
    [
        (GOOD, GOOD_XML.replace("<worldbody>", '<option integrator="RK4"/><worldbody>'),
         ["w.xml", "RK4", "implicitfast"], []),
        (GOOD, SDFS, ["w.xml", "'hill' (sdf)", "'dune' (sdf)", 'exclude = ["hill", "dune"]', "[haptics]"],
         ["backdrop"]),
        (GOOD + '\n[measure]\nobject = "box"\n', GOOD_XML.replace("</worldbody>", '<body name="lid"/></worldbody>'),
         ["s.toml", "measure.object", "'box'", "lid"], []),
    ],
    ids=["rk4", "sdfs", "measured-body"],
)
def test_a_model_the_loop_cannot_run_is_refused_at_load(tmp_path, toml, xml, words, absent):
    """An MJCF the servo loop cannot run is a SceneError from load_model, naming the file, every
    culprit and the fix (RK4 has no split step; a touchable SDF; a measured body the
    model lacks); geoms kept out of contact are not culprits."""
    scene = load_scene(write(tmp_path, toml, xml=xml))
    with pytest.raises(SceneError) as err:
        scene.load_model()
    message = str(err.value)
    assert "\n" not in message
    for w in words:
        assert w in message, (w, message)
    for w in absent:
        assert w not in message, (w, message)


DROP_XML = """<mujoco><option timestep="0.002"/>
  <worldbody><geom type="plane" size="1 1 .1"/>
    <body name="box" pos="0 0 0.3"><freejoint/><geom type="box" size=".02 .02 .02" mass="0.1"/></body>
  </worldbody>
  <keyframe><key name="high" qpos="0.1 0 0.5 1 0 0 0"/></keyframe></mujoco>"""


def test_a_scene_starts_from_its_keyframe_and_settles(tmp_path):
    """[scene] keyframe: the world starts from that <key>'s state; settle_s: it then runs on its
    own that long, so a box dropped from the key has landed and come to rest (on the floor,
    its half-size up, nearly still) before the device takes over. Without either: qpos0."""
    toml = GOOD.replace('mjcf = "w.xml"', 'mjcf = "w.xml"\nkeyframe = "high"\nsettle_s = 1.5')
    scene = load_scene(write(tmp_path, toml, xml=DROP_XML))
    model = scene.load_model()
    data = scene.start_data(model)
    box = model.body("box").id
    assert data.xpos[box][0] == pytest.approx(0.1, abs=1e-3)  # the key's x, kept through the drop
    assert data.xpos[box][2] == pytest.approx(0.02, abs=2e-3)  # landed from 0.5 m
    assert abs(data.qvel[2]) < 0.05 and data.time == pytest.approx(1.5, abs=0.002)
    plain = load_scene(write(tmp_path, GOOD, xml=DROP_XML))
    start = plain.start_data(plain.load_model())
    assert tuple(start.xpos[box]) == (0.0, 0.0, 0.3) and start.time == 0.0


def test_a_keyframe_the_model_lacks_is_refused_naming_its_keys(tmp_path):
    toml = GOOD.replace('mjcf = "w.xml"', 'mjcf = "w.xml"\nkeyframe = "home"')
    scene = load_scene(write(tmp_path, toml, xml=DROP_XML))
    with pytest.raises(SceneError, match=r"scene.keyframe 'home' is not a <key> of w.xml; its keys: 'high'"):
        scene.load_model()
    with pytest.raises(SceneError, match=r"scene.settle_s must be"):
        load_scene(write(tmp_path, GOOD.replace('mjcf = "w.xml"', 'mjcf = "w.xml"\nsettle_s = -1')))
