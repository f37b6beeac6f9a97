"""Matplotlib set-up for the studies: no screen, one style, PNG output, and one line style per
method that stays distinguishable when a plot holds a dozen methods."""
from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from cycler import cycler  # noqa: E402

#: ten distinct hues (matplotlib's tab10 without its pale grey, plus black): no two of them are
#: a light and a dark shade of one hue, as tab20's neighbours are
COLORS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
          "#000000", "#bcbd22", "#17becf"]
#: seven markers: their count is prime to the colours', so that lines 10 apart, which share a
#: colour, differ in marker (the first 70 lines are all different pairs)
MARKERS = ["o", "s", "^", "D", "v", "P", "X"]

plt.rcParams.update({"figure.dpi": 110, "savefig.dpi": 110, "axes.grid": True,
                     "grid.alpha": 0.3, "font.size": 9, "legend.fontsize": 8,
                     "axes.prop_cycle": cycler(color=COLORS)})


def line_style(i: int) -> dict:
    """The colour and marker of the i-th line of a many-line plot (keyword arguments of plot)."""
    return {"color": COLORS[i % len(COLORS)], "marker": MARKERS[i % len(MARKERS)]}


def save(fig, out: Path, name: str) -> Path:
    out.mkdir(parents=True, exist_ok=True)
    path = out / f"{name}.png"
    if fig.get_layout_engine() is None:
        fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path
