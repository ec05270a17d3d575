"""The declared schema of every input (softproxy.schema): the JSON Schema `softproxy schema`
writes accepts every shipped scene, profile and [device] table and refuses malformed ones;
the declarations agree with the modules that use them; errors are one line with the fix."""

import copy
import functools
import json
import operator
import tomllib

import jsonschema
import pytest

from softproxy import cli, schema
from softproxy.devices import device_config, hid_profile, simulated
from softproxy.devices.hid_profile import PROFILE_DIR
from softproxy.finger import FingerParams
from softproxy.scene import SceneError, list_scenes, load_scene

SCENES = list_scenes()
PROFILES = sorted(PROFILE_DIR.glob("*.toml"))


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """The files `softproxy schema --out DIR` wrote, parsed: file name -> validator."""
    out = tmp_path_factory.mktemp("schema")
    assert cli.main(["schema", "--out", str(out)]) == 0
    validators = {}
    for path in sorted(out.iterdir()):
        js = json.loads(path.read_text(encoding="utf-8"))
        jsonschema.Draft202012Validator.check_schema(js)  # a schema an editor can load
        validators[path.name] = jsonschema.Draft202012Validator(js)
    assert set(validators) == {"scene.schema.json", "hid_profile.schema.json", "device.schema.json"}
    return validators


def toml(path):
    return tomllib.loads(path.read_text(encoding="utf-8"))


def errors(validator, doc) -> list[str]:
    return [e.message for e in validator.iter_errors(doc)]


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_the_written_schema_accepts_every_shipped_scene(written, path):
    doc = toml(path)
    assert errors(written["scene.schema.json"], doc) == []
    tables = doc["device"] if isinstance(doc["device"], list) else [doc["device"]]  # [[device]]: one per device
    for table in tables:
        assert errors(written["device.schema.json"], table) == []


@pytest.mark.parametrize("path", PROFILES, ids=lambda p: p.stem)
def test_the_written_schema_accepts_every_shipped_profile(written, path):
    assert errors(written["hid_profile.schema.json"], toml(path)) == []


def _mutated(doc, path, value):
    """A deep copy of `doc` with the value at `path` (keys and indices) set."""
    out = copy.deepcopy(doc)
    functools.reduce(operator.getitem, path[:-1], out)[path[-1]] = value
    return out


# (where in the grasp scene, the wrong value, what the loader's one line must hold)
MALFORMED_SCENES = [
    (("finger", 0, "stiffness"), 2.0, ["finger[0].stiffness", "between 10 and 1e+08 N/m", "N/mm"]),
    (("finger", 0, "radius"), 8.0, ["finger[0].radius", "at most 0.1 m", "8 mm is 0.008"]),
    (("finger", 0, "stifness"), 5.0, ["finger[0] has unknown field(s) ['stifness']"]),
    (("finger", 0, "tactile"), "yes", ["finger[0].tactile must be true, false or a table, got 'yes'"]),
    (("finger", 0, "tactile"), {"cells": 100000}, ["finger[0].tactile.cells must be at most 64, got 100000"]),
    (("scene", "rate_hz"), 1, ["scene.rate_hz must be between 10 and 100000 Hz", "1 kHz is 1000"]),
    (("haptics",), {"mesh_surface": "smooth"}, ["haptics.mesh_surface must be one of 'true', 'hull'"]),
    (("measure",), {"object": "box", "axis": [0, 0]}, ["measure.axis must be 3 finite numbers [x, y, z], got [0, 0]"]),
    (("finger",), [], ["at least one [[finger]] table is required"]),
]


@pytest.mark.parametrize("where, value, words", MALFORMED_SCENES,
                         ids=[".".join(map(str, m[0])) for m in MALFORMED_SCENES])
def test_a_malformed_scene_is_refused_by_the_schema_and_the_loader_alike(written, tmp_path, where, value, words):
    """The written schema (what an editor flags) and `load_scene` (one line naming the file, the
    field and the fix) refuse the same mistakes."""
    grasp = next(p for p in SCENES if p.stem == "two_finger_grasp")
    doc = _mutated(toml(grasp), where, value)
    assert errors(written["scene.schema.json"], doc)
    (tmp_path / "two_finger_grasp.xml").write_text(grasp.with_suffix(".xml").read_text())
    text = grasp.read_text()
    path = tmp_path / "bad.toml"
    path.write_text(_toml_with(text, where, value))
    with pytest.raises(SceneError) as exc:
        load_scene(str(path))
    message = str(exc.value)
    assert message.startswith(f"{path}: ") and "\n" not in message, message
    for w in words:
        assert w in message, (w, message)


def _toml_with(text: str, where, value) -> str:
    """The grasp scene's TOML written out again with one value set."""
    doc = _mutated(tomllib.loads(text), where, value)
    return _dump(doc)


def _dump(doc: dict) -> str:
    """A minimal TOML writer for scene documents (tables, arrays of tables, inline values)."""
    def value(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, str):
            return json.dumps(v)
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {value(x)}" for k, x in v.items()) + " }"
        if isinstance(v, (list, tuple)):
            return "[" + ", ".join(value(x) for x in v) + "]"
        return repr(v)

    def table(header: str, name: str, t: dict) -> list[str]:
        """A table's header, its values, then its arrays of tables ([[name.key]])."""
        lines = [header] + [f"{k} = {value(x)}" for k, x in t.items() if not _is_tables(x)]
        for k, x in t.items():
            if _is_tables(x):
                for sub in x:
                    lines += table(f"[[{name}.{k}]]", f"{name}.{k}", sub)
        return lines

    lines = [f"{name} = {value(t)}" for name, t in doc.items() if not isinstance(t, dict) and not _is_tables(t)]
    for name, t in doc.items():
        if _is_tables(t):
            for one in t:
                lines += table(f"[[{name}]]", name, one)
        elif isinstance(t, dict):
            lines += table(f"[{name}]", name, t)
    return "\n".join(lines) + "\n"


def _is_tables(x) -> bool:
    return isinstance(x, list) and bool(x) and all(isinstance(t, dict) for t in x)


def test_the_toml_writer_round_trips_every_shipped_scene():
    """The helper above writes what it read (so the malformed scenes differ only where set)."""
    for path in SCENES:
        doc = toml(path)
        assert tomllib.loads(_dump(doc)) == doc, path


def test_a_malformed_profile_and_device_table_are_refused(written):
    profile = toml(PROFILE_DIR / "open_haptic.toml")
    assert errors(written["hid_profile.schema.json"], {**profile, "max_force": 500.0})
    assert errors(written["hid_profile.schema.json"], _mutated(profile, ("input", "report", 0, "id"), 256))
    assert errors(written["hid_profile.schema.json"], {**profile, "wheels": 4})
    device = toml(next(p for p in SCENES if p.stem == "knob"))["device"]
    assert errors(written["device.schema.json"], {**device, "faults": {"nan": 7}})
    assert errors(written["device.schema.json"], {**device, "bogus": 1})
    assert errors(written["device.schema.json"], {"type": "hid"})  # a HID table names its profile
    assert errors(written["device.schema.json"], {"type": "hid", "profile": "spacemouse", "stale_ms": -1})
    assert errors(written["device.schema.json"], {"type": "hid", "profile": "spacemouse"}) == []


def test_a_plugin_device_type_keeps_a_table_of_its_own(written):
    """A scene's [device] of a type installed as a plugin is not checked against the shipped tables."""
    doc = toml(next(p for p in SCENES if p.stem == "knob"))
    assert errors(written["scene.schema.json"], {**doc, "device": {"type": "my_glove", "port": "/dev/ttyACM0"}}) == []
    assert errors(written["scene.schema.json"], {**doc, "device": {"type": "sim"}})  # a sim table scripts fingers


@pytest.mark.parametrize("type_name, cfg, message", [
    ("hid", {"profile": "spacemouse", "stale_ms": -1}, "device.stale_ms must be a finite number >= 0 ms, got -1"),
    ("forcedimension", {"stall_ms": 2000}, "device.stall_ms must be at most 1000 ms, got 2000"),
    ("openhaptics", {"command_timeout_ms": 0}, "device.command_timeout_ms must be a finite number > 0 ms, got 0"),
    ("sim", {"finger": [{"keyframes": [[0, 0, 0, 0]]}]},
     "device.finger[0].keyframes[0] must be 5 finite numbers [t, x, y, z, twist], got [0, 0, 0, 0]"),
    ("openhaptics", {"colour": "red"}, "device has unknown field(s) ['colour']; expected some of"),
])
def test_each_device_table_is_checked_against_its_declaration(type_name, cfg, message):
    """Building a device checks its [device] table against the declared one: one line, file and field."""
    with pytest.raises(ValueError) as exc:
        device_config.check_type(cfg, "s.toml", type_name)
    assert str(exc.value).startswith(f"s.toml: {message}"), str(exc.value)


def test_the_declarations_agree_with_the_modules_that_use_them():
    from softproxy import fingertip

    assert schema.SIM_FAULT_KINDS == simulated.FAULT_KINDS
    assert set(schema.HID_FIELD_TYPES) == set(hid_profile.TYPES)
    assert set(FingerParams.LIMITS) == {"radius", "stiffness", "damping", "torsion_stiffness", "torsion_damping",
                                        "mu_s", "mu_d", "torsion_mu_s", "torsion_mu_d", "restick_time", "max_force",
                                        "max_torque", "max_speed", "soft_start", "scale", "offset"}
    for name in fingertip.MODELS:
        FingerParams(model=name)


def test_a_unit_slip_is_named_with_its_fix():
    """stiffness typed in N/mm (2 for 2000 N/m) and a radius in mm are caught by their bounds, and
    the message says the unit; a negative stiffness is not taken for a unit slip."""
    with pytest.raises(ValueError, match=r"^stiffness must be between 10 and 1e\+08 N/m, got 2\.0 "
                                         r"\(stiffness is in N/m: 2 N/mm is 2000 N/m\)$"):
        FingerParams(stiffness=2.0)
    with pytest.raises(ValueError, match=r"^radius must be at most 0\.1 m, got 8\.0 "
                                         r"\(radius is in m: 8 mm is 0\.008\)$"):
        FingerParams(radius=8.0)
    with pytest.raises(ValueError) as exc:
        FingerParams(stiffness=-5.0)
    assert "N/mm" not in str(exc.value)
    FingerParams(stiffness=10.0)  # the bound itself is legal


def test_several_mistakes_give_one_line_naming_the_first():
    with pytest.raises(schema.InputError) as exc:
        schema.validate(schema.SceneTable, {"mjcf": "w.xml", "rate_hz": "fast", "audit": 1}, source="s.toml",
                        path="scene")
    assert str(exc.value) == "s.toml: scene.rate_hz must be a finite number in [10, 100000] Hz, got 'fast'"


def test_an_unwritable_out_folder_is_one_line(capsys, tmp_path):
    (tmp_path / "file").write_text("")
    out = tmp_path / "file" / "schema"
    assert cli.main(["schema", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out {out}" in err and "writable folder" in err
