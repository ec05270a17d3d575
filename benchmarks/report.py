"""What every benchmark does around its measurement: a progress line, then a chart and a JSON file."""

from __future__ import annotations

import json
import sys
from pathlib import Path


class Progress:
    """One status line on stderr, redrawn in place by tqdm: `progress("wall 3/45")`; `done()`
    clears it. Silent when stderr is not a terminal (a file or a pipe gets no control codes)."""

    def __init__(self, name: str) -> None:
        from tqdm import tqdm

        self.bar = tqdm(desc=f"  {name}", bar_format="{desc}: {postfix} [{elapsed}]", file=sys.stderr, leave=False,
                        disable=not sys.stderr.isatty())

    def __call__(self, message: str) -> None:
        self.bar.set_postfix_str(message)

    def done(self) -> None:
        self.bar.close()


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


def publish(args, name: str, result: dict, fig, print_report, shown: dict | None = None) -> None:
    """Write NAME.json and NAME.png into `args.out` (`save`), then show the result: as JSON with
    `--json` (`shown`, or the whole result), else as `print_report(result)` prints it, followed
    by where the two files went."""
    json_path, png_path = save(args.out, name, result, fig)
    if args.json:
        print(json.dumps(result if shown is None else shown, indent=2))
        return
    print_report(result)
    print(f"  wrote {json_path} and {png_path}")
