"""A file an MJCF names that is not a regular file (a FIFO, a directory, a device) is refused
in one line before MuJoCo opens it: a FIFO would block MuJoCo's loader forever."""

import os
import shutil
import subprocess
import sys
import threading

import pytest

from softproxy.mjcf_files import ModelFileError, check_model_files
from softproxy.scene import SceneError, load_scene

SCENES = os.path.join(os.path.dirname(__file__), "..", "scenes")


@pytest.fixture
def bowl_scene(tmp_path):
    """A copy of the mesh_object scene (its MJCF names meshes/bowl.obj under <compiler meshdir>)."""
    for name in ("mesh_object.toml", "mesh_object.xml"):
        shutil.copy(os.path.join(SCENES, name), tmp_path / name)
    (tmp_path / "meshes").mkdir()
    return tmp_path


def refused(scene_path, seconds=60.0):
    """The SceneError load_model gives, checked to come (a blocked loader would never return)."""
    box = {}

    def target():
        try:
            load_scene(str(scene_path)).load_model()
        except BaseException as exc:  # handed back to the test
            box["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), "load_model blocked: MuJoCo opened a file that is no regular file"
    assert isinstance(box.get("error"), SceneError), box
    message = str(box["error"])
    assert "\n" not in message
    return message


@pytest.mark.parametrize("kind", ["fifo", "directory", "device"])
def test_a_mesh_that_is_no_regular_file_is_refused_before_mujoco_opens_it(bowl_scene, kind):
    """meshes/bowl.obj as a FIFO with no writer, a directory, or a link to /dev/zero: one line
    naming the MJCF, the element and the path."""
    mesh = bowl_scene / "meshes" / "bowl.obj"
    if kind == "fifo":
        os.mkfifo(mesh)
    elif kind == "directory":
        mesh.mkdir()
    else:
        mesh.symlink_to("/dev/zero")
    message = refused(bowl_scene / "mesh_object.toml")
    what = {"fifo": "a FIFO", "directory": "a directory", "device": "a device"}[kind]
    assert f"{bowl_scene / 'mesh_object.xml'}: <mesh file='bowl.obj'> names {mesh}, which is {what}" in message


def test_includes_are_checked_before_they_are_opened_and_their_meshes_too(bowl_scene):
    """An <include> that is a FIFO is refused without opening it; a mesh named in an included
    file is checked like one in the main file."""
    xml = (bowl_scene / "mesh_object.xml").read_text()
    assert '<mesh name="bowl" file="bowl.obj"/>' in xml
    (bowl_scene / "mesh_object.xml").write_text(xml.replace('<mesh name="bowl" file="bowl.obj"/>',
                                                            '</asset><include file="assets.xml"/><asset>'))
    os.mkfifo(bowl_scene / "assets.xml")
    message = refused(bowl_scene / "mesh_object.toml")
    assert "<include file='assets.xml'>" in message and "a FIFO" in message
    os.unlink(bowl_scene / "assets.xml")
    (bowl_scene / "assets.xml").write_text('<mujoco><asset><mesh name="bowl" file="bowl.obj"/></asset></mujoco>')
    os.mkfifo(bowl_scene / "meshes" / "bowl.obj")
    message = refused(bowl_scene / "mesh_object.toml")
    assert f"{bowl_scene / 'assets.xml'}: <mesh file='bowl.obj'>" in message and "a FIFO" in message


def test_regular_and_missing_files_pass_to_mujoco(bowl_scene):
    """The shipped scene's files pass; a missing mesh is left for MuJoCo to name."""
    check_model_files(os.path.join(SCENES, "mesh_object.xml"))
    check_model_files(bowl_scene / "mesh_object.xml")  # meshes/bowl.obj missing: not this check's to name
    with pytest.raises(SceneError, match="MJCF does not compile"):
        load_scene(str(bowl_scene / "mesh_object.toml")).load_model()
    os.mkfifo(bowl_scene / "model.xml")
    with pytest.raises(ModelFileError, match="a FIFO"):
        check_model_files(bowl_scene / "model.xml")


def test_softproxy_run_refuses_a_fifo_mesh_in_one_line(bowl_scene):
    """`softproxy run SCENE --headless` with the bowl a FIFO: exit 2 and one line, not a run
    that hangs in MuJoCo's loader."""
    os.mkfifo(bowl_scene / "meshes" / "bowl.obj")
    done = subprocess.run([sys.executable, "-m", "softproxy.cli", "run", str(bowl_scene / "mesh_object.toml"),
                           "--headless", "--duration", "0.1"], capture_output=True, text=True, timeout=120)
    assert done.returncode == 2 and done.stderr.count("\n") == 1, done.stderr
    assert "bowl.obj" in done.stderr and "a FIFO" in done.stderr
