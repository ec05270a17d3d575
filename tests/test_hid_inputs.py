"""HID profiles as untrusted input and HID output as what a motor renders: a profile with any
wrong type in any field, or a file that is not UTF-8, is one line naming the file and the
field (from `softproxy run --device hid:PROFILE` and from `softproxy devices`), and an
output report never decodes to more than the clamp, not even by a rounding."""

import copy
import math
import tomllib

import numpy as np
import pytest

from softproxy import cli
from softproxy.devices.hid_profile import (
    PROFILE_DIR,
    PROFILE_PATH_ENV,
    ProfileError,
    build_output,
    load_profile,
    parse_output,
    parse_profile,
)

SHIPPED = sorted(PROFILE_DIR.glob("*.toml"))
WRONG = [["int16"], {"a": 1}, 7, -1, 2.5, math.nan, True, "nonsense", [], {}]
"""Values of the wrong type (or out of range) for any field of a profile."""


def paths(doc, prefix=()):
    """Every (path, value) of a parsed TOML document: tables, arrays and leaves."""
    items = doc.items() if isinstance(doc, dict) else enumerate(doc) if isinstance(doc, list) else ()
    for key, value in items:
        yield (*prefix, key), value
        yield from paths(value, (*prefix, key))


def replaced(doc, path, value):
    out = copy.deepcopy(doc)
    node = out
    for key in path[:-1]:
        node = node[key]
    node[path[-1]] = value
    return out


@pytest.mark.parametrize("profile", SHIPPED, ids=lambda p: p.stem)
def test_any_wrong_type_anywhere_in_a_profile_is_a_profile_error(profile):
    """Each field, table and array of the shipped profiles replaced by a list, a table, a
    number, a bool or a string: the profile loads or is refused by ProfileError in one line
    naming the file; never a TypeError or another exception (a list where a type name goes
    was a TypeError from a dict lookup)."""
    doc = tomllib.loads(profile.read_text())
    tried = refused = 0
    for path, _ in list(paths(doc)):
        for value in WRONG:
            tried += 1
            try:
                parse_profile(replaced(doc, path, value), str(profile))
            except ProfileError as exc:
                refused += 1
                assert str(exc).startswith(f"{profile}: ") and "\n" not in str(exc)
    assert refused > tried // 2  # most of these are mistakes, and were found


def write_profile(tmp_path, name, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


@pytest.fixture
def broken_profiles(tmp_path):
    """A profile with a list where a field's type name goes, and one that is not UTF-8."""
    text = (PROFILE_DIR / "open_haptic.toml").read_text()
    assert 'x = { offset = 4, type = "int32"' in text
    listed = write_profile(tmp_path, "listed.toml", text.replace('x = { offset = 4, type = "int32"',
                                                                 'x = { offset = 4, type = ["int32"]').encode())
    latin = write_profile(tmp_path, "latin.toml", text.replace("micrometres", "µm").encode("latin-1"))
    return listed, latin


def test_run_names_the_profile_file_and_field_in_one_line(broken_profiles, capsys):
    """`softproxy run --device hid:PROFILE`: exit 2, one line naming the file and the field (or
    the byte that is not UTF-8), no traceback, no device opened."""
    listed, latin = broken_profiles
    assert cli.main(["run", "two_finger_grasp", "--headless", "--device", f"hid:{listed}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{listed}: input.report[0].fields.x.type must be one of" in err
    assert "got ['int32']" in err
    assert cli.main(["run", "two_finger_grasp", "--headless", "--device", f"hid:{latin}"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"{latin}: not UTF-8 text (byte " in err and "0xb5" in err


def test_devices_lists_broken_profiles_in_one_line_each(broken_profiles, monkeypatch, capsys):
    """`softproxy devices` with the broken profiles on the search path: one line each naming the
    file and what is wrong, the shipped profiles still listed, exit 0."""
    listed, latin = broken_profiles
    monkeypatch.setenv(PROFILE_PATH_ENV, str(listed.parent))
    assert cli.main(["devices"]) == 0
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert any(f"{listed}: input.report[0].fields.x.type" in line for line in lines), captured.err
    assert any(f"{latin}: not UTF-8 text" in line for line in lines), captured.err
    assert "Traceback" not in captured.err and "open_haptic" in captured.out


def test_an_oversized_profile_is_refused_unread(tmp_path):
    """A profile file over 1 MiB is not parsed (a profile is a short file)."""
    path = write_profile(tmp_path, "huge.toml", b"# " + b"x" * (2 << 20) + b"\n")
    with pytest.raises(ProfileError, match="over 1048576 bytes"):
        load_profile(str(path))


def decoded(profile, report):
    """The force (N) and torque (N·m) vectors an output report renders, from its decoded fields."""
    back = parse_output(profile, report)
    force, torque = np.zeros(3), np.zeros(3)
    for f in profile.output.fields:
        if f.source in ("fx", "fy", "fz"):
            force["xyz".index(f.source[1])] += back[f.name]
        elif f.source in ("tx", "ty", "tz"):
            torque["xyz".index(f.source[1])] += back[f.name]
        elif f.source == "twist":
            torque += back[f.name] * np.asarray(profile.finger_axis)
    return force, torque


@pytest.mark.parametrize("name", ["open_haptic", "open_haptic_rawhid"])
def test_output_reports_never_decode_over_the_clamp(name):
    """40,000 random wrenches, most of them over the limits (the clamp's direction then decides
    every count), some just under: the decoded |F| is never over max_force, |T| never over
    max_torque, nor over a lower limit the caller gives (counts round toward zero; rounding to
    nearest gave 5.0001 N against a 5 N clamp)."""
    profile = load_profile(name)
    rng = np.random.default_rng(49)
    worst_force = worst_torque = 0.0
    for k in range(40_000):
        direction = rng.normal(size=6)
        direction[:3] /= np.linalg.norm(direction[:3])
        direction[3:] /= np.linalg.norm(direction[3:])
        scale = rng.choice([rng.uniform(0.9, 1.0), rng.uniform(1.0, 20.0), 1.0 - 1e-9])
        fmax = profile.max_force if k % 4 else rng.uniform(0.1, profile.max_force)  # a derated device too
        tmax = profile.max_torque if k % 4 else rng.uniform(0.0, profile.max_torque)
        wrench = np.concatenate([direction[:3] * fmax * scale, direction[3:] * tmax * scale])
        report = build_output(profile, k, *wrench, max_force=fmax, max_torque=tmax)
        force, torque = decoded(profile, report)
        worst_force = max(worst_force, np.linalg.norm(force) / fmax)
        assert np.linalg.norm(force) <= fmax, (k, wrench, force)
        if tmax > 0:
            worst_torque = max(worst_torque, np.linalg.norm(torque) / tmax)
        assert np.linalg.norm(torque) <= tmax, (k, wrench, torque)
    assert worst_force > 0.999  # the clamp was reached, not avoided
    print(f"\n{name}: largest decoded |F| / clamp {worst_force:.9f}, |T| / clamp {worst_torque:.9f}")


def test_float32_fields_round_toward_zero(tmp_path):
    """A float32 output field carries the float32 at or inside the value: 1/3 N is sent as
    0.33333331 N, not 0.33333334, and the largest force sent is at most the clamp."""
    text = (PROFILE_DIR / "open_haptic.toml").read_text()
    text = text.replace('fx = { offset = 4, type = "int16", source = "fx", scale = 1000.0 }', "")
    text = text.replace("size = 12\n[output.fields]", 'size = 16\n[output.fields]\n'
                        'fx = { offset = 12, type = "float32", source = "fx", scale = 1.0 }')
    path = write_profile(tmp_path, "float.toml", text.encode())
    profile = load_profile(str(path))
    third = parse_output(profile, build_output(profile, 0, 1 / 3, 0, 0, 0, 0, 0))["fx"]
    assert 0 < third <= 1 / 3 and np.float32(third) == third and float(np.nextafter(np.float32(third), np.float32(1))) > 1 / 3
    for fx in np.random.default_rng(3).uniform(-20, 20, 2000):
        sent = parse_output(profile, build_output(profile, 0, fx, 0, 0, 0, 0, 0))["fx"]
        assert abs(sent) <= min(abs(fx), profile.max_force)
