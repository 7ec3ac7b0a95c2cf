"""The seed 002 spring flexure's physics :data:`BEAM_CHAIN` (its definition's plug-in) on top of
its virtual wrench test
(:mod:`designlab.sensors.flexure.model`): the plots, the loop gains, the force-test finish and
the loop -> predict glue. The model's names are re-exported here
(``designlab.sensors.flexure.virtual.run`` etc.)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from designlab.atomic import atomic_savefig
from designlab.sensors.protocols import FlexureWrenchTest
from designlab.sensors.flexure.montecarlo import MONTE_CARLO
from designlab.sensors.flexure.model import (FlexureModelSettings, FlexurePrediction, run)
from designlab.sensors.flexure.spring import TWIST, WRENCH
from designlab.sensors.flexure.validation import validate
from designlab.sensors.definition import Physics


# ------------------------------------------------------------------------------------ plots

def _save(fig, path: Path) -> Path:
    return atomic_savefig(fig, path, dpi=120)


def plots(prediction: FlexurePrediction, report: dict[str, Any] | None, out_dir: str | Path
          ) -> list[Path]:
    """PNG: applied vs estimated wrench per axis (the loads along that axis)."""
    from designlab.sensors.plotstyle import close, figure, legend_outside, series_style

    report = prediction.report if report is None else report
    W, E = prediction.wrenches, prediction.estimated
    fig, axes = figure(2, 3, width=12.5, height=7)
    names = {"m_x": "moment m_x", "m_y": "moment m_y", "m_z": "moment m_z",
             "f_x": "force f_x", "f_y": "force f_y", "f_z": "force f_z"}
    for i, (name, ax) in enumerate(zip(WRENCH, axes.ravel())):
        on = np.abs(W[:, i]) > 0
        ax.plot(W[on, i], E[on, i], ls="", ms=4, label="estimated from the pose",
                **series_style(i))
        lim = np.abs(np.r_[W[on, i], E[on, i]]).max() if on.any() else 1.0
        ax.plot([-lim, lim], [-lim, lim], "k--", lw=0.8, label="estimated = applied")
        unit = "N mm" if i < 3 else "N"
        ax.set_xlabel(f"applied {names.get(name, name)} ({unit})")
        ax.set_ylabel(f"estimated {names.get(name, name)} ({unit})")
        ax.grid(alpha=0.3)
    legend_outside(fig, handles=[axes.ravel()[0].lines[1]], where="below")
    fig.suptitle(f"flexure: wrench from pose with the closed-form K_f "
                 f"(truth: {report.get('K_f_source')})")
    path = _save(fig, Path(out_dir) / "flexure_wrench.png")
    close(fig)
    return [path]


def gains(report: dict[str, Any], prediction: FlexurePrediction) -> tuple[dict, dict]:
    """Loop base: the wrench m_x..f_z (N mm, N) -> the twist w_x..v_z (rad, mm) through the
    compliance K_f^-1 of the built flexure (designlab units)."""
    C = np.linalg.inv(prediction.K_true)
    outs = {tw: {w: float(C[i, j]) for j, w in enumerate(WRENCH)} for i, tw in enumerate(TWIST)}
    return outs, {o: ("rad" if o.startswith("w") else "mm") for o in outs}


def finish(report: dict[str, Any], prediction: FlexurePrediction, part, protocol) -> None:
    """Seed 002's force-sensing test with its noise budget beside Table I (in place):
    ``report["force_error_test"]`` (:func:`designlab.sensors.flexure.force_error.run_force_test`
    on the built flexure: pose noise 25 um, hysteresis 3.5 % of range, K_c fitted on 92 points
    and tested on 410, the error split into pose noise / hysteresis / model error).
    ``wrench_error.table_I_forces_N`` stays what it was: the noise-free closed form against the
    truth (model error only)."""
    from designlab.sensors.flexure.force_error import run_force_test

    r = run_force_test(prediction.K_true, prediction.K_design)
    report["force_error_test"] = r
    report["wrench_error"]["table_I_forces_N_note"] = (
        "noise-free closed form vs the built flexure (model error only); seed 002's Table I "
        "test with its noise and hysteresis is force_error_test")


def apply_model(*args, **kw):
    """loop -> predict: :func:`designlab.sensors.flexure.loop.apply_model`."""
    from designlab.sensors.flexure.loop import apply_model as apply

    return apply(*args, **kw)


def _meshed(settings) -> bool:
    return settings.truth == "fem"


#: the flexure's physics (:class:`~designlab.sensors.definition.Physics`), plugged into its
#: definition (:class:`designlab.sensors.flexure.definition.SpringFlexure`): the spring's
#: closed form or its beam chain with coil contact and friction (``truth``)
BEAM_CHAIN = Physics(
    name="beam chain", paper="seed 002 (fingertip on a helical spring flexure, Visiflex)",
    protocol=FlexureWrenchTest, settings=FlexureModelSettings, run=run, plots=plots,
    gains=gains, hooks=dict(finish=finish, meshed=_meshed, apply_model=apply_model,
                            uncertainty=MONTE_CARLO, validate=validate))
