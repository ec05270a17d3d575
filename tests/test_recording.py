"""Record and replay: samples stream to disk as the run goes (a killed run leaves a file that
replays), a lockstep replay reproduces the recorded run, and hostile files are refused in one
line without hanging or allocating what their header claims."""

import errno
import json
import os
import re
import signal
import subprocess
import sys
import textwrap
import threading
import time
import tracemalloc
import zlib

import numpy as np
import pytest

from conftest import ScriptedDevice
from softproxy.devices.replay import ReplayDevice
from softproxy import cli
from softproxy.device import DeviceError, DeviceSample
from softproxy.recording import (MAX_FILE_BYTES, MAX_READS_PER_RECORD, RecordingDevice, RecordingError, load_recording,
                                 record_bytes, seal)
from softproxy.run import open_device, run_scene
from softproxy.scene import SceneError, load_scene

NOISE_M = 2e-5  # noise makes the samples worth recording exactly


def without_timing(result):
    return {k: v for k, v in result.items() if k != "tick_us"}


def grasp_scene():
    scene = load_scene("two_finger_grasp")
    scene.device["noise_m"] = NOISE_M
    return scene


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    path = tmp_path_factory.mktemp("rec") / "grasp.rec"
    scene = grasp_scene()
    result = run_scene(scene, open_device("sim", scene), duration_s=1.5, record=str(path))
    return path, result


def within(seconds, fn, *args):
    """fn(*args) in a daemon thread; fails the test if it is still running after `seconds`."""
    box = {}

    def target():
        try:
            box["value"] = fn(*args)
        except BaseException as exc:  # handed back to the test
            box["error"] = exc

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    thread.join(seconds)
    assert not thread.is_alive(), f"{getattr(fn, '__name__', fn)} still running after {seconds} s: it hangs"
    if "error" in box:
        raise box["error"]
    return box["value"]


def refusal(path, seconds=5.0, peak_bytes=16 << 20):
    """The one-line RecordingError that load_recording gives for `path`, checked to come within
    `seconds` and to allocate less than `peak_bytes` on the way."""
    tracemalloc.start()
    try:
        with pytest.raises(RecordingError) as err:
            within(seconds, load_recording, str(path))
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    message = str(err.value)
    assert "\n" not in message and str(path) in message
    assert peak < peak_bytes, f"refusing {path} allocated {peak} bytes"
    return message


# --- a lockstep replay reproduces the run --------------------------------------------------

def _sigint_by_default() -> None:
    """In the child before exec: SIGINT at its default, as a terminal's Ctrl-C finds it. A
    shell that runs the tests in the background ignores SIGINT, children inherit that, and
    Python then never raises KeyboardInterrupt."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)



def test_replay_reproduces_the_recorded_run(recorded):
    """Replaying the streamed recording in lockstep gives the recorded run's result exactly."""
    path, original = recorded
    scene = load_scene("two_finger_grasp")
    replayed = run_scene(scene, open_device(f"replay:{path}", scene), duration_s=1.5)
    assert without_timing(replayed) == without_timing(original)


def test_file_is_versioned_and_complete(recorded):
    """Version 3 header without a read count, sealed by its CRC-32; the body holds every read and the end record."""
    path, _ = recorded
    rec = load_recording(path)
    line = path.read_bytes().split(b"\n", 1)[0]
    header = json.loads(line)
    assert header["format"] == "softproxy-recording" and header["version"] == 3 and "reads" not in header
    unsealed = {k: v for k, v in header.items() if k != "crc32"}
    assert int(header["crc32"], 16) == zlib.crc32(json.dumps(unsealed).encode())
    assert header["record_bytes"] == record_bytes(2) and header["scene"] == "two_finger_grasp"
    assert rec.values.shape == (1501, 2, 9) and rec.valid.all()  # start read + 1500 ticks, all valid
    assert rec.complete and not rec.truncated and rec.dropped == 0 and rec.reads == rec.recovered == 1501
    assert (rec.index == np.arange(1501)).all()
    assert os.path.getsize(path) == len(path.read_bytes().split(b"\n", 1)[0]) + 1 + 1502 * record_bytes(2)
    print(f"\nlockstep recording: {rec.recovered} reads written, {os.path.getsize(path)} bytes")


def test_device_failures_replay_as_failures(tmp_path):
    """A device that raised on a read raises again on that read of the replay: same faults."""
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


# --- a run that ends badly still leaves its recording ----------------------------------------

KILLED_RUN = textwrap.dedent("""
    import sys, time
    from softproxy.run import open_device, run_scene
    from softproxy.scene import load_scene

    scene = load_scene("two_finger_grasp")
    scene.device["noise_m"] = {noise}

    def paced(loop):  # ~2 ms a tick: slow enough to be killed mid-run
        time.sleep(0.002)
        if loop.ticks % 10 == 0:
            print(loop.ticks, flush=True)

    run_scene(scene, open_device("sim", scene), record=sys.argv[1], on_tick=paced)
""")


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM, signal.SIGINT], ids=lambda s: s.name)
def test_a_killed_run_leaves_a_recording_that_replays(recorded, tmp_path, sig):
    """A recording subprocess killed mid-run by `sig` leaves a file holding at least every read
    on disk before the signal (the writer flushes every 50 ms), the very samples a lockstep
    run reads, and a replay of it reproduces that run; a signal that unwinds (SIGINT) also
    writes the end record."""
    script = tmp_path / "record.py"
    script.write_text(KILLED_RUN.format(noise=NOISE_M))
    path = tmp_path / "killed.rec"
    stderr = open(tmp_path / "stderr.txt", "w+")
    proc = subprocess.Popen([sys.executable, str(script), str(path)], stdout=subprocess.PIPE,
                            preexec_fn=_sigint_by_default,
                            stderr=stderr, text=True, cwd=tmp_path)
    try:
        deadline = time.monotonic() + 600.0  # a hang guard: the child may compile the engine first
        seen = 0
        while seen < 300 and time.monotonic() < deadline:
            line = proc.stdout.readline()
            if not line:
                break
            seen = int(line)
        assert seen >= 300, f"the recording run stopped early: {(tmp_path / 'stderr.txt').read_text()[-2000:]}"
        # the writer flushes every 50 ms; on a loaded machine its thread may run later: wait
        # until the file holds every read up to tick `seen` (what the kill must not lose)
        while time.monotonic() < deadline:
            try:
                if load_recording(path).recovered >= seen + 1:
                    break
            except ValueError:
                pass  # (a header not yet on disk)
            time.sleep(0.05)
        proc.send_signal(sig)
        proc.wait(timeout=20)
        rest = proc.stdout.read().split()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        proc.stdout.close()
        stderr.close()
    last_printed = int(rest[-1]) if rest else seen
    rec = load_recording(path)
    print(f"\n{sig.name}: {seen + 1} reads on disk before the signal, last tick printed {last_printed}; "
          f"recovered {rec.recovered} reads (complete {rec.complete}, truncated {rec.truncated}, "
          f"dropped {rec.dropped})")
    assert seen + 1 <= rec.recovered <= last_printed + 12  # start read + ticks; at most the ticks run since
    assert rec.dropped == 0 and (rec.index == np.arange(rec.recovered)).all()
    if sig == signal.SIGINT:
        assert rec.complete and rec.reads == rec.recovered
    reference = load_recording(recorded[0])
    assert rec.recovered <= reference.recovered
    assert np.array_equal(rec.values, reference.values[:rec.recovered], equal_nan=True)
    duration = (rec.recovered - 1) / 1000.0
    scene = grasp_scene()
    replayed = run_scene(scene, open_device(f"replay:{path}", scene), duration_s=duration)
    scene = grasp_scene()
    direct = run_scene(scene, open_device("sim", scene), duration_s=duration)
    assert without_timing(replayed) == without_timing(direct)


def test_an_exception_in_on_tick_leaves_a_complete_recording(recorded, tmp_path):
    """on_tick raising mid-run propagates, and the file is drained and closed first: every read
    made, the end record, the recorded samples."""
    path = tmp_path / "raised.rec"

    def fail_at_200(loop):
        if loop.ticks == 200:
            raise RuntimeError("the application failed")

    scene = grasp_scene()
    with pytest.raises(RuntimeError, match="the application failed"):
        run_scene(scene, open_device("sim", scene), record=str(path), on_tick=fail_at_200)
    rec = load_recording(path)
    print(f"\non_tick raised at tick 200: recovered {rec.recovered} reads, complete {rec.complete}")
    assert rec.complete and rec.recovered == rec.reads == 201 and rec.dropped == 0
    assert np.array_equal(rec.values, load_recording(recorded[0]).values[:201], equal_nan=True)


def test_samples_reach_the_file_while_the_run_goes(tmp_path):
    """Without any close, the reads made are in the file within two flush intervals."""
    scene = load_scene("knob")
    device = open_device("sim", scene)
    samples = [DeviceSample() for _ in range(device.fingers)]
    recorder = RecordingDevice(device, tmp_path / "open.rec", rate_hz=1000.0)
    try:
        for i in range(300):
            recorder.read(i * 1e-3, samples)
        time.sleep(0.15)
        rec = load_recording(tmp_path / "open.rec")
        assert rec.recovered == 300 and not rec.complete and not rec.truncated
    finally:
        recorder.close()
    assert device.closed and load_recording(tmp_path / "open.rec").complete


def test_a_long_planned_run_allocates_nothing_for_its_length(tmp_path):
    """A run planned for 10^7 s records into a bounded ring: no array sized by the duration."""
    path = tmp_path / "long.rec"

    def stop_at_50(loop):
        if loop.ticks == 50:
            raise RuntimeError("stopped")

    scene = load_scene("knob")
    tracemalloc.start()
    try:
        with pytest.raises(RuntimeError, match="stopped"):
            run_scene(scene, open_device("sim", scene), duration_s=1e7, record=str(path), on_tick=stop_at_50)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    print(f"\n10^7 s planned, stopped at tick 50: peak {peak / 2**20:.1f} MiB traced")
    assert peak < 64 << 20
    assert load_recording(path).recovered == 51


class _Script(ScriptedDevice):
    """A one-finger device reading a counter into x (so each read's sample is known)."""

    def __init__(self):
        self.closed = False

    def read(self, t, samples):
        s = samples[0]
        s.t, s.x, s.valid = t, t * 2.0, True

    def close(self):
        self.closed = True


class _FileWrapper:
    """A recording's file with its writes changed by a subclass; flush and close pass through."""

    def __init__(self, file):
        self.file = file

    def flush(self):
        self.file.flush()

    def close(self):
        self.file.close()


class _StalledFile(_FileWrapper):
    """A file whose first write hangs (a slow disk) until the test releases it, to make the
    writer fall behind for as long as the test needs, however loaded the machine is."""

    def __init__(self, file):
        super().__init__(file)
        self.entered, self.release = threading.Event(), threading.Event()
        self.returned = False  # the stalled write has returned

    def write(self, data):
        if not self.entered.is_set():
            self.entered.set()
            self.release.wait(60.0)  # a read that waited for the writer would wait out this
            self.returned = True
        return self.file.write(data)


def test_a_writer_that_falls_behind_drops_reads_without_blocking_and_says_so(tmp_path):
    """With the writer stuck in a write, the reads go on and those beyond the ring are dropped,
    not waited for (every read returned while the write still hung); the file records the gap
    and the replay fails exactly those reads."""
    path = tmp_path / "behind.rec"
    recorder = RecordingDevice(_Script(), path, rate_hz=100.0, buffer_s=1.0)  # a 256-read ring
    stalled = recorder._writer.file = _StalledFile(recorder._writer.file)
    samples = [DeviceSample()]
    with recorder:
        for i in range(10):
            recorder.read(i * 1e-3, samples)
        assert stalled.entered.wait(30.0), "the writer never took the first reads"
        for i in range(10, 2000):
            recorder.read(i * 1e-3, samples)
        hung_throughout = not stalled.returned
        stalled.release.set()
    rec = load_recording(path)
    print(f"\nwriter stalled: {rec.recovered} reads written, {rec.dropped} dropped")
    assert hung_throughout  # no read waited for the writer
    # the ring's 256 records held the first reads (those in the hung write among them); the rest were dropped
    assert rec.reads == 2000 and rec.recovered == 256 and recorder.dropped == rec.dropped == 1744
    assert np.array_equal(rec.values[:, 0, 1], rec.index * 2e-3)  # each record is the read it claims
    replay = ReplayDevice(str(path))
    kept = set(rec.index.tolist())
    failed = []
    for i in range(2000):
        try:
            replay.read(i * 1e-3, samples)
            assert samples[0].x == i * 2e-3
        except DeviceError as exc:
            assert "not recorded" in str(exc)
            failed.append(i)
    assert failed == [i for i in range(2000) if i not in kept]


class _FullAfterHeader(_FileWrapper):
    """A file that takes the header line, then fails every write as a full disk does."""

    def __init__(self, file):
        super().__init__(file)
        self.header_written = False

    def write(self, data):
        if self.header_written:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        self.header_written = True
        return self.file.write(data)


def test_a_full_disk_stops_the_recording_not_the_run(tmp_path, monkeypatch):
    """Writes failing mid-run: the run goes to its end, then run_scene says in one line that
    --record failed and why; the file keeps what was written before (here the header)."""
    import softproxy.recording as recording

    opened = recording._open_for_writing
    monkeypatch.setattr(recording, "_open_for_writing", lambda path: _FullAfterHeader(opened(path)))
    path = tmp_path / "full.rec"
    scene = load_scene("knob")
    device = open_device("sim", scene)
    with pytest.raises(SceneError) as err:
        run_scene(scene, device, duration_s=0.3, record=str(path))
    assert str(err.value) == (f"--record {path}: writing the recording failed after 0 reads: "
                              f"{os.strerror(errno.ENOSPC)}")
    assert device.sends > 0  # the run itself went on
    rec = load_recording(path)
    assert rec.recovered == 0 and not rec.complete


def test_odd_sample_types_are_recorded_not_raised(tmp_path):
    """A device filling samples with ints, numpy scalars or a float bit field is recorded (the
    record's types), never an exception in the tick."""

    class Odd(_Script):
        def read(self, t, samples):
            s = samples[0]
            s.t, s.x, s.y, s.z, s.buttons, s.valid = t, np.float32(0.5), 3, None, 2.0, np.bool_(True)

    path = tmp_path / "odd.rec"
    with RecordingDevice(Odd(), path) as recorder:
        recorder.read(0.25, [DeviceSample()])
    rec = load_recording(path)
    assert rec.values[0, 0, :4].tolist()[:3] == [0.25, 0.5, 3.0] and np.isnan(rec.values[0, 0, 3])
    assert rec.buttons[0, 0] == 2 and rec.valid[0, 0] == 1


def test_a_recording_left_open_is_finished_by_its_finaliser(tmp_path):
    """A RecordingDevice dropped without close() still writes its end record."""
    import gc

    path = tmp_path / "dropped.rec"
    recorder = RecordingDevice(_Script(), path)
    for i in range(10):
        recorder.read(i * 1e-3, [DeviceSample()])
    del recorder
    gc.collect()
    rec = load_recording(path)
    assert rec.complete and rec.recovered == 10


def test_an_unwritable_record_path_fails_before_the_run_in_one_line(tmp_path, capsys):
    """--record into a missing directory or onto a directory: one line naming the path, exit 2,
    and the device was never read."""
    scene = load_scene("knob")
    device = open_device("sim", scene)
    for bad in (tmp_path / "no" / "such.rec", tmp_path):
        with pytest.raises(SceneError, match=re.escape(f"--record {bad}: ")):
            run_scene(scene, device, duration_s=0.1, record=str(bad))
    assert device.sends == 0
    code = cli.main(["run", "knob", "--headless", "--record", str(tmp_path / "no" / "such.rec")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "such.rec" in err and "No such file" in err


# --- hostile and damaged files ----------------------------------------------------------------


def v3_file(tmp_path, recorded, name="bad.rec"):
    """A copy of the recorded file: (path, header bytes, records as a bytearray)."""
    data = recorded[0].read_bytes()
    cut = data.index(b"\n") + 1
    return tmp_path / name, data[:cut], bytearray(data[cut:])


def v2_file(tmp_path, recorded, name="bad.rec"):
    """The recorded file as version 2 wrote it (no checksums): (path, header bytes, records)."""
    path, header, records = v3_file(tmp_path, recorded, name)
    old = {k: v for k, v in json.loads(header).items() if k != "crc32"}
    old.update(version=2, record_bytes=record_bytes(2, 2))
    size = record_bytes(2)
    body = bytearray()
    for k in range(len(records) // size):
        body += records[k * size:(k + 1) * size - 8]  # without the crc32 and its 4 zero bytes
    return path, json.dumps(old).encode() + b"\n", body


def write_v1(path, rec):
    """A version-1 text file of a recording (the format softproxy wrote before streaming)."""
    reads, fingers = rec.values.shape[:2]
    lines = [json.dumps({"format": "softproxy-recording", "version": 1, "fingers": fingers, "reads": reads,
                         **{k: rec.header[k] for k in ("scene", "rate_hz")}})]
    for i in range(reads):
        for f in range(fingers):
            floats = " ".join(repr(float(v)) for v in rec.values[i, f])
            lines.append(f"{i} {f} {floats} {rec.buttons[i, f]} {rec.valid[i, f]} {int(rec.error[i])}")
    path.write_text("\n".join(lines) + "\n")
    return lines


def test_version_1_files_still_replay(recorded, tmp_path):
    """A version-1 text recording of the run replays to the same result."""
    path, original = recorded
    old = tmp_path / "old.rec"
    write_v1(old, load_recording(path))
    rec = load_recording(old)
    assert rec.recovered == 1501 and rec.complete and np.array_equal(rec.values, load_recording(path).values)
    scene = load_scene("two_finger_grasp")
    replayed = run_scene(scene, open_device(f"replay:{old}", scene), duration_s=1.5)
    assert without_timing(replayed) == without_timing(original)


@pytest.mark.parametrize(
    "mutate, words",
    [
        (lambda lines: lines[:500], ["truncated", "record 499 "]),  # header + records 0..498 kept
        (lambda lines: lines[:10] + [lines[10].replace(" ", " x", 1)] + lines[11:], ["record 9", "not a number"]),
        (lambda lines: lines[:7] + [" ".join(lines[7].split()[:5])] + lines[8:], ["record 6", "expected 14 fields"]),
        (lambda lines: [lines[0].replace('"version": 1', '"version": 7')] + lines[1:], ["version 7"]),
        (lambda lines: ["garbage"] + lines[1:], ["line 1"]),
        (lambda lines: lines[:3] + [lines[4], lines[3]] + lines[5:], ["record 2", "out of order"]),
        (lambda lines: [lines[0].replace('"reads": 1501', '"reads": 1000000000000')] + lines[1:], ["truncated"]),
        (lambda lines: lines + lines[-2:], ["more records than the header's 1501 reads"]),
    ],
)
def test_corrupt_version_1_recordings_are_refused(recorded, tmp_path, mutate, words):
    """Damaged version-1 files: one line naming the file and the first bad record; a header
    claiming 10^12 reads allocates nothing for them."""
    lines = write_v1(tmp_path / "v1.rec", load_recording(recorded[0]))
    bad = tmp_path / "bad.rec"
    bad.write_text("\n".join(mutate(lines)) + "\n")
    message = refusal(bad)
    for w in words:
        assert w in message


def _put(records, k, offset, fmt, value, size=record_bytes(2, 2)):
    import struct

    struct.pack_into(fmt, records, k * size + offset, value)


CORRUPT_BODIES = pytest.mark.parametrize(
    "mutate, words",
    [
        (lambda r: _put(r, 7, 0, "<I", 9), ["record 7 ", "kind"]),
        (lambda r: _put(r, 12, 4, "<I", 3), ["record 12 ", "error must be 0 or 1"]),
        (lambda r: _put(r, 30, 16 + 88 + 80, "<B", 7), ["record 30 ", "valid must be 0 or 1"]),
        (lambda r: _put(r, 40, 8, "<q", 39), ["record 40 ", "out of order"]),
        (lambda r: _put(r, 0, 8, "<q", -5), ["record 0 ", "negative"]),
        (lambda r: _put(r, 1501, 16, "<q", 3), ["record 1501 ", "end record"]),  # the end record's dropped count
        (lambda r: _put(r, 900, 0, "<I", 2), ["record 900 ", "kind"]),  # an end record in the middle
        (lambda r: r.extend(b"\0" * 10), ["bytes after the end record"]),
        (lambda r: r.__setitem__(slice(0, None), b"\xff" * len(r)), ["record 0 "]),  # garbage body
    ],
)


@CORRUPT_BODIES
def test_corrupt_version_2_recordings_are_refused(recorded, tmp_path, mutate, words):
    """Damaged binary bodies of the older format: one line naming the file and the first bad record."""
    path, header, records = v2_file(tmp_path, recorded)
    mutate(records)
    path.write_bytes(header + records)
    message = refusal(path)
    for w in words:
        assert w in message


@CORRUPT_BODIES
def test_forged_version_3_records_are_refused_and_damaged_ones_named(recorded, tmp_path, mutate, words):
    """The same damage in version 3: as it is, the first changed record's checksum names it;
    resealed with valid checksums (a forgery, not a flipped bit), the record's contents are
    still checked and the first bad one named."""
    path, header, records = v3_file(tmp_path, recorded)
    size = record_bytes(2)
    v2_size = record_bytes(2, 2)
    shifted = bytearray(len(records))  # the mutation's offsets are version 2's: apply it per record
    whole = len(records) // size
    flat = bytearray(b"".join(bytes(records[k * size:(k + 1) * size - 8]) for k in range(whole)))
    mutate(flat)
    if len(flat) != whole * v2_size:  # bytes appended after the end record
        tail = flat[whole * v2_size:]
        flat = flat[:whole * v2_size]
    else:
        tail = b""
    for k in range(whole):
        shifted[k * size:(k + 1) * size - 8] = flat[k * v2_size:(k + 1) * v2_size]
        shifted[(k + 1) * size - 8:(k + 1) * size] = records[(k + 1) * size - 8:(k + 1) * size]
    changed = next((k for k in range(whole) if shifted[k * size:(k + 1) * size] != records[k * size:(k + 1) * size]),
                   None)
    path.write_bytes(header + shifted + tail)
    message = refusal(path)
    if changed is not None:
        assert f"record {changed} (bytes " in message and "checksum mismatch" in message
    seal(shifted, 0, whole, size)
    path.write_bytes(header + shifted + tail)
    message = refusal(path)
    for w in words:
        assert w in message


def test_every_flipped_bit_of_a_recording_is_found_and_named(tmp_path):
    """Each single-bit flip of a version-3 file (every bit of its header, 300 random bits of
    its records, every bit of its end record) is refused in one line naming the header or the
    record that holds the flipped bit; version 2 accepted 186 of 200 such flips."""
    path = tmp_path / "small.rec"
    with RecordingDevice(_Script(), path, rate_hz=1000.0) as recorder:
        for i in range(40):
            recorder.read(i * 1e-3, [DeviceSample()])
    data = path.read_bytes()
    head = data.index(b"\n") + 1
    size = record_bytes(1)
    assert len(data) == head + 41 * size and load_recording(path).recovered == 40
    rng = np.random.default_rng(49)
    bits = [*range(head * 8), *rng.integers(head * 8, len(data) * 8, 300).tolist(),
            *range((len(data) - size) * 8, len(data) * 8)]
    flipped = tmp_path / "flipped.rec"
    for bit in bits:
        damaged = bytearray(data)
        damaged[bit // 8] ^= 1 << (bit % 8)
        flipped.write_bytes(damaged)
        with pytest.raises(RecordingError) as err:
            load_recording(flipped)
        message = str(err.value)
        assert "\n" not in message and str(flipped) in message
        if bit // 8 < head:
            assert "header" in message or "line 1" in message, (bit, message)
        else:
            k = (bit // 8 - head) // size
            assert f"record {k} (bytes {head + k * size}-{head + (k + 1) * size - 1})" in message, (bit, message)


def test_a_truncated_last_record_is_dropped_and_reported(recorded, tmp_path):
    """A file cut mid-record (a kill mid-write) replays its whole records; `truncated` says so."""
    path, header, records = v3_file(tmp_path, recorded)
    path.write_bytes(header + records[:700 * record_bytes(2) + 50])
    rec = load_recording(path)
    assert rec.truncated and not rec.complete and rec.recovered == rec.reads == 700 and rec.dropped == 0
    replay = ReplayDevice(str(path))
    assert replay.truncated and replay.recovered == 700


def test_claims_in_a_header_or_record_allocate_nothing(recorded, tmp_path):
    """A v2 header claiming 10^12 reads is ignored (the body counts); a record claiming a later
    read is a gap of dropped reads, replayed as failures without an array for them."""
    path, header, records = v2_file(tmp_path, recorded)
    claim = json.loads(header)
    claim["reads"] = 10**12
    size = record_bytes(2, 2)
    body = records[:5 * size]
    gap = 5 * MAX_READS_PER_RECORD - 1  # the largest last read 5 records may claim
    _put(body, 4, 8, "<q", gap)
    path.write_bytes(json.dumps(claim).encode() + b"\n" + body)
    tracemalloc.start()
    try:
        rec = within(5.0, load_recording, str(path))
        replay = ReplayDevice(str(path))
        samples = [DeviceSample(), DeviceSample()]
        for _ in range(4):
            replay.read(0.0, samples)
        with pytest.raises(DeviceError, match="read 4 was not recorded"):
            replay.read(0.0, samples)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert rec.recovered == 5 and rec.reads == gap + 1 and rec.dropped == gap - 4
    assert peak < 1 << 20


@pytest.mark.parametrize("version", [2, 3])
@pytest.mark.parametrize("where, claim, words", [
    ("end", 2**40, ["record 1501 (the end record)", f"claims {2**40} reads", "holds 1501 read records"]),
    ("end", 1501 * MAX_READS_PER_RECORD + 1, ["the end record", "holds 1501 read records"]),
    ("last", 10**12, ["record 1500", f"claims {10**12 + 1} reads"]),
])
def test_a_recordings_claims_are_bounded_by_what_the_file_holds(recorded, tmp_path, version, where, claim, words):
    """An end record claiming 2^40 reads (decades of replay), or a last read far past the
    records: refused in one line naming the record, at once, allocating nothing for the claim.
    The end record's claim is forged consistently (dropped = reads - held), with valid checksums."""
    import struct

    path, header, records = (v2_file if version == 2 else v3_file)(tmp_path, recorded)
    size = record_bytes(2, version)
    if where == "end":
        struct.pack_into("<qq", records, 1501 * size + 8, claim, claim - 1501)
    else:
        records = records[:1501 * size]  # no end record (a killed run): the last read index is the claim
        struct.pack_into("<q", records, 1500 * size + 8, claim)
    if version == 3:
        seal(records, 0, len(records) // size, size)
    path.write_bytes(header + records)
    message = refusal(path)
    for w in words:
        assert w in message, message


def test_a_recording_may_claim_no_more_than_a_day_at_its_rate(tmp_path):
    """A recording spanning more than 24 h of reads at its header's rate is refused, even with
    enough records to make its gaps plausible (here 10 records claiming 144 reads at 0.001 Hz)."""
    path = tmp_path / "slow.rec"
    with RecordingDevice(_Script(), path, rate_hz=0.001) as recorder:
        for i in range(10):
            recorder.read(float(i), [DeviceSample()])
    assert load_recording(path).reads == 10
    data = bytearray(path.read_bytes())
    head = data.index(b"\n") + 1
    size = record_bytes(1)
    import struct

    struct.pack_into("<qq", data, head + 10 * size + 8, 100, 90)  # 100 reads: 1e5 s at 0.001 Hz
    seal(data, head + 10 * size, 1, size)
    path.write_bytes(data)
    message = refusal(path)
    assert "record 10 (the end record)" in message and "86400 s" in message


def test_what_is_not_a_recording_file_is_refused_in_one_line(recorded, tmp_path):
    """A FIFO (no writer: opening it must not wait), /dev/zero, a directory, random bytes, a
    header line with no end, a huge finger count, a file over the size bound: each refused at
    once in one line, without reading the body."""
    fifo = tmp_path / "fifo.rec"
    os.mkfifo(fifo)
    assert "not a regular file" in refusal(fifo)
    assert "not a regular file" in refusal("/dev/zero")
    assert "is a directory" in refusal(tmp_path)
    assert "cannot read" in refusal(tmp_path / "missing.rec")
    noise = tmp_path / "noise.rec"
    noise.write_bytes(np.random.default_rng(5).integers(0, 256, 100_000, dtype=np.uint8).tobytes().replace(b"\n", b"."))
    assert "line 1 is not a JSON header" in refusal(noise)
    binary = tmp_path / "binary.rec"
    binary.write_bytes(b"\xff\xfe\x00garbage\n" + b"\x00" * 1000)
    assert "line 1 is not a JSON header" in refusal(binary)
    path, header, records = v2_file(tmp_path, recorded, "fingers.rec")
    claim = json.loads(header)
    claim["fingers"] = 10**9
    path.write_bytes(json.dumps(claim).encode() + b"\n" + records)
    assert "fingers must be an integer from 1 to 16, got 1000000000" in refusal(path)
    big = tmp_path / "big.rec"
    with open(big, "wb") as out:  # sparse: no disk used
        out.write(header)
        out.truncate(MAX_FILE_BYTES + 1)
    assert "over the" in refusal(big)
    for bad in (fifo, "/dev/zero", tmp_path):  # the device says the same through --device replay:
        with pytest.raises(RecordingError):
            within(5.0, ReplayDevice, str(bad))
