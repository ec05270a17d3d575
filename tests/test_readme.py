"""The README's embedding example runs as printed."""

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
