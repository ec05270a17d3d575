"""The command line, run as a user would run it."""

import json
import re
import subprocess
import sys

import pytest

from softproxy import cli


def run_cli(*args):
    out = subprocess.run([sys.executable, "-m", "softproxy.cli", *args], capture_output=True, text=True, check=True)
    return out.stdout


def test_models_json_lists_the_four_models_with_seed_constants():
    """`softproxy models --json`: seed 002 Table 1 exponents and coefficients, P* from eq 27."""
    models = {m["name"]: m for m in json.loads(run_cli("models", "--json"))["models"]}
    assert {"CH", "MH", "VS", "LFM", "point"} <= set(models)
    assert models["MH"]["gamma"] == 1.1433 and abs(models["MH"]["mu_prime_Nmm"] - 8.8327) < 1e-9
    assert abs(models["LFM"]["mu_prime_Nmm"] - 9.0028) < 1e-9
    for name in ("CH", "MH", "VS", "LFM"):
        m = models[name]
        assert abs(m["mu_prime_Nmm"] * m["gamma"] * m["p_star_N"] ** (m["gamma"] - 1) - 8.7855) < 1e-9
    assert models["point"]["p_star_N"] is None


def test_models_table():
    text = run_cli("models")
    assert "CH" in text and "1.3333" in text and "8.1489" in text


def test_sense_recovers_a_pushing_contact():
    """`softproxy sense`: a 1 N push straight down on the top of the ellipsoid (seed 003) is found there."""
    out = json.loads(run_cli("sense", "--wrench", "0", "0", "-1", "0", "0", "0", "--json"))
    assert out["explained"] and out["contact_point_m"][0] == 0.0 and out["contact_point_m"][2] > 0.009
    assert abs(out["normal_force_N"] - 1.0) < 1e-9


@pytest.mark.slow  # two commands, each in its own process, writing charts
def test_tactile_and_calibrate_print_json(tmp_path):
    tactile = json.loads(run_cli("tactile", "inoue-hirai", "--json", "--out", str(tmp_path)))
    assert {"rotation", "rolling", "frame"} <= set(tactile)
    calib = json.loads(run_cli("calibrate", "--json", "--out", str(tmp_path)))
    assert "depth_mm" in json.dumps(calib) and (tmp_path / "calibration.png").exists()


def test_devices_lists_profiles():
    text = run_cli("devices")
    assert "spacemouse" in text and "open_haptic" in text


def test_run_help_lists_every_scene_with_its_description():
    """`softproxy run --help` names each scene it can run, so a user need not look in the folder."""
    from softproxy.scene import list_scenes

    text = run_cli("run", "--help")
    listed = text[text.index("scenes:"):]
    scenes = list_scenes()
    assert scenes
    for path in scenes:
        line = next((l for l in listed.splitlines() if l.split()[:1] == [path.stem]), None)
        assert line is not None, path.stem
        assert len(line.split(None, 1)) == 2  # a description follows the name


def test_a_long_run_on_a_terminal_shows_progress_and_is_silent_otherwise(monkeypatch, capsys):
    """A real-time run over 2 s (lockstep: over a minute of servo time) on a terminal gets a bar
    of servo seconds on stderr; a short run, or any run into a pipe or file, prints none."""
    from softproxy import cli

    monkeypatch.setattr(sys.stderr, "isatty", lambda: False)
    assert cli._run_progress(3600.0, True) is None
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert cli._run_progress(1.5, True) is None and cli._run_progress(30.0, False) is None
    bar = cli._run_progress(3.0, True)

    class Loop:
        t = 1.5

    bar.chain(None)(Loop())
    assert bar.bar.n == 1.5
    bar.close()
    assert "servo time" in capsys.readouterr().err


def test_compile_leaves_nothing_for_a_first_run_to_compile(capsys):
    """`softproxy compile knob`: the knob scene's kernels built (one line saying so); a run of
    it then compiles nothing (no "compiling" line). An unknown scene: one line, exit 2."""
    assert cli.main(["compile", "knob"]) == 0
    assert re.fullmatch(r"knob: ready in [\d.]+ s \([\d.]+ s of CPU\)\n", capsys.readouterr().out)
    run = subprocess.run([sys.executable, "-m", "softproxy.cli", "run", "knob", "--headless", "--duration", "0.01"],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 0 and "compiling" not in run.stderr, run.stderr
    assert cli.main(["compile", "no_such_scene"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("softproxy compile:") and "no_such_scene" in err[0]
