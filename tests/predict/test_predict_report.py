"""The HTML report (one template for predict, sweep and optimize): its sections from a real
prediction, and the page opened in headless Chromium with every image loaded; the screenshot is
kept in ``test-artifacts/`` (or ``$DESIGNLAB_ARTIFACTS``)."""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest

from conftest import ROOT, require_tool

ARTIFACTS = Path(os.environ.get("DESIGNLAB_ARTIFACTS", ROOT / "test-artifacts"))

#: appended to a copy of the page: marks every image that did not load
CHECK_SCRIPT = """<script>
window.addEventListener('load', function () {
  var imgs = Array.from(document.images);
  var bad = imgs.filter(function (i) { return !(i.complete && i.naturalWidth > 0); });
  document.body.setAttribute('data-images', String(imgs.length));
  document.body.setAttribute('data-broken', String(bad.length));
  document.body.setAttribute('data-checked', 'yes');
});
</script>"""

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync"]


def chromium() -> str:
    for name in ("chromium", "chromium-browser"):
        import shutil

        if shutil.which(name):
            return shutil.which(name)
    return require_tool("chromium")


def open_in_chromium(page: Path, tmp: Path, screenshot: Path | None = None) -> dict[str, str]:
    """Load a copy of ``page`` (with :data:`CHECK_SCRIPT`) and return the body's data
    attributes after load; optionally a full-page screenshot of the original page."""
    exe = chromium()
    html = page.read_text(encoding="utf-8")
    probe = page.with_name(".probe-" + page.name)
    probe.write_text(html.replace("</body>", CHECK_SCRIPT + "</body>"), encoding="utf-8")
    try:
        dom = subprocess.run([exe, *FLAGS, f"--user-data-dir={tmp / 'profile-dom'}",
                              "--virtual-time-budget=10000", "--dump-dom", probe.as_uri()],
                             capture_output=True, text=True, timeout=180).stdout
    finally:
        probe.unlink()
    if screenshot is not None:
        screenshot.parent.mkdir(parents=True, exist_ok=True)
        subprocess.run([exe, *FLAGS, f"--user-data-dir={tmp / 'profile-shot'}",
                        "--window-size=1400,4000", "--hide-scrollbars",
                        f"--screenshot={screenshot}", page.as_uri()],
                       capture_output=True, timeout=180)
    m = re.search(r"<body([^>]*)>", dom)
    assert m, "Chromium returned no DOM"
    return dict(re.findall(r'data-([a-z]+)="([^"]*)"', m.group(1)))


@pytest.fixture(scope="module")
def predicted(tmp_path_factory) -> Path:
    """A coarse but complete fingertip prediction written with its report."""
    from designlab.predict.record import write_prediction
    from designlab.predict.run import predict

    out = tmp_path_factory.mktemp("pred") / "fingertip"
    pred = predict("fingertip", {}, settings={"edge_length": 4.0})
    write_prediction(pred, out)
    return out


def test_prediction_report_sections(predicted):
    html = (predicted / "report.html").read_text()
    doc = json.loads((predicted / "prediction.json").read_text())
    # version, date, command; parameter table with units and meanings from the metadata
    assert "designlab 0." in html and re.search(r"\d{4}-\d\d-\d\d \d\d:\d\d", html)
    assert "Design parameters" in html and "top rounding radius" in html
    assert "Model settings" in html and "Test protocol" in html
    # results with the mesh error bar column, stress with the ABS strength; the paper's own
    # sensor is designlab validate's, not the design's report
    assert "± error bar" in html or "&plusmn; error bar" in html
    assert "Stress and safety factor" in html and "ABSplus-P430" in html
    assert "Paper vs predicted" not in html and "34.92" not in html
    # every plot of the prediction is embedded; links to the VTU and JSON
    pngs = [p for p in predicted.glob("*.png") if p.name not in ("design.png", "deformed.png")]
    assert pngs and html.count("data:image/png;base64,") >= len(pngs) + 2
    for name in ("deformed.vtu", "prediction.json", "model.json", "run.json"):
        assert f'href="{name}"' in html
    assert doc["stress"]["min_safety_factor"] > 0
    run = json.loads((predicted / "run.json").read_text())
    assert run["what"] == "predict fingertip" and run["designlab"] and run["date"]


@pytest.mark.slow
def test_prediction_report_in_chromium(predicted, tmp_path):
    shot = ARTIFACTS / "report_predict_fingertip.png"
    attrs = open_in_chromium(predicted / "report.html", tmp_path, shot)
    assert attrs.get("checked") == "yes"
    assert int(attrs["images"]) >= 5
    assert attrs["broken"] == "0"
    assert shot.is_file() and shot.stat().st_size > 20_000


def test_chromium_check_sees_a_broken_image(predicted, tmp_path):
    """The check can fail: an image that does not decode is counted."""
    page = tmp_path / "broken.html"
    html = (predicted / "report.html").read_text()
    page.write_text(html.replace("</main>", '<img src="data:image/png;base64,AAAA"></main>'))
    attrs = open_in_chromium(page, tmp_path)
    assert attrs["broken"] == "1"


@pytest.mark.slow
def test_sweep_report_in_chromium(tmp_path):
    """A sweep report from the cheap evaluator: designs with readable metric names, the
    chosen design, the tie, settings; loads in Chromium with its plots."""
    from sweep_fixtures import quadratic

    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.report import write_report
    from designlab.optimize.space import sweep_config
    from designlab.optimize.sweep import run_sweep

    cfg = sweep_config({"part": "fingertip", "method": "grid",
                              "parameters": {"h": {"range": [0.0, 6.0], "levels": 3},
                                             "r": {"range": [6.0, 9.0], "levels": 2}},
                              "objectives": {"condition_number": "min",
                                             "hysteresis_percent.overall": "min"}})
    res = run_sweep(cfg, tmp_path / "s", evaluator=quadratic, executor=LocalExecutor(1))
    write_report(tmp_path / "s", res.rows, cfg, res.pareto_keys, res.best_key,
                 title="designlab sweep: test", tie_keys=res.tie_keys, kind="sweep")
    html = (tmp_path / "s" / "report.html").read_text()
    assert "condition number of the calibration matrix" in html
    assert "hysteresis (eq. 1, overall) (% of span)" in html
    assert "h (mm)" in html and "Swept parameters" in html and "class=\"best\"" in html
    attrs = open_in_chromium(tmp_path / "s" / "report.html", tmp_path,
                             ARTIFACTS / "report_sweep.png")
    assert attrs["broken"] == "0" and int(attrs["images"]) == 2


@pytest.mark.slow
def test_prediction_json_defines_its_metrics(tmp_path):
    """prediction.json carries each top-level metric's readable name, definition and unit: the
    fingertip's non-linearity says it takes every channel, noise-only ones included."""
    import json

    from designlab.cli import main

    main(["predict", "flexure", "--out", str(tmp_path / "o")])
    doc = json.loads((tmp_path / "o" / "prediction.json").read_text())
    assert doc["definitions"]["condition_number"] == "condition number of the calibration matrix"
    from designlab.sensors.labels import METRICS

    assert "noise-only channels included" in METRICS["linearity_percent_span"][0]
