"""The README: its embedding example runs as printed, its test command is what CI runs."""

import re
import subprocess
import sys
from pathlib import Path

README = Path(__file__).resolve().parents[1] / "README.md"


def test_embedding_example_runs(tmp_path):
    text = README.read_text()
    section = text.split("## Embedding", 1)[1]
    code = re.search(r"```python\n(.*?)```", section, re.S).group(1)
    script = tmp_path / "example.py"
    script.write_text(code)
    out = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    force = float(re.search(r"pressing with ([0-9.]+) N", out.stdout).group(1))
    assert 0.5 < force < 3.0


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
