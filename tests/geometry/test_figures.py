"""Figures a reviewer would accept: readable axis names with units, distinct colour+marker per
series, loading vs unloading distinct, legends outside the data with black text, load arrows and
the load case on the deformed plot."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.colors import to_rgba

from designlab.sensors.labels import metric_label, metric_name_unit
from designlab.sensors.plotstyle import loading_style, series_style, unloading_style


def test_metric_labels_have_names_and_units():
    assert metric_label("hysteresis_percent.overall") == "hysteresis (eq. 1, overall) (% of span)"
    assert metric_label("condition_number", "min").endswith("lower is better")
    assert metric_name_unit("printed_volume_mm3") == ("printed volume", "mm³")
    # unknown keys: the unit read from the suffix, never the raw key
    assert metric_name_unit("foo.bar_N_per_m") == ("foo bar", "N/m")
    assert metric_name_unit("electrical.resolution_mN.F_n")[1] == "mN"


def test_twenty_series_are_distinct_and_unloading_differs():
    pairs = {(series_style(i)["color"], series_style(i)["marker"]) for i in range(20)}
    assert len(pairs) == 20
    assert len({series_style(i)["color"] for i in range(20)}) == 20
    up, down = loading_style(3), unloading_style(3)
    assert up["color"] == down["color"] and up["ls"] != down["ls"]
    assert down["mfc"] == "white"


def _capture(monkeypatch):
    import designlab.optimize.report as rep

    figs = []

    def grab(fig):
        fig.canvas.draw()
        figs.append(fig)
        return b"png"

    monkeypatch.setattr(rep, "_fig_png", grab)
    monkeypatch.setattr("designlab.sensors.plotstyle.close", lambda fig: None)
    return rep, figs


@pytest.fixture
def sweep_rows(tmp_path):
    from sweep_fixtures import quadratic

    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.space import sweep_config
    from designlab.optimize.sweep import run_sweep

    cfg = sweep_config({"part": "fingertip", "method": "grid",
                        "parameters": {"h": {"range": [0.0, 6.0], "levels": 3},
                                       "r": {"range": [6.0, 9.0], "levels": 2}},
                        "objectives": {"condition_number": "min",
                                       "hysteresis_percent.overall": "min"}})
    return cfg, run_sweep(cfg, tmp_path / "s", evaluator=quadratic, executor=LocalExecutor(1))


def test_pareto_axes_legend_outside_black(monkeypatch, sweep_rows):
    rep, figs = _capture(monkeypatch)
    cfg, res = sweep_rows
    rep.pareto_plot(res.rows, cfg, res.pareto_keys, res.best_key, res.tie_keys)
    ax = figs[0].axes[0]
    assert ax.get_xlabel().startswith("condition number") and "lower is better" in ax.get_xlabel()
    assert "(% of span)" in ax.get_ylabel()
    leg = ax.get_legend()
    assert all(to_rgba(t.get_color()) == to_rgba("black") for t in leg.get_texts())
    # the legend lies right of the axes, off the data
    r = figs[0].canvas.get_renderer()
    assert leg.get_window_extent(r).x0 >= ax.get_window_extent(r).x1 - 1
    assert figs[0].get_layout_engine() is not None


def test_sensitivity_axes_have_units(monkeypatch, sweep_rows):
    rep, figs = _capture(monkeypatch)
    cfg, res = sweep_rows
    rep.sensitivity_plot(res.rows, cfg)
    labels = [(a.get_xlabel(), a.get_ylabel()) for a in figs[0].axes]
    assert all(x in ("h (mm)", "r (mm)") for x, _ in labels)
    ys = {y for _, y in labels}                   # readable names, units where there are
    assert ys == {"condition number of the calibration matrix",
                  "hysteresis (eq. 1, overall) (% of span)"}


def test_deformed_png_has_arrow_and_case(tmp_path):
    """The deformed picture names the load case and the bodies and draws the load arrow
    (matplotlib backend: the arrow is a red quiver)."""
    from designlab.fem import output
    from designlab.mesh.tetmesh import TetMesh

    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1], [1, 1, 1.0]])
    cells = np.array([[0, 1, 2, 3], [1, 2, 3, 4]])
    mesh = TetMesh(pts, cells, np.array([0, 1]), {0: "base", 1: "cap"},
                   {"base": "ABS", "cap": "PLA"})
    seen = {}

    def fake(path, mesh, u, k, label, size, loads=()):
        seen.update(label=label, arrows=output._arrow_geometry(mesh, loads))
        open(path, "wb").write(b"x")

    import designlab.geometry.render as render

    old = render.ensure_display
    render.ensure_display = lambda: True
    old_pv, output._png_pyvista = output._png_pyvista, fake
    try:
        output.write_png(tmp_path / "d.png", mesh, np.zeros((5, 3)) + 0.01,
                         loads=[((0, 0, 1), (0, 0, -1), 2.0)], case="2 N down on the top")
    finally:
        output._png_pyvista, render.ensure_display = old_pv, old
    assert "load case: 2 N down on the top" in seen["label"]
    assert "base (ABS)" in seen["label"] and "cap (PLA)" in seen["label"]
    (start, d, L, text), = seen["arrows"]
    assert np.allclose(start + L * d, (0, 0, 1)) and text == "F = 2 N"


def test_fingertip_paper_comparison_figure_has_the_shared_look():
    """Seed 001 beside the contact model: a fixed grid saved as drawn (no layout engine, no
    tight box) whose panels, labels and legends all lie inside the figure and do not overlap,
    every panel with both axis names, the model series in distinct colours and markers,
    legends right of the data with black text."""
    import matplotlib.pyplot as plt

    from designlab.sensors.fingertip.validation import paper_comparison_figure

    loc = {f"h{i}": 0.5 / i for i in range(1, 4)}
    rad = {f"r{i}": 0.1 * i for i in range(1, 4)}
    hp = {k: {"G1_by_location": {a: v * (j + 1) for a, v in loc.items()},
              "G2_by_location": {a: v * (j + 1) for a, v in rad.items()}}
          for j, k in enumerate(("robust_eq1_span10", "paper_eq1_all_sensors",
                                 "robust_eq1_span10_noise_free"))}
    contact = {"paper": {"lowest_mean_G1_pct": 1.2, "lowest_mean_G2_pct": 0.6,
                         "compressed_change_h9_to_h1_pct": 40.0,
                         "compressed_change_r1_to_r5_pct": 20.0},
               "table_II_design": {"heights_mm": [30.0, 20.0, 10.0], "radii_mm": [1.0, 2.0, 3.0],
                                   "hysteresis_percent": hp},
               "goals": {"compressed_change_h9_to_h1": {"value_pct": 35.0}},
               "compressed_change_r1_to_r5": {"value_pct": 15.0},
               "table_III_design": {"condition_number": 30.0, "relative_error_per_axis_all_weights":
                                    {"x": 0.05, "y": 0.06, "z": 0.2}}}
    fig = paper_comparison_figure(contact, plt)
    try:
        fig.canvas.draw()
        assert fig.get_layout_engine() is None
        r = fig.canvas.get_renderer()
        page = fig.bbox
        boxes = [ax.get_tightbbox(r) for ax in fig.axes]     # labels and legends included
        for b in boxes:
            assert b.x0 >= page.x0 and b.y0 >= page.y0 and b.x1 <= page.x1 and b.y1 <= page.y1
        for i in range(len(boxes)):
            for j in range(i + 1, len(boxes)):
                assert not boxes[i].overlaps(boxes[j]), (i, j)
        for ax in fig.axes:
            assert ax.get_xlabel() and ax.get_ylabel()
        for ax in fig.axes[:3]:
            leg = ax.get_legend()
            assert leg is not None
            assert all(to_rgba(t.get_color()) == to_rgba("black") for t in leg.get_texts())
            assert leg.get_window_extent(r).x0 >= ax.get_window_extent(r).x1 - 1
        lines = [ln for ln in fig.axes[0].get_lines() if ln.get_marker() not in ("None", "")]
        assert len(lines) == 3
        assert len({(ln.get_color(), ln.get_marker()) for ln in lines}) == 3
    finally:
        plt.close(fig)


def test_a_render_size_out_of_range_is_refused_before_any_work():
    """20000 x 20000 px exhausted the X server and killed the interpreter: a ParameterError."""
    from designlab.errors import ParameterError
    from designlab.geometry.render import check_size, render_items

    assert check_size((900, 675)) == (900, 675)
    for size in ((20000, 20000), (900, 675.5), (10, 10), "ab", (900,), (True, 900)):
        with pytest.raises(ParameterError, match="size=.*whole pixels, 64 to 8000 each"):
            render_items([], "never.png", size=size)
