"""One look for every designlab figure: constrained layout (or a fixed grid where measuring the
labels costs seconds), a distinct colour *and* marker per series (up to 20 before a pair
repeats), loading solid/filled vs unloading dashed/open, legends outside the data with black
text."""

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


def figure(nrows: int = 1, ncols: int = 1, *, width: float = 6.0, height: float = 4.0,
           fixed: bool = False, top: float = 0.86, wspace: float = 0.28, hspace: float = 0.35,
           **kw):
    """``plt.subplots`` with constrained layout (labels never collide with the next panel).

    ``fixed``: a fixed grid instead (``top``: where the axes end, a fraction of the height,
    room for a title and a ``suptitle``; ``wspace``/``hspace``: gaps between panels, fractions
    of a panel). Constrained layout measures every tick label two more times per save; a fixed
    grid does not. Use it for panels whose tick labels and
    titles are short and whose legends are figure legends or the last column's:
    :func:`legend_outside` then anchors a figure legend just outside the right edge, and the
    save (``bbox_inches="tight"``) takes the outer margins in."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if fixed:
        fig, ax = plt.subplots(nrows, ncols, figsize=(width, height), **kw)
        fig.subplots_adjust(top=top, wspace=wspace, hspace=hspace)
        return fig, ax
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
        if fig_or_ax.get_layout_engine() is None:       # a fixed grid: anchored outside
            right = max(a.get_position().x1 for a in fig_or_ax.axes) if fig_or_ax.axes else 1.0
            if where == "right":
                return fig_or_ax.legend(loc="upper left", bbox_to_anchor=(right + 0.01, 0.98),
                                        borderaxespad=0.0, **kw)
            return fig_or_ax.legend(loc="upper center", bbox_to_anchor=(0.5, 0.0),
                                    borderaxespad=0.0, **kw)
        loc = "outside right upper" if where == "right" else "outside lower center"
        return fig_or_ax.legend(loc=loc, **kw)
    return fig_or_ax.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0,
                            **kw)


def close(fig) -> None:
    import matplotlib.pyplot as plt

    plt.close(fig)
