"""The loop's plots: validation time series, each accepted effect, the unexplained residual."""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np

from designlab.atomic import FileSet, atomic_write_bytes


def _file_safe(name: str) -> str:
    """A channel or effect name as a file-name part: anything but letters, digits, '.', '-'
    becomes '_' (a channel named 'a/b' or '[/bold]' never writes outside --out)."""
    return re.sub(r"[^\w.-]", "_", str(name))


def _savefig(fig, path: Path, files: FileSet | None) -> Path:
    """The figure as PNG at ``path``: staged in ``files`` (written with the set), or now."""
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    if files is not None:
        files.write_bytes(path, buf.getvalue())
    else:
        atomic_write_bytes(path, buf.getvalue())
    return path


def plot_output(o: str, ser: dict, rep: dict, out: Path,
                files: FileSet | None = None) -> list[Path]:
    """The PNG plots of one output into ``out``: the validation time series, one per accepted
    effect, the final residual against its strongest correlate.

    Args:
        o: the output's name.
        ser: its series (:func:`designlab.loop.report.output_report`).
        rep: its loop.json entry.
        out: the folder.
        files: the set the plots are staged in (None: each written at once).

    Returns:
        The files written.
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    paths = [_timeseries(plt, o, ser, rep, out, files)]
    for k, st in enumerate(ser["stages"], 1):
        paths.append(_effect(plt, o, k, st, rep["unit"], out, files))
    if ser["top_var"] is not None:
        paths.append(_unexplained(plt, o, ser, rep, out, files))
    return paths


def _timeseries(plt, o: str, ser: dict, rep: dict, out: Path, files: FileSet | None) -> Path:
    unit = rep["unit"]
    fig, ax = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    x = np.arange(ser["t_val"].size) * (np.median(np.diff(ser["t_val"])) if ser["t_val"].size
                                        > 1 else 1.0)
    ax[0].plot(x, ser["y_val"], "k", lw=0.8, label="measured")
    ax[0].plot(x, ser["base_val"], "C0", lw=0.8,
               label=f"base (RMSE {rep['error_before']:.4g} {unit})")
    ax[0].plot(x, ser["final_val"], "C3", lw=0.8,
               label=f"physics (RMSE {rep['error_after']:.4g} {unit})")
    if ser.get("peer_val") is not None:
        ax[0].plot(x, ser["peer_val"], "C2", lw=0.8, alpha=0.8,
                   label=f"{ser['peer_kind']} peer (RMSE {ser['peer_error']:.4g} {unit})")
    ax[0].set_ylabel(f"{o} ({unit})")
    ax[0].legend(loc="upper right", fontsize=8)
    ax[0].set_title(f"{o}: validation data")
    ax[1].plot(x, ser["y_val"] - ser["base_val"], "C0", lw=0.6, label="residual before")
    ax[1].plot(x, ser["residual_val"], "C3", lw=0.6, label="residual physics")
    if ser.get("peer_val") is not None:
        ax[1].plot(x, ser["y_val"] - ser["peer_val"], "C2", lw=0.6, alpha=0.8,
                   label="residual peer")
    ax[1].set_ylabel(f"residual ({unit})")
    ax[1].set_xlabel("validation time (s)")
    ax[1].legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    path = _savefig(fig, out / f"timeseries_{_file_safe(o)}.png", files)
    plt.close(fig)
    return path


def _effect(plt, o: str, k: int, st: dict, unit: str, out: Path,
            files: FileSet | None) -> Path:
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.5))
    idx = np.linspace(0, st["regressor"].size - 1, min(st["regressor"].size, 4000)).astype(int)
    r, c = st["residual"][idx], st["contribution"][idx]
    ax[0].plot(st["regressor"][idx], r, ".", ms=2, color="0.6", label="residual before (train)")
    ax[0].plot(st["regressor"][idx], c, ".", ms=2, color="C3", label=f"{st['key']} fit")
    ax[0].set_xlabel(st["regressor_name"])
    ax[0].set_ylabel(f"{o} residual ({unit})")
    ax[0].legend(fontsize=8, markerscale=4)
    ax[1].plot(c, r, ".", ms=2, color="C0")
    lim = [min(c.min(), r.min()), max(c.max(), r.max())]
    ax[1].plot(lim, lim, "k--", lw=0.8, label="1:1")
    ax[1].set_xlabel(f"{st['key']} contribution ({unit})")
    ax[1].set_ylabel(f"residual before ({unit})")
    ax[1].legend(fontsize=8)
    fig.suptitle(f"{o} effect {k}: {st['key']}")
    fig.tight_layout()
    safe = _file_safe(st["key"])
    path = _savefig(fig, out / f"effect_{_file_safe(o)}_{k}_{safe}.png", files)
    plt.close(fig)
    return path


def _unexplained(plt, o: str, ser: dict, rep: dict, out: Path, files: FileSet | None) -> Path:
    fig, ax = plt.subplots(figsize=(6, 4.5))
    ax.plot(ser["top_values"], ser["residual_val"], ".", ms=2, color="C0")
    ax.set_xlabel(ser["top_var"])
    ax.set_ylabel(f"{o} final residual ({rep['unit']})")
    ax.set_title(f"{o}: unexplained {100 * rep['unexplained_fraction']:.1f} % of variance")
    fig.tight_layout()
    path = _savefig(fig, out / f"unexplained_{_file_safe(o)}.png", files)
    plt.close(fig)
    return path
