"""Figures for studies and reports: one place for the look and for writing PNG + SVG."""

from __future__ import annotations

from functools import partial
from pathlib import Path

from workbench.core.files import atomic_write


def new_figure(panels: int = 2, size=(11, 4.2)):
    """A headless matplotlib figure with ``panels`` side-by-side axes."""
    import matplotlib  # deferred: start-up time (half a second; only studies and reports plot)

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(1, panels, figsize=size)


def save_figure(fig, axes, out: Path, stem: str) -> None:
    """Grid and legend on every panel, then ``stem``.png and ``stem``.svg in ``out``."""
    import matplotlib.pyplot as plt  # deferred: start-up time

    for ax in axes:
        ax.grid(True, which="both", alpha=0.3)
        ax.legend()
    fig.tight_layout()
    for ext in ("png", "svg"):  # each written atomically: a temporary name, then renamed
        atomic_write(Path(out) / f"{stem}.{ext}", partial(_savefig, fig, ext))
    plt.close(fig)


def _savefig(fig, ext: str, path: Path) -> None:
    fig.savefig(path, dpi=120, format=ext)
