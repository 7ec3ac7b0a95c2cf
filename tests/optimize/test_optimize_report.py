"""The optimize report a designer opens: a render of the chosen design, why it was chosen (in
words, with the objectives' readable names and values), the settings the run used, the swept
parameters' meanings, links to the printable files, every image loading in headless Chromium;
and a cached optimize that does not export and predict the chosen design again."""

from __future__ import annotations

import json
import re
import sys
from pathlib import Path
from typing import Iterator

import pytest

from designlab.cli import main
from designlab.optimize.space import sweep_config

CFG = ('part = "fingertip"\nmethod = "grid"\n[parameters]\n'
       'h = { range = [0.0, 4.0], levels = 2 }\n[fixed]\nr = 9.0\n'
       '[settings]\nmodel = { edge_length = 4.5, order = 1 }\n'
       '[objectives]\ncondition_number = "min"\n"hysteresis_percent.overall" = "min"\n')


def _fake_export(calls):
    """Stand-in for ``export_design``: writes one STL and a prediction.json, counts calls."""

    def export_design(part, params, out, **kw):
        calls.append(dict(params))
        out = Path(out)
        (out / part).mkdir(parents=True, exist_ok=True)
        (out / "prediction").mkdir(parents=True, exist_ok=True)
        stl = out / part / f"{part}-body.stl"
        stl.write_text(json.dumps(params))
        pj = out / "prediction" / "prediction.json"
        pj.write_text("{}")
        return [stl, pj]

    return export_design


def test_a_cached_chosen_design_is_not_exported_again(tmp_path, monkeypatch, capsys):
    import designlab.optimize.evaluate as ev
    from designlab.cli.sweep import _export_chosen

    calls: list = []
    monkeypatch.setattr(ev, "export_design", _fake_export(calls))
    cfg = sweep_config({"part": "fingertip", "parameters": {"h": {"range": [0, 4], "levels": 2}},
                        "settings": {"model": {"edge_length": 4.0}},
                        "objectives": {"condition_number": "min"}})
    d = tmp_path / "chosen"
    f1 = _export_chosen(cfg, {"h": 0.0}, d, "stl", fem_cache=tmp_path / "fem")
    f2 = _export_chosen(cfg, {"h": 0.0}, d, "stl", fem_cache=tmp_path / "fem")
    assert len(calls) == 1 and sorted(f1) == sorted(f2)
    assert "up to date" in " ".join(capsys.readouterr().out.split())
    # another design, other formats, or a file gone: exported again
    _export_chosen(cfg, {"h": 4.0}, d, "stl", fem_cache=tmp_path / "fem")
    _export_chosen(cfg, {"h": 4.0}, d, "stl,3mf", fem_cache=tmp_path / "fem")
    assert len(calls) == 3
    (d / "fingertip" / "fingertip-body.stl").unlink()
    _export_chosen(cfg, {"h": 4.0}, d, "stl,3mf", fem_cache=tmp_path / "fem")
    assert len(calls) == 4
    run = json.loads((d / "run.json").read_text())
    assert run["what"] == "optimize chosen design" and run["settings"]["params"] == {"h": 4.0}


def test_choice_in_words_for_the_pareto_method():
    from designlab.optimize.report import choice_text

    cfg = sweep_config({"part": "fingertip", "parameters": {"h": {"range": [0, 4], "levels": 3}},
                        "objectives": {"condition_number": "min",
                                       "hysteresis_percent.overall": "min"}})
    rows = [{"key": k, "status": "ok", "condition_number": c, "hysteresis_percent.overall": hy}
            for k, c, hy in (("a", 10.0, 3.0), ("b", 12.0, 1.0), ("c", 20.0, 5.0))]
    text = choice_text("pareto", rows, cfg, ["a", "b"], rows[0])
    assert "closest to the ideal point" in text and "of the 2 designs" in text
    assert "condition number of the calibration matrix" in text and "hysteresis" in text
    assert "condition_number" not in text          # readable names, not raw keys
    assert "10" in text and "1" in text            # the ideal point's values: 10 and 1
    one = choice_text("surrogate", rows, sweep_config(
        {"part": "fingertip", "parameters": {"h": {"range": [0, 4]}},
         "objectives": {"condition_number": "min"}}), [], rows[0])
    assert "condition number of the calibration matrix" in one and "= 10" in one


@pytest.fixture(scope="module")
def optimized(tmp_path_factory) -> Iterator[Path]:
    """A small real optimize (2 designs, coarse TET4 mesh, two objectives: Pareto)."""
    tmp = tmp_path_factory.mktemp("opt")
    cfg = tmp / "s.toml"
    cfg.write_text(CFG)
    main(["optimize", str(cfg), "--out", str(tmp / "o"), "--workers", "1", "--format", "stl"])
    yield tmp / "o"
    # its FEM stays out of the in-process cache that later tests' forked workers inherit (a
    # test counting the FEM files its own sweep writes would find none)
    from designlab.fem.cache import clear_memory

    clear_memory()


@pytest.mark.slow
def test_optimize_report_in_chromium(optimized, tmp_path):
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "predict"))
    from test_predict_report import ARTIFACTS, open_in_chromium

    html = (optimized / "report.html").read_text()
    assert "Why this design" in html and "closest to the ideal point" in html
    assert re.search(r'<section id="design">.*?<img src="data:image/png', html, re.S)
    assert "the chosen design (printed bodies" in html
    assert re.search(r'href="chosen/fingertip/[^"]+\.stl"', html)
    # the run's settings (edge_length 4.5, TET4), not the class defaults
    ms = html[html.index("<h2>Model settings</h2>"):]
    ms = ms[:ms.index("</table>")]
    assert re.search(r"<td>edge_length</td><td>4.5</td>", ms) and \
        re.search(r"<td>order</td><td>1</td>", ms)
    sw = html[html.index("<h2>Swept parameters</h2>"):]
    assert "straight height" in sw[:sw.index("</table>")]
    attrs = open_in_chromium(optimized / "report.html", tmp_path,
                             ARTIFACTS / "report_optimize_fingertip.png")
    assert attrs.get("checked") == "yes" and attrs["broken"] == "0"
    assert int(attrs["images"]) >= 4


@pytest.mark.slow
def test_cached_optimize_does_not_predict_again(optimized, monkeypatch, capsys):
    import designlab.predict.run as sp

    def fail(*a, **k):
        raise AssertionError("predict called for a cached chosen design")

    monkeypatch.setattr(sp, "predict", fail)
    main(["optimize", str(optimized.parent / "s.toml"), "--out", str(optimized), "--workers",
          "1", "--format", "stl"])
    assert "up to date" in " ".join(capsys.readouterr().out.split())
