"""The fixed grid of :func:`designlab.sensors.plotstyle.figure` (the cheap layout the fingertip's
plots use): the figure legend outside the panels, titles below the suptitle, panels apart."""

from matplotlib.colors import to_rgba


def test_fixed_grid_keeps_legend_titles_and_labels_apart(tmp_path):
    from matplotlib.lines import Line2D

    from designlab.atomic import atomic_savefig
    from designlab.sensors.plotstyle import figure, legend_outside, series_style

    fig, axes = figure(1, 3, width=14, height=4.4, fixed=True, top=0.84)
    assert fig.get_layout_engine() is None
    for k, ax in enumerate(axes):
        ax.plot([0, 200], [-40 * k, 40 * k], **series_style(k))
        ax.set_title(f"sensor {k} (azimuth {30 * k} deg)")
        ax.set_xlabel("hanging weight (g)")
        ax.set_ylabel("reading change (mV)")
    leg = legend_outside(fig, handles=[Line2D([], [], label=f"h{i}", **series_style(i))
                                       for i in range(12)], title="load point")
    sup = fig.suptitle("hysteresis loops: loading (solid, filled) and unloading (dashed, open)")
    fig.canvas.draw()
    r = fig.canvas.get_renderer()
    boxes = [ax.get_tightbbox(r) for ax in axes]
    assert leg.get_window_extent(r).x0 >= max(ax.get_window_extent(r).x1 for ax in axes)
    assert all(to_rgba(t.get_color()) == to_rgba("black") for t in leg.get_texts())
    for ax in axes:                                  # each title under the suptitle
        assert ax.title.get_window_extent(r).y1 <= sup.get_window_extent(r).y0
    for a, b in zip(boxes, boxes[1:]):               # y label of a panel off the previous one
        assert a.x1 < b.x0
    assert atomic_savefig(fig, tmp_path / "f.png", dpi=110).stat().st_size > 0
