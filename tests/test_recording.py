"""Record and replay: a lockstep replay reproduces the recorded run; bad files are named and refused."""

import pytest

from devices.replay import ReplayDevice
from softproxy.recording import RecordingError, load_recording
from softproxy.run import open_device, run_scene
from softproxy.scene import load_scene


def without_timing(result):
    return {k: v for k, v in result.items() if k != "tick_us"}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "grasp.rec"
    scene = load_scene("two_finger_grasp")
    scene.device["noise_m"] = 2e-5  # noise makes the samples worth recording exactly
    result = run_scene(scene, open_device("sim", scene), duration_s=1.5, record=str(path))
    return path, result


def test_replay_reproduces_the_recorded_run(recorded):
    path, original = recorded
    scene = load_scene("two_finger_grasp")
    replayed = run_scene(scene, open_device(f"replay:{path}", scene), duration_s=1.5)
    assert without_timing(replayed) == without_timing(original)


def test_file_is_versioned_and_complete(recorded):
    path, _ = recorded
    header, values, flags = load_recording(path)
    assert header["format"] == "softproxy-recording" and header["version"] == 1
    assert values.shape == (1501, 2, 9) and flags[:, :, 1].all()  # start read + 1500 ticks, all valid


@pytest.mark.parametrize(
    "mutate, words",
    [
        (lambda lines: lines[:500], ["truncated", "record 499 "]),  # header + records 0..498 kept
        (lambda lines: lines[:10] + [lines[10].replace(" ", " x", 1)] + lines[11:], ["record 9", "not a number"]),
        (lambda lines: lines[:7] + [" ".join(lines[7].split()[:5])] + lines[8:], ["record 6", "expected 14 fields"]),
        (lambda lines: [lines[0].replace('"version": 1', '"version": 7')] + lines[1:], ["version 7"]),
        (lambda lines: ["garbage"] + lines[1:], ["line 1"]),
        (lambda lines: lines[:3] + [lines[4], lines[3]] + lines[5:], ["record 2", "out of order"]),
    ],
)
def test_corrupt_recordings_are_refused(recorded, tmp_path, mutate, words):
    path, _ = recorded
    bad = tmp_path / "bad.rec"
    bad.write_text("\n".join(mutate(path.read_text().splitlines())) + "\n")
    with pytest.raises(RecordingError) as err:
        ReplayDevice(str(bad))
    message = str(err.value)
    assert "bad.rec" in message
    for w in words:
        assert w in message


def test_device_failures_replay_as_failures(tmp_path):
    """A device that raised on a read raises again on that read of the replay: same faults."""
    from softproxy.device import DeviceError

    scene = load_scene("knob")
    device = open_device("sim", scene)
    original_read = device.read
    calls = {"n": 0}

    def flaky(t, samples):
        calls["n"] += 1
        if calls["n"] in (50, 51, 300):
            raise DeviceError("cable pulled")
        original_read(t, samples)

    device.read = flaky
    path = tmp_path / "knob.rec"
    first = run_scene(scene, device, duration_s=0.5, record=str(path))
    assert first["faults"]["device_error"] == 3 and first["device_error"] == "cable pulled"
    again = run_scene(load_scene("knob"), open_device(f"replay:{path}", scene), duration_s=0.5)
    assert again.pop("device_error") == "the recorded device failed on read 299"  # the replay's own words
    first.pop("device_error")
    assert without_timing(again) == without_timing(first)
