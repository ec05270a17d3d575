"""The README: its embedding example runs as printed, its test command is what CI runs."""

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_embedding_example_runs(tmp_path):
    """The example runs as printed and its finger rests on the puck: the force it prints is the
    spring's, stiffness × (proxy height - device height), the proxy held up by the puck's top
    face (puck centre + half-height + finger radius) above the device's last z."""
    text = README.read_text()
    section = text.split("## Embedding", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    script = tmp_path / "example.py"
    shown = 'print(f"proxy z {float(finger.god.z)!r}; puck z {float(world.data.body(\'puck\').xpos[2])!r}")\n'
    script.write_text(code + shown)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    force = float(re.search(r"pressing with ([0-9.]+) N", out.stdout).group(1))
    proxy_z, puck_z = (float(v) for v in re.search(r"proxy z (\S+); puck z (\S+)", out.stdout).groups())
    stiffness, radius, half_height, device_z = 1000.0, 0.008, 0.01, 0.028 - 0.5 * 0.004  # as the example sets them
    assert abs(proxy_z - (puck_z + half_height + radius)) < 5e-4, (proxy_z, puck_z)
    assert force > 0.5 and abs(force - stiffness * (proxy_z - device_z)) <= 0.006, (force, proxy_z)


def test_the_readme_test_command_is_what_ci_runs():
    """The README's one test command is the line .ci/run runs, word for word, so a fresh
    machine following the README installs exactly what CI proved enough."""
    text = README.read_text()
    section = text.split("## Two commands", 1)[1].split("\n## ", 1)[0]
    commands = re.findall(r"```sh\n(.*?)\n```", section, re.S)
    assert len(commands) == 2, commands
    main, tests = commands
    assert "softproxy run two_finger_grasp --device sim --headless" in main
    ci = (README.parent / ".ci" / "run").read_text()
    assert f'"{tests}"' in ci  # one of .ci/run's phases runs exactly this command


def test_the_main_job_prints_what_the_readme_shows():
    """`softproxy run two_finger_grasp --device sim --headless` prints the README's lines digit
    for digit, all but the tick times (they vary with the machine): the grasp's figures the
    README promises are the engine's."""
    shown = README.read_text().split("The main job prints", 1)[1]
    block = re.search(r"```\n(.*?)\n```", shown, re.S).group(1)
    out = subprocess.run([sys.executable, "-m", "softproxy.cli", "run", "two_finger_grasp", "--device", "sim",
                          "--headless"], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr

    def untimed(text: str) -> list[str]:
        return [re.sub(r"tick p50 [0-9.]+ us, p99 [0-9.]+ us, max [0-9.]+ us", "tick times", line)
                for line in text.strip().splitlines()]

    assert untimed(out.stdout) == untimed(block)
