"""What every benchmark does around its measurement: a progress line, then a chart and a JSON file."""

from __future__ import annotations

import json
import sys
from pathlib import Path


class Progress:
    """One status line on stderr, rewritten in place: `progress("wall 3/45")`; `done()` clears it."""

    def __init__(self, name: str) -> None:
        self.name = name
        self.width = 0

    def __call__(self, message: str) -> None:
        line = f"  {self.name}: {message}"
        print("\r" + line.ljust(self.width), end="", file=sys.stderr, flush=True)
        self.width = max(self.width, len(line))

    def done(self) -> None:
        print("\r" + " " * self.width + "\r", end="", file=sys.stderr, flush=True)


def figure(nrows: int, ncols: int, size: tuple[float, float], **kwargs):
    """`plt.subplots` on matplotlib's file-only Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, figsize=size, **kwargs)


def save(out_dir: str | Path, name: str, result: dict, fig) -> tuple[Path, Path]:
    """Write NAME.json and NAME.png (closing the figure) into out_dir; returns both paths."""
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(out / f"{name}.png", dpi=100)
    plt.close(fig)
    (out / f"{name}.json").write_text(json.dumps(result, indent=1))
    return out / f"{name}.json", out / f"{name}.png"
