"""Every mistake a user can make on the command line, or in a file it names, ends the command
with exit status 2 and exactly one line on stderr naming the flag, file or field (no
traceback), and is found before a servo loop is built."""

import math
import os
import re
import shutil
import subprocess
import sys

import pytest

import softproxy.run
from softproxy import cli
from softproxy.finger import FingerParams
from softproxy.input_error import UnitWarning
from softproxy.scene import find_scene, load_scene

GRASP = find_scene("two_finger_grasp")


class LoopBuilt(AssertionError):
    """A servo loop was built: the mistake was not found before the run."""


@pytest.fixture
def no_loop(monkeypatch):
    """softproxy.run builds no ServoLoop during the test (a mistake must be found first)."""

    def refuse(*args, **kwargs):
        raise LoopBuilt("a servo loop was built before the mistake was found")

    monkeypatch.setattr(softproxy.run, "ServoLoop", refuse)


@pytest.fixture(scope="module")
def one_finger_recording(tmp_path_factory):
    """A recording of the one-finger knob scene (a real, short run)."""
    path = tmp_path_factory.mktemp("rec") / "knob.rec"
    assert cli.main(["run", "knob", "--headless", "--duration", "0.02", "--record", str(path)]) == 0
    return path


def grasp_variant(tmp_path, toml=(), xml=()) -> str:
    """The two-finger grasp scene copied to tmp_path with text replacements (old, new) in its
    TOML and MJCF; the path of its TOML."""
    text = GRASP.read_text()
    for old, new in toml:
        assert old in text
        text = text.replace(old, new, 1)
    model = GRASP.with_suffix(".xml").read_text()
    for old, new in xml:
        assert old in model
        model = model.replace(old, new, 1)
    (tmp_path / "grasp.xml").write_text(model)
    path = tmp_path / "grasp.toml"
    path.write_text(text.replace('mjcf = "two_finger_grasp.xml"', 'mjcf = "grasp.xml"'))
    return str(path)


def one_line_error(capsys, argv, words):
    """Run `softproxy ARGV`: exit 2, one line on stderr holding every word; that line."""
    try:
        code = cli.main(argv)
    except SystemExit as exc:  # argparse's own errors
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2, (code, err)
    assert "Traceback" not in err
    assert len(err.splitlines()) == 1 and err.endswith("\n"), err
    for w in words:
        assert w in err, (w, err)
    return err


RUN = ["run", "two_finger_grasp", "--headless"]


# (flags after `softproxy run two_finger_grasp --headless`, words the one error line holds)
RUN_FLAG_MISTAKES = [
    *[(["--duration", v], ["--duration", "86400"]) for v in ("nan", "inf", "-1", "0", "-1.5e-05", "1e9")],
    *[(["--rate", v], ["--rate", "10", "100000"]) for v in ("0", "nan", "-5", "9.99", "1e9")],
    (["--faults", "bogus=0.1"], ["--faults", "bogus", "'nan', 'drop'"]),
    (["--faults", "nan=2"], ["--faults", "nan=2", "[0, 1]"]),
    (["--faults", "nan"], ["--faults", "'nan'", "NAME=PROBABILITY"]),
    (["--faults", "nan=0.1", "--device", "replay:x.rec"], ["--faults", "--device sim"]),
    (["--device", "warp"], ["--device warp", "no device type", "sim"]),
    (["--device", "replay:"], ["--device 'replay:'", "replay:run.rec"]),
    (["--device", "replay:MISSING.rec"], ["--device replay:MISSING.rec", "MISSING.rec"]),
    (["--finger-model", "thumb"], ["--finger-model", "thumb"]),
    (["--realtime", "--rt-priority", "0"], ["--rt-priority", "1 to 99", "got 0"]),
    (["--rt-priority", "80"], ["--rt-priority", "--realtime"]),
]


@pytest.mark.parametrize("flags, words", [pytest.param(f, w, id=" ".join(f)) for f, w in RUN_FLAG_MISTAKES])
def test_a_bad_run_flag_is_named(capsys, no_loop, flags, words):
    """A bad flag of `softproxy run` is blamed on the flag, never on the scene file."""
    err = one_line_error(capsys, RUN + flags, words)
    assert "two_finger_grasp.toml" not in err


@pytest.mark.parametrize("flag", ["--snapshot", "--video", "--record"])
def test_an_unwritable_output_is_refused_before_the_run(capsys, no_loop, tmp_path, flag):
    """An output file in a folder that does not exist (or that is a folder) is refused before
    anything runs, naming the flag and the path."""
    missing = str(tmp_path / "no_such_folder" / {"--snapshot": "out.png", "--video": "out.mp4"}.get(flag, "out.rec"))
    one_line_error(capsys, RUN + [flag, missing], [flag, missing, "cannot write"])
    one_line_error(capsys, RUN + [flag, str(tmp_path)], [flag, str(tmp_path), "folder"])
    assert list(tmp_path.iterdir()) == []  # the check left nothing behind


def test_a_writable_output_is_left_as_it_was(capsys, no_loop, tmp_path):
    """The write check (passed here; the run then fails on --device) appends nothing to an
    existing file and removes the file it created."""
    old = tmp_path / "old.rec"
    old.write_bytes(b"keep me")
    one_line_error(capsys, RUN + ["--record", str(old), "--snapshot", str(tmp_path / "new.png"), "--device", "warp"],
                   ["--device warp"])
    assert old.read_bytes() == b"keep me" and sorted(p.name for p in tmp_path.iterdir()) == ["old.rec"]


def test_a_recording_with_fewer_fingers_than_the_scene_is_refused(capsys, no_loop, one_finger_recording):
    """Replaying a one-finger recording into the two-finger grasp would leave the second finger
    without samples: refused, naming the recording, the scene and the finger."""
    one_line_error(capsys, RUN + ["--device", f"replay:{one_finger_recording}"],
                   [str(one_finger_recording), "drives 1 finger", "two_finger_grasp.toml", "'left'", "at least 2"])


@pytest.fixture(scope="module")
def two_finger_recording(tmp_path_factory):
    """A recording of the two-finger grasp (a real, short run)."""
    path = tmp_path_factory.mktemp("rec") / "grasp.rec"
    assert cli.main(["run", "two_finger_grasp", "--headless", "--duration", "0.02", "--record", str(path)]) == 0
    return path


def test_a_recording_with_more_fingers_than_the_scene_drives_is_refused(capsys, no_loop, two_finger_recording):
    """Replaying the two-finger grasp into the one-finger knob would drop a recorded finger
    and render nothing from it: refused, naming the recording, the scene it was made in and
    the finger left over."""
    one_line_error(capsys, ["run", "knob", "--headless", "--device", f"replay:{two_finger_recording}"],
                   [str(two_finger_recording), "holds 2 finger", "'two_finger_grasp'", "'knob'", "finger(s) 1"])


def test_a_replay_at_another_rate_or_into_another_scene_is_noted(capsys, two_finger_recording, tmp_path):
    """A replay that differs from how it was recorded runs, with one note per difference."""
    other = grasp_variant(tmp_path)
    assert cli.main(["run", other, "--headless", "--rate", "500", "--duration", "0.01",
                     "--device", f"replay:{two_finger_recording}"]) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if "note:" in line]
    assert len(notes) == 2, notes
    assert "made in scene 'two_finger_grasp', replayed into 'grasp'" in notes[0]
    assert "1000 Hz, replayed at 500 Hz" in notes[1]
    assert cli.main(["run", "two_finger_grasp", "--headless", "--duration", "0.01",
                     "--device", f"replay:{two_finger_recording}"]) == 0
    assert "note:" not in capsys.readouterr().err


@pytest.mark.parametrize(
    "toml, xml, words",
    [
        ([('object = "box"', 'object = "lid"')], [], ["grasp.toml", "measure.object", "'lid'", "box"]),
        ([], [('integrator="implicitfast"', 'integrator="RK4"')], ["grasp.xml", "RK4", "implicitfast"]),
        ([], [("<asset>", '<extension><plugin plugin="mujoco.sdf.torus"><instance name="torus">'
                          '<config key="radius1" value="0.1"/><config key="radius2" value="0.03"/></instance>'
                          '</plugin></extension><asset><mesh name="torus"><plugin instance="torus"/></mesh>'),
              ('<geom name="floor"', '<geom name="hill" type="sdf" mesh="torus" pos="0.3 0.3 0">'
                                     '<plugin instance="torus"/></geom><geom name="dune" type="sdf" mesh="torus" '
                                     'pos="-0.3 0.3 0"><plugin instance="torus"/></geom><geom name="floor"')],
         ["grasp.xml", "'hill' (sdf)", "'dune' (sdf)", 'exclude = ["hill", "dune"]']),
        ([("[measure]", "deep = " + "[" * 5000 + "]" * 5000 + "\n[measure]")], [], ["grasp.toml", "nested too deeply"]),
        ([("device_finger = 0", "device_finger = 0\ntactile = { cells = 100000 }")], [],
         ["grasp.toml", "finger[0].tactile", "cells", "64"]),
        ([("device_finger = 0", "device_finger = 0\nsensing = { rate_hz = 1e9 }")], [],
         ["grasp.toml", "finger[0].sensing", "rate_hz", "100000"]),
        ([("device_finger = 0", "device_finger = 0\ntactile = { history = 1000000000 }")], [],
         ["grasp.toml", "finger[0].tactile", "history"]),
        ([("duration_s = 4.0", "duration_s = 1e7")], [], ["grasp.toml", "scene.duration_s", "86400"]),
        ([("rate_hz = 1000", "rate_hz = 1e9")], [], ["grasp.toml", "scene.rate_hz", "100000"]),
        ([("[device]", "[device]\nbogus = 1")], [], ["grasp.toml", "device", "bogus"]),
        ([("max_torque_Nm = 1.0", "max_torque_Nm = 1.0\nfaults = { nan = 7 }")], [], ["grasp.toml", "device.faults.nan"]),
        ([("[[device.finger]]", "[[device.fingerz]]")], [], ["grasp.toml", "device"]),
    ],
    ids=["measured-body", "rk4", "sdfs", "deep-toml", "tactile-cells", "sensing-rate", "tactile-history",
         "duration", "rate", "device-field", "device-faults", "device-fingers"],
)
def test_a_scene_mistake_names_the_file_and_field(capsys, no_loop, tmp_path, toml, xml, words):
    """A scene (TOML or MJCF) the loop cannot run: one line naming the file and the culprit."""
    one_line_error(capsys, ["run", grasp_variant(tmp_path, toml, xml), "--headless"], words)


def test_a_scene_driving_more_fingers_than_its_device_scripts_is_refused(capsys, no_loop, tmp_path):
    """A sim [device] with one scripted finger for a two-finger scene: refused naming the scene."""
    text = GRASP.read_text()
    one_finger = text[:text.rindex("[[device.finger]]")]
    path = tmp_path / "grasp.toml"
    path.write_text(one_finger)
    shutil.copy(GRASP.with_suffix(".xml"), tmp_path / "two_finger_grasp.xml")
    one_line_error(capsys, ["run", str(path), "--headless"], [str(path), "[device] drives 1 finger", "'left'"])


# A value past each FingerParams bound, and one inside it, per field (offset: a component).
OVER_BOUNDS = {name: high * 1.5 if high > 0 else 1.0 for name, (_, high, _) in FingerParams.LIMITS.items()}
OVER_BOUNDS.update(damping=1e308, torsion_damping=2e305)


@pytest.mark.parametrize("field", sorted(OVER_BOUNDS))
def test_a_finger_setting_past_its_bound_names_the_file_and_field(capsys, no_loop, tmp_path, field):
    """Every FingerParams field past its bound (damping 1e308, which sent NaN to the device,
    included) is refused at load, naming the scene file, the finger and the field."""
    value = OVER_BOUNDS[field]
    entry = f"offset = [0.0, 0.0, {-value}]" if field == "offset" else f"{field} = {value!r}"
    path = grasp_variant(tmp_path, [("device_finger = 0", f"device_finger = 0\n{entry}")])
    one_line_error(capsys, ["run", path, "--headless"], ["grasp.toml", "finger[0]", field, "at most"])


@pytest.mark.parametrize("field", sorted(FingerParams.LIMITS))
def test_every_finger_bound_is_admitted_and_its_unit_given(field):
    """Each bound itself is a legal value (the bounds catch mistakes, not extremes); just past
    it the message gives the bound with its unit."""
    low, high, unit = FingerParams.LIMITS[field]
    if field == "offset":
        FingerParams(offset=(low, high, 0.0))
        value = {"offset": (0.0, 0.0, math.nextafter(high, math.inf))}
    else:
        extra = {"mu_s": high} if field == "mu_d" else {"torsion_mu_s": high} if field == "torsion_mu_d" else {}
        FingerParams(**{field: high, **extra})
        value = {field: math.nextafter(high, math.inf), **extra}
    u = " " + unit if unit else ""
    expected = (f"offset[2] must be at least {low:g}{u} and at most {high:g}{u}" if field == "offset"  # a component
                else f"{field} must be at most {high:g}{u}")
    with pytest.raises(ValueError, match=re.escape(expected)):
        FingerParams(**value)


def test_the_extremes_the_tests_and_benchmarks_drive_are_admitted():
    """The bounds admit the extreme-but-legal settings of test_extremes and bench stability."""
    FingerParams(stiffness=1e7, damping=0.0, torsion_stiffness=1e6)
    FingerParams(stiffness=10.0, damping=0.0, torsion_stiffness=1e-3)
    FingerParams(stiffness=2000.0, damping=1e3, max_force=1e4)
    FingerParams(radius=0.0, stiffness=1e5, damping=10.0, model="point", max_force=200.0)


# (argv, words the one error line holds)
OTHER_MISTAKES = [
    (["sense", "--wrench", "1", "2"], ["softproxy sense", "--wrench", "6"]),
    (["sense", "--wrench", "nan", "0", "0", "0", "0", "0"], ["softproxy sense", "wrench[0]", "finite"]),
    (["run"], ["softproxy run", "scene"]),
    (["teleport"], ["softproxy", "teleport"]),
    (["bench", "latency", "--duration", "nan"], ["softproxy bench", "--duration"]),
    (["bench", "latency", "--duration", "-1e-3"], ["softproxy bench", "--duration"]),
    (["bench", "latency", "--paced", "1e9"], ["softproxy bench", "--paced", "3600"]),
    (["bench", "warp"], ["softproxy bench", "warp", "latency"]),
    (["tactile", "other"], ["softproxy tactile", "other"]),
    (["calibrate", "--data", "MISSING.csv"], ["softproxy calibrate", "MISSING.csv"]),
]


@pytest.mark.parametrize("argv, words", [pytest.param(a, w, id=" ".join(a)) for a, w in OTHER_MISTAKES])
def test_other_subcommands_mistakes_are_one_line(capsys, argv, words):
    """Every subcommand's argument mistakes (argparse's own included) are one line, exit 2."""
    one_line_error(capsys, argv, words)


@pytest.mark.parametrize("argv", [["tactile", "inoue-hirai"], ["calibrate"], ["bench", "latency", "--duration", "0.01"]])
def test_an_unwritable_out_folder_is_refused_before_the_work(capsys, tmp_path, argv):
    """--out under a regular file (no folder can be made there): one line naming --out, before
    any simulation, fit or benchmark runs (the benchmark's used to end in a traceback)."""
    (tmp_path / "file").write_text("")
    out = str(tmp_path / "file" / "out")
    one_line_error(capsys, argv + ["--out", out], [f"softproxy {argv[0]}", f"--out {out}", "writable folder"])


def test_a_device_type_the_scene_does_not_configure_is_named(capsys, no_loop, tmp_path):
    """--device hid on a scene scripted for the simulated device (and the default sim on a HID
    scene): the flag and the scene are named, with the device type that fits."""
    one_line_error(capsys, RUN + ["--device", "hid"], ["--device hid", "two_finger_grasp.toml", "'sim'", "hid:"])
    path = grasp_variant(tmp_path, [('type = "sim"', 'type = "hid"')])
    one_line_error(capsys, ["run", path, "--headless"], ["--device sim", "grasp.toml", "--device hid"])


def test_a_negative_number_in_scientific_notation_is_a_value(capsys):
    """`sense --wrench -1.5e-05 ...`: argparse's own pattern took -1.5e-05 for an option."""
    assert cli.main(["sense", "--wrench", "-1.5e-05", "0", "-1", "0", "0", "-2E-4", "--json"]) == 0
    assert '"explained"' in capsys.readouterr().out


def test_version(capsys):
    """`softproxy --version` prints the installed version and exits 0."""
    from importlib.metadata import version

    with pytest.raises(SystemExit) as exc:
        cli.main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"softproxy {version('softproxy')}"


@pytest.mark.parametrize("argv", [["models"], ["calibrate", "--out", "{tmp}"]])
def test_a_reader_that_goes_away_ends_the_command_quietly(tmp_path, argv):
    """`softproxy calibrate | head`: the reader closes the pipe; the command ends with
    128 + SIGPIPE and nothing on stderr (it printed a BrokenPipeError traceback)."""
    read_end, write_end = os.pipe()
    os.close(read_end)  # the reader is gone before the first line: every write meets a closed pipe
    try:
        out = subprocess.run([sys.executable, "-m", "softproxy.cli", *(a.format(tmp=tmp_path) for a in argv)],
                             stdout=write_end, stderr=subprocess.PIPE, text=True, timeout=120)
    finally:
        os.close(write_end)
    assert out.stderr == ""
    assert out.returncode == 141


@pytest.mark.parametrize("flags, words", [
    (["--snapshot", "{tmp}/shot.txt"], ["--snapshot", "shot.txt", "ending in .png", "shot.png"]),
    (["--snapshot", "{tmp}/shot"], ["--snapshot", "ending in .png"]),
    (["--video", "{tmp}/run.gif"], ["--video", "run.gif", "ending in .mp4"]),
    (["--record", "{tmp}/same.png", "--snapshot", "{tmp}/same.png"], ["--snapshot and --record both name"]),
])
def test_an_output_of_the_wrong_format_is_refused_before_the_run(capsys, no_loop, tmp_path, flags, words):
    """`--snapshot shot.txt` (it failed with a traceback after the run), a video that is no
    .mp4, two outputs on one file: one line naming the flag before anything runs."""
    one_line_error(capsys, RUN + [f.format(tmp=tmp_path) for f in flags], words)
    assert list(tmp_path.iterdir()) == []


def test_a_recording_claiming_more_than_it_holds_is_refused_before_the_run(capsys, no_loop, one_finger_recording,
                                                                            tmp_path):
    """`softproxy run --device replay:FILE` with an end record claiming 2^40 reads (with valid
    checksums): one line naming the file and the record, exit 2, before any loop is built."""
    import struct

    from softproxy.recording import record_bytes, seal

    data = bytearray(one_finger_recording.read_bytes())
    size = record_bytes(1)
    end = len(data) - size
    struct.pack_into("<qq", data, end + 8, 2**40, 2**40 - 21)  # 21 reads held: the start's and 20 ticks
    seal(data, end, 1, size)
    forged = tmp_path / "forged.rec"
    forged.write_bytes(data)
    one_line_error(capsys, ["run", "knob", "--headless", "--device", f"replay:{forged}"],
                   [f"--device replay:{forged}", "(the end record): claims 1099511627776 reads"])


def _close_stdout() -> None:
    os.close(1)  # in the child, before exec: its stdout is closed, as `softproxy run ... >&-` leaves it


@pytest.mark.parametrize("argv", [["models"], ["run", "knob", "--headless", "--duration", "0.05", "--json"],
                                  ["run", "knob", "--headless", "--duration", "0.05", "--record", "{tmp}/r.rec"]])
def test_a_closed_stdout_ends_quietly(tmp_path, argv):
    """With stdout closed the command runs as asked, prints no traceback (it raised
    AttributeError on sys.stdout.flush) and exits 0; a file it opens does not take stdout's
    number (a recording then replays)."""
    from softproxy.recording import load_recording

    out = subprocess.run([sys.executable, "-m", "softproxy.cli", *(a.format(tmp=tmp_path) for a in argv)],
                         stderr=subprocess.PIPE, text=True, timeout=300, preexec_fn=_close_stdout)
    assert out.returncode == 0 and "Traceback" not in out.stderr, out.stderr
    if "--record" in argv:
        assert load_recording(tmp_path / "r.rec").recovered == 51


def test_run_scene_refuses_a_bad_duration_or_rate_before_building(no_loop):
    """The library entry point checks duration and rate before it builds anything."""
    from softproxy.scene import load_scene

    scene = load_scene("knob")
    for kwargs in ({"duration_s": math.nan}, {"duration_s": -1.0}, {"rate_hz": 0.0}, {"rate_hz": 1e9}):
        with pytest.raises(ValueError, match="duration|rate"):
            softproxy.run.run_scene(scene, None, **kwargs)


def test_an_interrupt_is_one_line(capsys, monkeypatch):
    """Ctrl-C in a subcommand (here `models`): one line and 128 + SIGINT, no traceback."""

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "cmd_models", interrupted)
    assert cli.main(["models"]) == 130
    assert capsys.readouterr().err == "softproxy models: interrupted\n"


def test_keyframes_in_mm_or_degrees_are_warned_of_naming_the_field(capsys, tmp_path):
    """Keyframes typed in mm (60 for 0.06 m) and a twist in degrees (90 for π/2): one warning
    per finger whose first position lies beyond a metre (when the loop starts), one naming the
    twist's keyframe, each with the value and the likely unit; the run goes on (rc 0) and ends
    saying that the fingers never touched anything. On the command line each warning is one
    line, `softproxy: warning: ...`."""
    scene = grasp_variant(tmp_path, toml=[("[0.0, 0.06, 0.02, 0.03, 0.0], [0.5, 0.0265, 0.02, 0.03, 0.0]",
                                           "[0.0, 60.0, 20.0, 30.0, 0.0], [0.5, 26.5, 20.0, 30.0, 90.0]"),
                                          ("[0.0, -0.06, 0.02, 0.03, 0.0], [0.5, -0.0265, 0.02, 0.03, 0.0]",
                                           "[0.0, -60.0, 20.0, 30.0, 0.0], [0.5, -26.5, 20.0, 30.0, 0.0]")])
    with pytest.warns(UnitWarning) as caught:
        assert cli.main(["run", scene, "--headless", "--duration", "0.3"]) == 0
    said = [str(w.message) for w in caught]
    assert said == [f"{scene}: device.finger[0].keyframes[1] twist is 90.0 rad: in degrees? the twist is in rad "
                    "(beyond a full turn)",
                    "device SimulatedDevice finger 0: position is (60.0, 20.0, 30.0) m: in mm? positions are in m, "
                    "and no desktop device reaches a metre",
                    "device SimulatedDevice finger 1: position is (-60.0, 20.0, 30.0) m: in mm? positions are in m, "
                    "and no desktop device reaches a metre"]
    out = capsys.readouterr().out
    assert "  warning: finger 'right' never touched anything" in out and "finger 'left' never touched" in out
    shown = subprocess.run([sys.executable, "-m", "softproxy.cli", "run", scene, "--headless", "--duration", "0.01"],
                           capture_output=True, text=True, timeout=300)
    assert shown.returncode == 0
    assert [line for line in shown.stderr.splitlines() if "warning" in line] == [f"softproxy: warning: {s}" for s in said]


def test_a_run_whose_samples_are_mostly_refused_says_so(tmp_path):
    """Positions beyond the workspace (±1 km: a device reporting in µm, say) are refused as
    garbage on every tick: the run ends cleanly, its result's warnings saying most samples
    were invalid; a clean run has none."""
    scene = grasp_variant(tmp_path, toml=[("[0.0, 0.06, 0.02, 0.03, 0.0], [0.5, 0.0265, 0.02, 0.03, 0.0]",
                                           "[0.0, 6e4, 0.02, 0.03, 0.0], [0.5, 2.65e4, 0.02, 0.03, 0.0]"),
                                          ("[0.0, -0.06, 0.02, 0.03, 0.0], [0.5, -0.0265, 0.02, 0.03, 0.0]",
                                           "[0.0, -6e4, 0.02, 0.03, 0.0], [0.5, -2.65e4, 0.02, 0.03, 0.0]")])
    loaded = load_scene(scene)
    result = softproxy.run.run_scene(loaded, softproxy.run.open_device("sim", loaded), duration_s=0.2)
    assert result["faults"]["invalid_sample"] > 0.5 * result["ticks"] * 2
    assert any(w.startswith(f"{result['faults']['invalid_sample']} of {result['ticks'] * 2} samples were invalid")
               for w in result["warnings"]), result["warnings"]
    clean = load_scene(str(GRASP))
    assert softproxy.run.run_scene(clean, softproxy.run.open_device("sim", clean), duration_s=1.0)["warnings"] == []
