"""Report writers shared by the reproduction and evaluation commands: Markdown tables, number
formats, generated blocks inside hand-written documents, and figure files.

Nothing here computes a statistic (that is `filters.experiments.stats`) or runs an
experiment (`filters.experiments.runner`).
"""

from __future__ import annotations

import math
import os
from collections.abc import Iterable, Sequence
from pathlib import Path

__all__ = ["markdown_table", "fmt_ci", "replace_block", "save_figure", "relative_to", "pyplot"]


def markdown_table(header: Sequence[str], rows: Iterable[Sequence[object]]) -> str:
    """A GitHub Markdown table (no trailing newline). Cells are ``str()``-ed; a row must have one
    cell per header column (``ValueError`` otherwise)."""
    lines = ["| " + " | ".join(str(h) for h in header) + " |", "|" + "---|" * len(header)]
    for row in rows:
        row = list(row)
        if len(row) != len(header):
            raise ValueError(f"row has {len(row)} cells, the header {len(header)}: {row}")
        lines.append("| " + " | ".join(str(c) for c in row) + " |")
    return "\n".join(lines)


def fmt_ci(mean: float, half_width: float, digits: int = 3) -> str:
    """``"1.234 ± 0.056"``; ``"-"`` for a NaN mean, and ``± nan`` for an undefined half-width."""
    if math.isnan(mean):
        return "-"
    return f"{mean:.{digits}f} ± {half_width:.{digits}f}"


def replace_block(path: Path, block: str, start: str, end: str, title: str) -> None:
    """Write ``start + block + end`` into ``path``: between the markers if the file has them (the
    hand-written text around them is kept), else as a new file headed ``# title``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    text = path.read_text() if path.exists() else ""
    new = "\n".join([start, block, end])
    if start in text and end in text.split(start, 1)[1]:
        head, rest = text.split(start, 1)
        path.write_text(head + new + rest.split(end, 1)[1])
    else:
        path.write_text(f"# {title}\n\n{new}\n")


def pyplot():
    """``matplotlib.pyplot`` on the non-interactive Agg backend (for figure files)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path: Path | str, dpi: int | None = None) -> str:
    """Save a matplotlib figure as ``path`` (parent folders created), close it, return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, **({} if dpi is None else {"dpi": dpi}))
    pyplot().close(fig)
    return str(path)


def relative_to(path: Path | str, start: Path | str) -> str:
    """``path`` relative to the folder ``start`` (for links from a report to its figures)."""
    return os.path.relpath(Path(path).resolve(), Path(start).resolve())
