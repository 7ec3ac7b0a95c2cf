"""Sweep reports: Pareto and parameter-sensitivity plots (PNG) and a self-contained HTML page."""

from __future__ import annotations

import base64
import html
import io
from pathlib import Path
from typing import Any

import numpy as np

from designlab.atomic import atomic_write_bytes
from designlab.optimize.space import SweepConfig
from designlab.optimize.sweep import error_bar


def _fig_png(fig) -> bytes:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110, bbox_inches="tight")
    return buf.getvalue()


def _numeric(rows, name):
    return np.array([r.get(name) if isinstance(r.get(name), (int, float)) and r.get("status") == "ok"
                     else np.nan for r in rows], float)


def _bars(rows, name):
    return np.array([error_bar(r, name) if r.get("status") == "ok" else np.nan for r in rows])


def pareto_plot(rows: list[dict], config: SweepConfig, pareto_keys: list[str],
                best_key: str | None, tie_keys: list[str] = ()) -> bytes | None:
    """Scatter of the first two objectives with each design's discretisation error bars (value
    vs one coarser mesh), Pareto set highlighted, designs not distinguishable from the chosen
    one ringed (None with < 2 objectives)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(config.objectives)
    if len(names) < 2:
        return None
    x, y = _numeric(rows, names[0]), _numeric(rows, names[1])
    is_p = np.array([r["key"] in pareto_keys for r in rows])
    fig, ax = plt.subplots(figsize=(5.5, 4.2))
    ex, ey = _bars(rows, names[0]), _bars(rows, names[1])
    ok = np.isfinite(x) & np.isfinite(y)
    ax.errorbar(x[ok], y[ok], xerr=np.nan_to_num(ex[ok]), yerr=np.nan_to_num(ey[ok]), fmt="none",
                ecolor="0.5", elinewidth=0.8, capsize=2, label="mesh error bar", zorder=1)
    ax.scatter(x[~is_p], y[~is_p], c="0.6", label="designs", zorder=2)
    order = np.argsort(x[is_p])
    ax.plot(x[is_p][order], y[is_p][order], "o-", c="C3", label="Pareto set", zorder=3)
    tie = np.array([r["key"] in tie_keys for r in rows])
    if tie.any():
        ax.scatter(x[tie], y[tie], s=160, facecolors="none", edgecolors="C0", zorder=4,
                   label="not distinguishable from the chosen")
    if best_key is not None:
        b = [i for i, r in enumerate(rows) if r["key"] == best_key][0]
        ax.scatter([x[b]], [y[b]], s=160, facecolors="none", edgecolors="k", label="chosen",
                   zorder=5)
    ax.set_xlabel(f"{names[0]} ({config.objectives[names[0]]})")
    ax.set_ylabel(f"{names[1]} ({config.objectives[names[1]]})")
    ax.legend()
    ax.grid(alpha=0.3)
    data = _fig_png(fig)
    plt.close(fig)
    return data


def sensitivity_plot(rows: list[dict], config: SweepConfig) -> bytes | None:
    """Each objective against each swept parameter (one panel per pair)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names = list(config.objectives)
    dims = [d.name for d in config.dimensions]
    if not names:
        return None
    fig, axes = plt.subplots(len(names), len(dims), figsize=(3.2 * len(dims), 2.6 * len(names)),
                             squeeze=False)
    for i, n in enumerate(names):
        y = _numeric(rows, n)
        for j, d in enumerate(dims):
            x = _numeric([{**r, "status": "ok"} for r in rows], f"param.{d}")
            ax = axes[i, j]
            ax.scatter(x, y, s=18)
            ok = np.isfinite(x) & np.isfinite(y)
            if ok.sum() >= 3 and np.ptp(x[ok]) > 0:
                rho = np.corrcoef(x[ok], y[ok])[0, 1]
                ax.set_title(f"r = {rho:+.2f}", fontsize=9)
            ax.set_xlabel(d)
            ax.set_ylabel(n if j == 0 else "")
            ax.grid(alpha=0.3)
    fig.tight_layout()
    data = _fig_png(fig)
    plt.close(fig)
    return data


def write_report(out: Path, rows: list[dict], config: SweepConfig, pareto_keys: list[str],
                 best_key: str | None, title: str = "designlab sweep",
                 tie_keys: list[str] = ()) -> dict[str, Path]:
    """Write ``pareto.png``, ``sensitivity.png`` and ``report.html`` (images embedded)."""
    out = Path(out)
    written: dict[str, Path] = {}
    images = {}
    for name, data in (("pareto", pareto_plot(rows, config, pareto_keys, best_key, tie_keys)),
                       ("sensitivity", sensitivity_plot(rows, config))):
        if data is not None:
            atomic_write_bytes(out / f"{name}.png", data)
            written[name] = out / f"{name}.png"
            images[name] = base64.b64encode(data).decode()
    dims = [f"param.{d.name}" for d in config.dimensions]
    objs = list(config.objectives)
    rows = [{**r, **{f"+-{n}": error_bar(r, n) for n in objs}} for r in rows]
    cols = (["key"] + dims + [c for n in objs for c in (n, f"+-{n}")]
            + ["feasible", "status", "elapsed_s"])
    esc = html.escape

    def cell(v: Any) -> str:
        if isinstance(v, float):
            return f"{v:.4g}"
        return esc(str(v)) if v is not None else ""

    body_rows = []
    for r in rows:
        cls = ("best" if r["key"] == best_key else "tie" if r["key"] in tie_keys
               else "pareto" if r["key"] in pareto_keys else "")
        tds = "".join(f"<td>{cell(r.get(c))}</td>" for c in cols)
        err = f"<td>{esc(r['error'])}</td>" if r.get("error") else "<td></td>"
        body_rows.append(f"<tr class='{cls}'>{tds}{err}</tr>")
    imgs = "".join(f"<h2>{k}</h2><img src='data:image/png;base64,{v}'/>" for k, v in images.items())
    objectives = ", ".join(f"{k}: {esc(str(v))}" for k, v in config.objectives.items())
    tie_text = (f"; in blue the {len(tie_keys)} design(s) whose {esc(objs[0])} differs from the "
                "chosen one's by less than the error bar of the difference: the prediction cannot "
                "tell them apart" if tie_keys else "")
    page = f"""<!doctype html><html><head><meta charset="utf-8"><title>{esc(title)}</title>
<style>body{{font-family:sans-serif;margin:2em}}table{{border-collapse:collapse;font-size:12px}}
td,th{{border:1px solid #ccc;padding:2px 6px}}tr.pareto{{background:#fde}}tr.best{{background:#fc9}}
tr.tie{{background:#cdf}}
</style></head><body><h1>{esc(title)}</h1>
<p>part: <b>{esc(config.part)}</b>; method: {esc(config.method)}; designs: {len(rows)};
objectives: {objectives}; Pareto designs highlighted, chosen design in orange{tie_text}.
+- columns: each design's discretisation error bar (its metric on the chosen mesh minus the
same on one coarser mesh).</p>{imgs}
<h2>designs</h2><table><tr>{''.join(f'<th>{esc(c)}</th>' for c in cols)}<th>error</th></tr>
{''.join(body_rows)}</table></body></html>"""
    atomic_write_bytes(out / "report.html", page.encode())
    written["html"] = out / "report.html"
    return written
