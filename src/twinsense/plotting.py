"""Shared plotting helpers (matplotlib, headless)."""

from __future__ import annotations

from pathlib import Path


def pyplot():
    """matplotlib.pyplot on the non-interactive Agg backend (no display needed)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def save_figure(fig, path, dpi: int = 110) -> Path:
    """Save ``fig`` to ``path`` atomically (a temporary name, then rename) and close it.

    If saving fails, the figure is closed all the same and the temporary file removed: no half-written
    picture is left beside (or in place of) ``path``, and the error goes to the caller."""
    path = Path(path)
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name("." + path.name + ".tmp" + path.suffix)
        try:
            fig.savefig(tmp, dpi=dpi, bbox_inches="tight")
            tmp.replace(path)
        finally:
            tmp.unlink(missing_ok=True)
    finally:
        pyplot().close(fig)
    return path
