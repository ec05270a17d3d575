"""Batch replays (softproxy.replay_batch, `softproxy replay-batch`): the unvaried replay is the
recorded run, variations change what they vary, the table is the same on every backend, a
broken recording fails alone, resampling is exact where it should be, and bad inputs are one line."""

import csv
import io
import json
import sys

import numpy as np
import pytest

from softproxy import cli
from softproxy.cells import Backend
from softproxy.example_recordings import generate
from softproxy.recording import load_recording
from softproxy.replay_batch import COLUMNS, resample, run_batch, table_text
from softproxy.run import open_device, run_scene
from softproxy.scene import load_scene

VARY = ["model=point", "rate=500", "stiffness=4000"]


@pytest.fixture(scope="module")
def recordings(tmp_path_factory):
    """Three 1.5 s example recordings: two grasps (one with faults) and a knob twist."""
    folder = tmp_path_factory.mktemp("recs")
    generate(folder, count=3, duration_s=1.5, seed=3)
    return folder


@pytest.fixture(scope="module")
def serial(recordings):
    return run_batch([str(recordings)], VARY)


def rows_by(result):
    return {(r["recording"].rsplit("/", 1)[-1], r["variation"]): r for r in result["rows"]}


def test_examples_are_deterministic(recordings, tmp_path):
    """The same arguments write the same files, byte for byte."""
    generate(tmp_path, count=3, duration_s=1.5, seed=3)
    for name in ("000_two_finger_grasp.rec", "001_two_finger_grasp.rec", "002_knob.rec", "recordings.json"):
        assert (tmp_path / name).read_bytes() == (recordings / name).read_bytes(), name
    manifest = json.loads((tmp_path / "recordings.json").read_text())["recordings"]
    assert [m["scene"] for m in manifest] == ["two_finger_grasp", "two_finger_grasp", "knob"]
    assert manifest[1]["faults"] and not manifest[0]["faults"]


def test_unvaried_replay_is_the_recorded_run(tmp_path):
    """The "recorded" row of a lockstep recording says what the recorded run said."""
    scene = load_scene("two_finger_grasp")
    scene.device["noise_m"] = 2e-5
    path = tmp_path / "grasp.rec"
    recorded = run_scene(scene, open_device("sim", scene), duration_s=1.2, record=str(path))
    (row,) = run_batch([str(path)], [])["rows"]
    assert row["status"] == "ok" and row["ticks"] == recorded["ticks"]
    assert row["turned_deg"] == recorded["object_rotation_deg"]
    assert row["max_force_N"] == max(f["max_force_N"] for f in recorded["fingers"])
    assert row["slip_events"] == sum(f["slip_events"] for f in recorded["fingers"])
    assert row["outcome"] == "held"


def test_variations_change_what_they_vary(serial):
    """Against itself the unvaried replay has no error; point contacts let the off-centre box
    turn; rate=500 runs 500 Hz ticks; stiffness changes the rendered force."""
    rows = rows_by(serial)
    assert len(rows) == 3 * 4 and all(r["status"] == "ok" for r in rows.values())
    for name in ("000_two_finger_grasp.rec", "001_two_finger_grasp.rec", "002_knob.rec"):
        ref = rows[(name, "recorded")]
        assert all(ref[c] == 0.0 for c in COLUMNS if c.endswith(("_m", "_deg", "_N", "_Nm")) and "error" in c)
        assert rows[(name, "rate=500")]["rate_hz"] == 500.0
        assert rows[(name, "rate=500")]["ticks"] == round(ref["duration_s"] * 500)
        assert rows[(name, "stiffness=4000")]["force_error_rms_N"] > 0.1
    grasp = rows[("000_two_finger_grasp.rec", "model=point")]
    assert grasp["rotation_error_max_deg"] > 1.0 and grasp["object"] == "box"
    assert rows[("002_knob.rec", "recorded")]["object"] == "knob"
    summary = serial["summary"]["by_variation"]
    assert list(summary) == ["recorded", *VARY] and summary["recorded"]["replays"] == 3


@pytest.mark.slow
@pytest.mark.parametrize("backend", [Backend(workers=2), Backend(ray="")], ids=["pool", "ray"])
def test_table_is_the_same_on_every_backend(serial, recordings, backend):
    """A pool and Ray give the serial table bit for bit (every column but the timings)."""
    if backend.ray is not None:
        pytest.importorskip("ray")
    other = run_batch([str(recordings)], VARY, backend=backend)
    assert table_text(other["rows"], COLUMNS) == table_text(serial["rows"], COLUMNS)
    assert other["summary"]["outcomes_sha256"] == serial["summary"]["outcomes_sha256"]


@pytest.mark.parametrize("damage, says", [
    ("garbage", "broken.rec: record 0 (bytes "),  # a body of 0x07 bytes: checksum mismatch
    ("claim", "broken.rec: record 1501 (the end record): claims 1099511627776 reads"),
    ("bit", "broken.rec: record 700 (bytes "),
])
def test_a_damaged_recording_stops_the_batch_before_it_runs(recordings, tmp_path, capsys, damage, says):
    """A recording with a garbage body, an end record claiming 2^40 reads (decades of replay),
    or one flipped bit: exit 2 and one line naming the file and the record, before any replay."""
    import struct

    from softproxy.recording import record_bytes, seal

    good = recordings / "000_two_finger_grasp.rec"
    data = good.read_bytes()
    head = data.index(b"\n") + 1
    body = bytearray(data[head:])
    size = record_bytes(2)
    if damage == "garbage":
        body = b"\x07" * 1000
    elif damage == "claim":
        assert len(body) == 1502 * size
        struct.pack_into("<qq", body, 1501 * size + 8, 2**40, 2**40 - 1501)
        seal(body, 1501 * size, 1, size)
    else:
        body[700 * size + 50] ^= 0x10
    broken = tmp_path / "broken.rec"
    broken.write_bytes(data[:head] + bytes(body))
    out = tmp_path / "out"
    code = cli.main(["replay-batch", str(good), str(broken), "--vary", "model=point", "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and says in err and err.count("\n") == 1, err
    assert not out.exists() or not list(out.iterdir())


def test_a_recording_too_short_to_replay_fails_alone(recordings, tmp_path, capsys):
    """A sound recording of a single read fails its cells, named with the error; the rest complete;
    the CLI writes the table, chart and summary and exits 1."""
    from softproxy.devices.simulated import SimulatedDevice  # noqa: F401 (the scene's device type)
    from softproxy.recording import RecordingDevice
    from softproxy.device import DeviceSample

    good = recordings / "000_two_finger_grasp.rec"
    broken = tmp_path / "broken.rec"
    scene = load_scene("two_finger_grasp")
    device = open_device("sim", scene)
    with RecordingDevice(device, broken, scene=scene.name, rate_hz=1000.0) as recorder:
        recorder.read(0.0, [DeviceSample(), DeviceSample()])
    out = tmp_path / "out"
    code = cli.main(["replay-batch", str(good), str(broken), "--vary", "model=point", "--out", str(out)])
    assert code == 1
    text = capsys.readouterr().out
    assert "FAILED" in text and "broken.rec" in text
    rows = list(csv.DictReader(io.StringIO((out / "replay_batch.csv").read_text())))
    assert sorted((r["recording"].endswith("broken.rec"), r["variation"], r["status"]) for r in rows) == [
        (False, "model=point", "ok"), (False, "recorded", "ok"),
        (True, "model=point", "failed"), (True, "recorded", "failed")]
    error = next(r["error"] for r in rows if r["status"] == "failed")
    assert error.startswith("RecordingError") and "broken.rec: holds 1 read(s), too few to replay" in error
    summary = json.loads((out / "replay_batch.json").read_text())
    assert len(summary["failed"]) == 2 and summary["by_variation"]["model=point"]["replays"] == 1
    assert (out / "replay_batch.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_resampling(recordings, tmp_path):
    """To the recorded rate: the recording back, bit for bit. To twice the rate: a new read
    halfway between two good records is their mean; a faulty record is held, not blended."""
    rec = load_recording(recordings / "001_two_finger_grasp.rec")  # noise and faults
    resample(rec, 1000.0, 1000.0, rec.reads - 1, tmp_path / "same.rec", "two_finger_grasp")
    same = load_recording(tmp_path / "same.rec")
    assert np.array_equal(same.values, rec.values, equal_nan=True) and np.array_equal(same.valid, rec.valid)
    assert np.array_equal(same.error, rec.error)
    resample(rec, 1000.0, 2000.0, 2 * (rec.reads - 1), tmp_path / "double.rec", "two_finger_grasp")
    double = load_recording(tmp_path / "double.rec")
    assert double.reads == 2 * (rec.reads - 1) + 1
    good = ~rec.error & rec.valid.all(axis=1).astype(bool) & np.isfinite(rec.values).all(axis=(1, 2))
    for k in range(1, rec.reads - 1):  # new read 2k is at recorded read k's time + half a period
        mid = double.values[2 * k, :, 1:4]
        if good[k] and good[k + 1]:
            # within the rounding of the loop clock's times the weights come from (~1e-13 s)
            assert np.allclose(mid, (rec.values[k, :, 1:4] + rec.values[k + 1, :, 1:4]) / 2, atol=1e-12, rtol=0)
        else:
            assert np.array_equal(mid, rec.values[k, :, 1:4], equal_nan=True)
            assert double.error[2 * k] == rec.error[k]
    assert not good.all()  # the faults were there to be held


@pytest.mark.parametrize("argv, says", [
    (["nowhere"], "nowhere: no such file or folder"),
    (["{empty}"], "no recordings (*.rec) in this folder"),
    (["{text}"], "text.rec: line 1 is not a JSON header; replay only recordings made by softproxy run --record"),
    (["{json}"], "other.rec: not a softproxy-recording file"),
    (["{recs}", "--vary", "colour=red"], "unknown setting 'colour'; vary any of model, rate, stiffness"),
    (["{recs}", "--vary", "stiffness=soft"], "stiffness must be a number"),
    (["{recs}", "--vary", "model=rubber"], "model must be one of"),
    (["{recs}", "--vary", "rate=5"], "rate must be a servo rate"),
    (["{recs}", "--vary", "mu_s=0.5"], "give mu_d too"),
    (["{recs}", "--scene", "no_such_scene"], "--scene"),
    (["{recs}", "--workers", "0"], "--workers must be"),
    (["{recs}", "--ray"], "pip install 'softproxy[cluster]'"),
])
def test_bad_inputs_are_one_line(argv, says, recordings, tmp_path, capsys, monkeypatch):
    """Each mistake: exit 2 and one line on stderr naming the path, flag or setting; nothing written."""
    monkeypatch.setitem(sys.modules, "ray", None)
    (tmp_path / "empty").mkdir()
    (tmp_path / "text.rec").write_text("hello\n")
    (tmp_path / "other.rec").write_text('{"format": "csv"}\n1,2,3\n')
    names = {"{empty}": str(tmp_path / "empty"), "{text}": str(tmp_path / "text.rec"),
             "{json}": str(tmp_path / "other.rec"), "{recs}": str(recordings)}
    out = tmp_path / "out"
    assert cli.main(["replay-batch", *[names.get(a, a) for a in argv], "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert says in err and err.count("\n") == 1, err
    assert not out.exists() or not list(out.iterdir())
