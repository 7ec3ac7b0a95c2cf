"""Monte Carlo bands in report.html: the "Scatter (Monte Carlo)" section of ``predict PART
--samples N`` (nominal, mean, 5 %, 95 %, drivers, builds, failed) and, in a robust sweep's
report, each objective's 5-95 % band beside it. Cheap: the flexure, a few builds per design;
the page is parsed and opened in headless Chromium."""

from __future__ import annotations

import re
import subprocess
from html.parser import HTMLParser
from pathlib import Path

import pytest


class Section(HTMLParser):
    """Text and table rows of one ``<section id=...>`` of a report."""

    def __init__(self, sid: str):
        super().__init__()
        self.sid, self.on, self.depth = sid, False, 0
        self.text: list[str] = []
        self.rows: list[list[str]] = []
        self._row: list[str] | None = None
        self._cell: list[str] | None = None

    def handle_starttag(self, tag, attrs):
        if tag == "section":
            if self.on:
                self.depth += 1
            elif ("id", self.sid) in attrs:
                self.on = True
        if not self.on:
            return
        if tag == "tr":
            self._row = []
        elif tag in ("td", "th"):
            self._cell = []

    def handle_endtag(self, tag):
        if not self.on:
            return
        if tag == "section":
            if self.depth:
                self.depth -= 1
            else:
                self.on = False
        elif tag in ("td", "th") and self._cell is not None and self._row is not None:
            self._row.append(" ".join(self._cell).strip())
            self._cell = None
        elif tag == "tr" and self._row is not None:
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        if self.on:
            if data.strip():
                self.text.append(data.strip())
            if self._cell is not None:
                self._cell.append(data.strip())


def section(html: str, sid: str) -> Section:
    p = Section(sid)
    p.feed(html)
    assert p.text, f"no section {sid!r} in the page"
    return p


def table(sec: Section, first: str) -> list[dict[str, str]]:
    """The rows of the section's table whose header starts with ``first``, as dicts."""
    for i, r in enumerate(sec.rows):
        if r and r[0] == first:
            head = r
            out = []
            for row in sec.rows[i + 1:]:
                if len(row) != len(head) or row[0] == first:
                    break
                out.append(dict(zip(head, row)))
            return out
    raise AssertionError(f"no table headed {first!r}")


def dom_of(page: Path, tmp: Path) -> str:
    """The page as headless Chromium renders it (its DOM after load)."""
    from test_predict_report import FLAGS, chromium

    return subprocess.run([chromium(), *FLAGS, f"--user-data-dir={tmp / 'profile'}",
                           "--virtual-time-budget=5000", "--dump-dom", page.as_uri()],
                          capture_output=True, text=True, timeout=180).stdout


def fmt(v: float) -> str:
    return f"{v:.4g}"


# ------------------------------------------------------------------ predict PART --samples N

@pytest.fixture(scope="module")
def mc_run(tmp_path_factory):
    """8 flexure builds, the hysteresis drawn from -1..5 %: the builds below 0 fail (counted)."""
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.montecarlo import monte_carlo
    from designlab.predict.report import write_uncertainty_report
    from designlab.predict.uncertainty import parse_uncertainty

    out = tmp_path_factory.mktemp("mc")
    spec = parse_uncertainty("flexure", {
        "samples": 8, "seed": 1, "batch": 8,
        "hysteresis_percent": {"dist": "uniform", "lo": -1.0, "hi": 5.0}})
    summary = monte_carlo("flexure", spec, out, executor=LocalExecutor(1))
    write_uncertainty_report(out, summary, params={})
    return out, summary


@pytest.mark.slow
def test_scatter_section_of_a_monte_carlo(mc_run):
    out, summary = mc_run
    assert summary["failed"] >= 1 and summary["ok"] >= 2          # the seed gives both
    html = (out / "report.html").read_text()
    sec = section(html, "scatter")
    assert sec.text[0] == "Scatter (Monte Carlo)"
    assert any(f"{summary['builds']} virtual builds ({summary['ok']} evaluated, "
               f"{summary['failed']} failed)" in t for t in sec.text)
    rows = {r["metric"]: r for r in table(sec, "metric")}
    from designlab.sensors.labels import metric_name_unit

    assert len(rows) == len(summary["metrics"])
    for m, e in summary["metrics"].items():
        r = rows[metric_name_unit(m)[0]]
        assert (r["mean"], r["5 %"], r["95 %"]) == (fmt(e["mean"]), fmt(e["p5"]), fmt(e["p95"]))
        assert r["builds"] == str(summary["ok"])
        assert r["nominal"] != ""                  # one build at the inputs' centres
        if e["drivers"]:
            first = next(iter(e["drivers"]))
            assert r["driven by"].startswith(f"{first} (")
    # the nominal build sits inside the band of the hysteresis share of the z error
    e = summary["metrics"]["split_std.hysteresis.z"]
    nom = float(rows[metric_name_unit("split_std.hysteresis.z")[0]]["nominal"])
    assert e["p5"] <= nom <= e["p95"]
    # the failed builds are named with their error, and the page warns
    assert any("builds:" in t and "hysteresis_percent" in t for t in sec.text)
    assert f"{summary['failed']} of {summary['builds']} builds failed" in html
    inputs = {r["uncertain input"]: r for r in table(sec, "uncertain input")}
    assert inputs["hysteresis_percent"]["distribution"].startswith("dist = uniform")


@pytest.mark.slow
def test_nominal_build_is_deterministic(mc_run):
    """Evaluated again, the nominal build gives the numbers the report shows."""
    from designlab.sensors.labels import metric_name_unit
    from designlab.predict.report import nominal_build

    out, summary = mc_run
    a = nominal_build(summary, {})
    assert set(summary["metrics"]) <= set(a)
    rows = {r["metric"]: r for r in table(section((out / "report.html").read_text(), "scatter"),
                                          "metric")}
    for m in summary["metrics"]:
        assert rows[metric_name_unit(m)[0]]["nominal"] == fmt(a[m])


@pytest.mark.slow
def test_scatter_section_in_chromium(mc_run, tmp_path):
    out, summary = mc_run
    dom = dom_of(out / "report.html", tmp_path)
    sec = section(dom, "scatter")
    rows = table(sec, "metric")
    assert len(rows) == len(summary["metrics"])
    assert all(re.fullmatch(r"-?[0-9.e+-]+", r["95 %"]) for r in rows)


# ----------------------------------------------------------------------- a robust sweep

@pytest.fixture(scope="module")
def robust_sweep(tmp_path_factory):
    """Two flexure designs, 6 builds each, the 95th percentile of the z error minimised."""
    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.report import write_report
    from designlab.optimize.robust import RobustEvaluator, robust_config
    from designlab.optimize.sweep import run_sweep

    cfg, spec = robust_config({
        "part": "flexure", "method": "grid",
        "parameters": {"wire_radius": {"range": [0.9, 1.2], "levels": 2}},
        "uncertainty": {"samples": 6, "seed": 3},
        "objectives": {"mc.force_error_std.z.p95": "min", "condition_number": "min"}})
    out = tmp_path_factory.mktemp("robust")
    res = run_sweep(cfg, out, evaluator=RobustEvaluator(spec), executor=LocalExecutor(1))
    write_report(out, res.rows, cfg, res.pareto_keys, res.best_key, uncertainty=spec)
    return out, res, cfg


@pytest.mark.slow
def test_robust_sweep_report_shows_the_band_of_each_objective(robust_sweep):
    out, res, cfg = robust_sweep
    from designlab.optimize.report import band_of
    from designlab.sensors.labels import metric_label

    ok = [r for r in res.rows if r["status"] == "ok"]
    assert len(ok) == 2
    html = (out / "report.html").read_text()
    sec = section(html, "designs")
    head = next(r for r in sec.rows if r and r[0] == "design")
    q = metric_label("mc.force_error_std.z.p95")
    i = head.index(q)
    assert head[i + 1] == "±" and head[i + 2] == "5-95 %"
    j = head.index(metric_label("condition_number"))
    assert head[j + 2] != "5-95 %"          # a flexure's condition number has no Monte Carlo
    cells = {r[0]: r for r in sec.rows if r and r[0] != "design"}
    for r in ok:
        lo, hi = band_of(r, "mc.force_error_std.z.p95")
        assert lo == r["mc.force_error_std.z.p5"] and hi == r["mc.force_error_std.z.p95"]
        assert lo <= r["mc.force_error_std.z.mean"] <= hi
        assert cells[r["key"][:8]][i + 2] == f"{fmt(lo)} .. {fmt(hi)}"


@pytest.mark.slow
def test_robust_sweep_report_scatter_of_the_best_design(robust_sweep):
    out, res, cfg = robust_sweep
    best = next(r for r in res.rows if r["key"] == res.best_key)
    html = (out / "report.html").read_text()
    sec = section(html, "scatter")
    assert any("6 virtual builds (6 evaluated, 0 failed)" in t for t in sec.text)
    assert any(best["key"][:8] in t for t in sec.text)
    rows = {r["metric"]: r for r in table(sec, "metric")}
    from designlab.sensors.labels import metric_name_unit

    r = rows[metric_name_unit("force_error_std.z")[0]]
    assert (r["mean"], r["5 %"], r["95 %"]) == tuple(
        fmt(best[f"mc.force_error_std.z.{s}"]) for s in ("mean", "p5", "p95"))
    assert r["driven by"] == "" and r["builds"] == ""           # not kept in a sweep row
    res_sec = section(html, "results")
    assert any("Monte Carlo 5-95 %" in t for t in res_sec.text)


def test_nominal_sweep_report_has_no_bands(tmp_path):
    """A sweep without [uncertainty]: no band column, no Scatter section (the test can fail)."""
    from sweep_fixtures import quadratic

    from designlab.optimize.executors import LocalExecutor
    from designlab.optimize.report import write_report
    from designlab.optimize.space import sweep_config
    from designlab.optimize.sweep import run_sweep

    cfg = sweep_config({"part": "fingertip", "method": "grid",
                        "parameters": {"h": {"range": [1.0, 2.0], "levels": 2},
                                       "r": {"range": [8.0, 8.0], "levels": 1}},
                        "objectives": {"condition_number": "min"}})
    res = run_sweep(cfg, tmp_path, evaluator=quadratic, executor=LocalExecutor(1))
    write_report(tmp_path, res.rows, cfg, res.pareto_keys, res.best_key)
    html = (tmp_path / "report.html").read_text()
    assert "5-95 %" not in html and 'id="scatter"' not in html
