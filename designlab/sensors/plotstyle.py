"""One look for every designlab figure: constrained layout, a distinct colour *and* marker per
series (up to 20 before a pair repeats), loading solid/filled vs unloading dashed/open, legends
outside the data with black text."""

from __future__ import annotations

from typing import Any

#: 20 distinct colours (tab20's dark half first, then its light half) and 10 markers: series i
#: gets COLOURS[i % 20] and MARKERS[i % 10]
COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf", "#0b3c5d", "#b35806", "#1b7837", "#7f0000",
           "#542788", "#543005", "#c51b7d", "#252525", "#6b6b00", "#006d77")
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">", "*")


def series_style(i: int) -> dict[str, Any]:
    """Colour and marker of the i-th series."""
    return {"color": COLOURS[i % len(COLOURS)], "marker": MARKERS[i % len(MARKERS)]}


def loading_style(i: int) -> dict[str, Any]:
    """The i-th series while the load rises: solid line, filled marker."""
    return {**series_style(i), "ls": "-", "ms": 5}


def unloading_style(i: int) -> dict[str, Any]:
    """The i-th series while the load falls: dashed line, open marker, same colour."""
    s = series_style(i)
    return {**s, "ls": "--", "ms": 5, "mfc": "white", "mec": s["color"]}


def figure(nrows: int = 1, ncols: int = 1, *, width: float = 6.0, height: float = 4.0, **kw):
    """``plt.subplots`` with constrained layout (labels never collide with the next panel)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt.subplots(nrows, ncols, figsize=(width, height), layout="constrained", **kw)


def legend_outside(fig_or_ax, handles=None, labels=None, *, title: str | None = None,
                   ncol: int = 1, where: str = "right", fontsize: float = 8):
    """A legend outside the data (right of the axes, or below the figure), black text."""
    import matplotlib.figure

    kw = {"labelcolor": "black", "fontsize": fontsize, "title": title, "ncol": ncol,
          "frameon": False}
    if handles is not None:
        kw["handles"] = handles
        if labels is not None:
            kw["labels"] = labels
    if isinstance(fig_or_ax, matplotlib.figure.Figure):
        loc = "outside right upper" if where == "right" else "outside lower center"
        return fig_or_ax.legend(loc=loc, **kw)
    return fig_or_ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                            **kw)


def close(fig) -> None:
    import matplotlib.pyplot as plt

    plt.close(fig)
