"""HID profiles: limits are bounded (non-finite or absurd ones refused at load, naming the file
and the field), and a profile shadowing another of the same name is reported, never silent."""

import io
import json

import pytest

from devices.hid import devices_main
from devices.hid_profile import (
    MAX_FORCE_N,
    MAX_TORQUE_NM,
    PROFILE_DIR,
    PROFILE_PATH_ENV,
    ProfileError,
    Shadowing,
    load_profile,
    load_profiles,
)


# ---------------------------------------------------------------------------------------------
# profiles: bounded limits, shadowing never silent


def _profile_text(**replace):
    text = (PROFILE_DIR / "open_haptic.toml").read_text()
    for old, new in replace.items():
        assert old in text
        text = text.replace(old, new, 1)
    return text


@pytest.mark.parametrize("old,new,field", [
    ("max_force = 5.0", "max_force = 1e6", "max_force"),
    ("max_force = 5.0", "max_force = 100.5", "max_force"),
    ("max_force = 5.0", "max_force = inf", "max_force"),
    ("max_force = 5.0", "max_force = nan", "max_force"),
    ("max_torque = 0.05", "max_torque = 11.0", "max_torque"),
    ("max_torque = 0.05", "max_torque = -inf", "max_torque"),
    ('x = { offset = 4, type = "int32", scale = 1e-6 }', 'x = { offset = 4, type = "int32", scale = 1e4 }',
     "input.report[0].fields.x.scale"),
    ('scale = 1000.0 }', 'scale = 1e10 }', "output.fields.fx.scale"),
    ('scale = 1000.0 }', 'scale = inf }', "output.fields.fx.scale"),
])
def test_profile_limits_are_bounded(tmp_path, old, new, field):
    """Non-finite or absurd limits are refused at load, in one line naming the file and the field."""
    path = tmp_path / "arm.toml"
    path.write_text(_profile_text(**{old: new}))
    with pytest.raises(ProfileError) as exc:
        load_profile(str(path))
    msg = str(exc.value)
    assert msg.startswith(f"{path}: {field} must be ") and "\n" not in msg, msg


def test_profile_limits_at_the_bounds_load(tmp_path):
    """The bounds themselves are allowed, and every shipped profile loads within them."""
    path = tmp_path / "strong.toml"
    path.write_text(_profile_text(**{"max_force = 5.0": f"max_force = {MAX_FORCE_N}",
                                     "max_torque = 0.05": f"max_torque = {MAX_TORQUE_NM}"}))
    p = load_profile(str(path))
    assert (p.max_force, p.max_torque) == (MAX_FORCE_N, MAX_TORQUE_NM)
    for f in PROFILE_DIR.glob("*.toml"):
        p = load_profile(str(f))
        assert p.max_force <= MAX_FORCE_N and p.max_torque <= MAX_TORQUE_NM


def test_shadowing_profile_wins_and_is_reported(tmp_path, monkeypatch):
    """A user profile named like a shipped one is the one used, and load_profiles and
    `softproxy devices` (text and JSON) say which file shadows which; a folder listed twice
    shadows nothing; a broken shadowing profile is an error, not a silent fallback."""
    monkeypatch.delenv(PROFILE_PATH_ENV, raising=False)
    assert load_profiles().shadowing == [] and load_profiles().errors == []

    user = tmp_path / "user"
    user.mkdir()
    (user / "open_haptic.toml").write_text(_profile_text(**{"max_force = 5.0": "max_force = 2.0"}))
    (user / "my_arm.toml").write_text(_profile_text(**{'name = "open_haptic"': 'name = "my_arm"'}))
    monkeypatch.setenv(PROFILE_PATH_ENV, f"{user}{__import__('os').pathsep}{user}")
    found = load_profiles()
    shadow = Shadowing("open_haptic", str(user / "open_haptic.toml"), str(PROFILE_DIR / "open_haptic.toml"))
    assert found.shadowing == [shadow] and found.errors == []
    by_name = {p.name: p for p in found.profiles}
    assert by_name["open_haptic"].max_force == 2.0 and "my_arm" in by_name
    assert load_profile("open_haptic").source == str(user / "open_haptic.toml")

    out, err = io.StringIO(), io.StringIO()
    assert devices_main(False, enumerate_fn=lambda: [], out=out, err=err) == 0
    lines = err.getvalue().splitlines()
    assert len(lines) == 1 and "warning" in lines[0] and "'open_haptic'" in lines[0]
    assert str(user / "open_haptic.toml") in lines[0] and str(PROFILE_DIR / "open_haptic.toml") in lines[0]
    out, err = io.StringIO(), io.StringIO()
    assert devices_main(True, enumerate_fn=lambda: [], out=out, err=err) == 0
    doc = json.loads(out.getvalue())
    assert [(d["name"], d["source"], d["shadowed"]) for d in doc["shadowing"]] == [tuple(shadow)]
    assert "warning" in err.getvalue()

    (user / "open_haptic.toml").write_text(_profile_text(**{"max_force = 5.0": "max_force = 1e6"}))
    found = load_profiles()
    assert found.shadowing == [shadow]
    assert len(found.errors) == 1 and "open_haptic.toml: max_force must be" in found.errors[0]
    assert "open_haptic" not in {p.name for p in found.profiles}  # not replaced by the shipped one silently
    with pytest.raises(ProfileError, match="max_force must be"):
        load_profile("open_haptic")
