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
