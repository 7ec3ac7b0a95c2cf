"""Compensation models of seed 000 behind one interface, and their evaluation.

Protocol (seed 000's inter/intra idea): fit every model on the training record(s) (task 1),
apply it to the other records (tasks), and compare per model, task and output channel with the
normalised cross-correlation at zero lag and the RMSE (:mod:`designlab.calibration.metrics`).
Wilcoxon signed-rank tests need paired samples: each record is cut into ``n_segments``
contiguous segments and the per-segment RMSE/NCC are paired -- between models on the same
segments of a task, and between tasks by segment index (seed 000 paired by subject instead).

Models (inputs u = sensor channels, outputs y = reference forces):

* ``linear`` -- first-order fit per output of its channel (seed 000: Ch1 + Ch2 -> F_n,
  Ch1 - Ch2 -> F_x), :mod:`designlab.measured.linear_fit`;
* ``mpl``    -- one mPL model per output, fitted as a compensator (input: the linear estimate of
  that output, an affine map of seed 000's sum/difference channel; output: the reference),
  :mod:`designlab.measured.mpl`;
* ``narx``   -- a 10-neuron network on 50 input delays (seed 000), all inputs -> all outputs,
  :mod:`designlab.measured.narx`; closed-loop when output delays are fed back.
"""

from __future__ import annotations

import dataclasses
import itertools
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Protocol, Sequence

import numpy as np

from designlab.atomic import FileSet, os_error
from designlab.measured import linear_fit
from designlab.measured import mpl
from designlab.measured import narx
from designlab.measured.dataset import MAX_CARD_SAMPLES
from designlab.measured.linear_fit import as_2d
from designlab.calibration.metrics import ncc, rmse, wilcoxon
from designlab.errors import DataError, ParameterError
from designlab.params import rng, validate

MODELS = ("linear", "mpl", "narx")
#: most samples (training and validation records together) the costly models take at their
#: default settings (one input, one output): the size whose fit and closed-loop evaluation
#: stays within about two minutes on two cores (the measurement is in the changelog); the cost
#: grows with the samples, so a larger record is refused before the fit rather than run for
#: many minutes
MAX_FIT_SAMPLES = {"mpl": 200_000, "narx": 200_000}


@dataclass(frozen=True, eq=False)
class Record:
    """One task: sensor channels u (T, n_in), reference y (T, n_out), sampled every dt s."""

    name: str
    u: np.ndarray
    y: np.ndarray
    dt: float
    inputs: tuple[str, ...] = ()
    outputs: tuple[str, ...] = ()

    def __post_init__(self):
        u, y = as_2d(self.u, f"{self.name}: inputs"), as_2d(self.y, f"{self.name}: outputs")
        if u.shape[0] != y.shape[0]:
            raise DataError(f"{self.name}: inputs and outputs lengths differ "
                            f"({u.shape[0]} vs {y.shape[0]} samples)")
        if not (np.isfinite(self.dt) and self.dt > 0):
            raise ParameterError("dt", self.dt, "a sample period > 0 s")
        object.__setattr__(self, "u", u)
        object.__setattr__(self, "y", y)
        object.__setattr__(self, "inputs", tuple(self.inputs) or
                           tuple(f"u{i}" for i in range(u.shape[1])))
        object.__setattr__(self, "outputs", tuple(self.outputs) or
                           tuple(f"y{i}" for i in range(y.shape[1])))


@dataclass(frozen=True)
class CompensationOptions:
    """Settings of the three models and of the evaluation."""

    mix: str = field(default="auto", metadata=rng(choices=linear_fit.MIXES,
                                                  doc="channel per output (linear, mpl)"))
    mpl_cells: int = field(default=0, metadata=rng(0, 8, doc="0: add cells while held-out "
                                                              "error improves"))
    mpl_max_cells: int = field(default=3, metadata=rng(1, 8))
    mpl_order: int = field(default=5, metadata=rng(0, 9, doc="degree of g (Table II: g0..g5)"))
    mpl_update: str = field(default="exact", metadata=rng(choices=mpl.UPDATES))
    narx_hidden: int = field(default=10, metadata=rng(1, 1000))
    narx_input_delays: int = field(default=50, metadata=rng(0, 5000))
    narx_output_delays: int = field(default=0, metadata=rng(
        0, 5000, doc="0: seed 000's input-output network; > 0: NARX, closed loop"))
    narx_max_iter: int = field(default=400, metadata=rng(1, 100000))
    n_segments: int = field(default=10, metadata=rng(2, 1000, doc="segments per record for "
                                                                  "the Wilcoxon pairs"))
    seed: int = field(default=0, metadata=rng(0, 2**31 - 1))

    def __post_init__(self):
        validate(self)


class Compensator(Protocol):
    """A fitted compensation model: sensor channels (T, n_in) -> force estimates (T, n_out)."""

    name: str

    def predict(self, u: np.ndarray, dt: float) -> np.ndarray: ...


@dataclass(frozen=True)
class LinearCompensator:
    fit: linear_fit.LinearFit
    name: str = "linear"

    def predict(self, u, dt):
        return self.fit.predict(u)


@dataclass(frozen=True)
class MPLCompensator:
    """mPL per output on the linear estimate of that output."""

    linear: linear_fit.LinearFit
    models: tuple[mpl.MPLParams, ...]
    name: str = "mpl"

    def predict(self, u, dt):
        c = self.linear.predict(u)
        return np.column_stack([m.simulate(c[:, j], dt) for j, m in enumerate(self.models)])


@dataclass(frozen=True)
class NARXCompensator:
    model: narx.NARXModel
    name: str = "narx"

    def predict(self, u, dt):
        return self.model.predict(u)


def _common_dt(records: Sequence[Record]) -> float:
    dts = np.array([r.dt for r in records])
    if np.ptp(dts) > 0.01 * dts.min():
        raise DataError(f"records have different sample periods {dts.tolist()} s: resample first")
    return float(dts.mean())


def _check_shapes(records: Sequence[Record], like: Record) -> None:
    for r in records:
        if r.u.shape[1] != like.u.shape[1] or r.y.shape[1] != like.y.shape[1]:
            raise DataError(f"{r.name}: {r.u.shape[1]} inputs/{r.y.shape[1]} outputs, but "
                            f"{like.name} has {like.u.shape[1]}/{like.y.shape[1]}")


def fit_compensator(model: str, train: Sequence[Record],
                    options: CompensationOptions = CompensationOptions()
                    ) -> tuple[Compensator, dict]:
    """Fit one model on the training records; returns it and a JSON-able fit report."""
    if model not in MODELS:
        raise ParameterError("model", model, "one of " + ", ".join(MODELS))
    if not train:
        raise DataError("no training record given")
    _check_shapes(train, train[0])
    dt = _common_dt(train)
    U, Y = np.vstack([r.u for r in train]), np.vstack([r.y for r in train])
    t0 = time.perf_counter()
    lin = linear_fit.fit_linear(U, Y, options.mix)
    if model == "linear":
        return LinearCompensator(lin), {"time_s": time.perf_counter() - t0,
                                        "A": lin.A, "b": lin.b, "channels": lin.channels}
    if model == "mpl":
        models, reports = [], []
        for j in range(Y.shape[1]):
            cs = [lin.predict(r.u)[:, j] for r in train]
            ys = [r.y[:, j] for r in train]
            p, rep = mpl.fit(cs, ys, dt, cells=options.mpl_cells or None,
                             max_cells=options.mpl_max_cells, order=options.mpl_order,
                             update=options.mpl_update, seed=options.seed)
            models.append(p)
            reports.append({"output": train[0].outputs[j], "params": dataclasses.asdict(p),
                            "tau_s": p.tau, **dataclasses.asdict(rep)})
        return MPLCompensator(lin, tuple(models)), {"time_s": time.perf_counter() - t0,
                                                    "per_output": reports}
    params = narx.NARXParams(hidden=options.narx_hidden, input_delays=options.narx_input_delays,
                             output_delays=options.narx_output_delays,
                             max_iter=options.narx_max_iter, seed=options.seed)
    net, rep = narx.fit([r.u for r in train], [r.y for r in train], params)
    return NARXCompensator(net), {"time_s": time.perf_counter() - t0,
                                  "params": dataclasses.asdict(params),
                                  **dataclasses.asdict(rep)}


def segment_metrics(y: np.ndarray, yhat: np.ndarray, n_segments: int) -> tuple[list, list]:
    """Per-segment RMSE and NCC of one channel (contiguous, nearly equal segments)."""
    if y.size < 2 * n_segments:
        raise DataError(f"{y.size} samples cannot be cut into {n_segments} segments of >= 2")
    idx = np.array_split(np.arange(y.size), n_segments)
    return ([rmse(y[i], yhat[i]) for i in idx], [ncc(y[i], yhat[i]) for i in idx])


@dataclass
class CompensationResult:
    """Fits, the metrics table and the Wilcoxon tables of one comparison."""

    fits: dict
    rows: list
    between_models: list
    between_tasks: list
    predictions: dict = field(repr=False)

    def to_json(self) -> dict:
        return {"units": "RMSE in the output unit (N for forces); NCC dimensionless",
                "fits": self.fits, "metrics": self.rows,
                "wilcoxon_between_models": self.between_models,
                "wilcoxon_between_tasks": self.between_tasks}

    def table(self) -> list[tuple]:
        """(model, task, role, output, RMSE, NCC) rows for printing."""
        return [(r["model"], r["task"], r["role"], r["output"], r["rmse"], r["ncc"])
                for r in self.rows]


def _wilcoxon_safe(a, b) -> dict:
    a, b = np.asarray(a, float), np.asarray(b, float)
    if np.allclose(a, b, rtol=0, atol=1e-15):
        return {"statistic": 0.0, "p_value": 1.0}
    return wilcoxon(a, b)


def evaluate(compensators: dict, records: Sequence[Record], *, train_names=(),
             n_segments: int = 10) -> CompensationResult:
    """Apply each fitted compensator to each record; metrics per model, task and output."""
    rows, preds = [], {}
    for name, comp in compensators.items():
        for rec in records:
            yhat = comp.predict(rec.u, rec.dt)
            preds[(name, rec.name)] = yhat
            for j, out in enumerate(rec.outputs):
                seg_r, seg_c = segment_metrics(rec.y[:, j], yhat[:, j], n_segments)
                rows.append({"model": name, "task": rec.name, "output": out,
                             "role": "train" if rec.name in train_names else "validate",
                             "rmse": rmse(rec.y[:, j], yhat[:, j]),
                             "ncc": ncc(rec.y[:, j], yhat[:, j]),
                             "segment_rmse": seg_r, "segment_ncc": seg_c})
    key = {(r["model"], r["task"], r["output"]): r for r in rows}
    models = list(compensators)
    tasks = [r.name for r in records]
    outputs = records[0].outputs if records else ()
    between_models, between_tasks = [], []
    for task, out in itertools.product(tasks, outputs):
        for a, b in itertools.combinations(models, 2):
            ra, rb = key[(a, task, out)], key[(b, task, out)]
            between_models.append({"task": task, "output": out, "a": a, "b": b,
                                   "rmse": _wilcoxon_safe(ra["segment_rmse"], rb["segment_rmse"]),
                                   "ncc": _wilcoxon_safe(ra["segment_ncc"], rb["segment_ncc"])})
    for model, out in itertools.product(models, outputs):
        for a, b in itertools.combinations(tasks, 2):
            ra, rb = key[(model, a, out)], key[(model, b, out)]
            between_tasks.append({"model": model, "output": out, "a": a, "b": b,
                                  "rmse": _wilcoxon_safe(ra["segment_rmse"], rb["segment_rmse"]),
                                  "ncc": _wilcoxon_safe(ra["segment_ncc"], rb["segment_ncc"])})
    return CompensationResult({}, rows, between_models, between_tasks, preds)


def compare(train: Sequence[Record], validate_on: Sequence[Record], models=MODELS,
            options: CompensationOptions = CompensationOptions(),
            progress: Callable[[str], None] | None = None) -> CompensationResult:
    """Fit ``models`` on ``train`` and evaluate on the training and validation records."""
    models = tuple(models)
    for m in models:
        if m not in MODELS:
            raise ParameterError("model", m, "one of " + ", ".join(MODELS))
    if not models:
        raise ParameterError("model", "", "at least one of " + ", ".join(MODELS))
    records = list(train) + list(validate_on)
    names = [r.name for r in records]
    if len(set(names)) != len(names):
        raise DataError(f"record names must be unique, got {names}")
    if train:
        _check_shapes(records, train[0])
    fitted, fits = {}, {}
    rows = sum(len(r.u) for r in records)
    if rows > MAX_CARD_SAMPLES:
        raise DataError(f"the records hold {rows} samples; at most {MAX_CARD_SAMPLES} in all (the "
                        "memory budget of a dataset card: shorten or decimate the files)")
    _check_cost(models, rows, records[0], options)
    for m in models:
        if progress:
            progress(f"fitting {m}")
        try:
            fitted[m], fits[m] = fit_compensator(m, train, options)
        except np.linalg.LinAlgError as exc:
            big = max(float(np.max(np.abs(r.u))) for r in train)
            raise DataError(f"the {m} fit on the training records failed ({exc}): their inputs "
                            f"are constant, collinear or of an extreme scale (largest |input| "
                            f"{big:.3g})") from None
    if progress:
        progress("evaluating")
    res = evaluate(fitted, records, train_names={r.name for r in train},
                   n_segments=options.n_segments)
    res.fits = fits
    return res


def fit_limit(model: str, like: Record, options: CompensationOptions) -> int | None:
    """The most samples (all records together) ``model`` is fitted on with these options:
    :data:`MAX_FIT_SAMPLES` scaled down by the work per sample beyond the measured default
    (one mPL fit per output and per cell; NARX features, neurons and iterations). None: no
    limit (the linear fit)."""
    base = MAX_FIT_SAMPLES.get(model)
    if base is None:
        return None
    n_in, n_out = like.u.shape[1], like.y.shape[1]
    o = options
    if model == "mpl":
        factor = n_out * max(o.mpl_cells or o.mpl_max_cells, 3) / 3
    else:
        feats = o.narx_input_delays * n_in + o.narx_output_delays * n_out
        factor = max(feats, 50) / 50 * max(o.narx_hidden, 10) / 10 * max(o.narx_max_iter, 400) / 400
    return int(base / max(factor, 1.0))


def _check_cost(models: Sequence[str], rows: int, like: Record,
                options: CompensationOptions) -> None:
    """Refuse, before any fit, a costly model on more samples than :func:`fit_limit` allows
    (such a fit runs for many minutes): one line naming the model, the samples, the limit."""
    for m in models:
        limit = fit_limit(m, like, options)
        if limit is not None and rows > limit:
            raise DataError(f"the records hold {rows} samples; the {m} model fits at most {limit} "
                            "(about 2 minutes on 2 cores with these settings): use --model linear, "
                            "or shorten or decimate the files")


# ----------------------------------------------------------------------------- files

def load_record(path: str | Path, inputs: Sequence[str], outputs: Sequence[str], *,
                time: str | None = None, dt: float | None = None) -> Record:
    """A :class:`Record` from named columns of a CSV (header row) or Parquet file, uniformly
    sampled; the sample period from ``dt`` (s) or a time column. For raw logs (several clocks,
    dropouts, units) write a dataset card instead (:func:`records_from_card`)."""
    if (time is None) == (dt is None):
        raise ParameterError("--time/--dt", f"time={time!r}, dt={dt!r}",
                             "exactly one of a time column or a sample period")
    from designlab.measured.dataset import MIN_TIME_STEP_S, _numeric, read_table

    cols = list(inputs) + list(outputs) + ([time] if time else [])
    table = read_table(Path(path))
    data = {c: _numeric(table, c, Path(path), spread=c != time) for c in cols}
    if time:
        steps = np.diff(data[time])
        if steps.size == 0 or np.any(steps <= 0):
            raise DataError(f"{path}: time column {time!r} must increase strictly")
        if steps.min() < MIN_TIME_STEP_S:
            raise DataError(f"{path}: time column {time!r} has a step of {steps.min():.3g} s; "
                            f"allowed: steps >= {MIN_TIME_STEP_S:g} s (is the time unit right?)")
        dt = float(np.median(steps))
        if np.max(np.abs(steps - dt)) > 0.05 * dt:
            raise DataError(f"{path}: time column {time!r} is not uniformly sampled "
                            f"(steps {steps.min():.4g}..{steps.max():.4g} s): resample first")
    return Record(name=Path(path).stem, u=np.column_stack([data[c] for c in inputs]),
                  y=np.column_stack([data[c] for c in outputs]), dt=float(dt),
                  inputs=tuple(inputs), outputs=tuple(outputs))


def records_from_dataset(ds, inputs: Sequence[str], outputs: Sequence[str]
                         ) -> tuple[list[Record], list[Record]]:
    """(train, validate) records from a :class:`~designlab.measured.dataset.Dataset`: one
    record per run and role, channels picked by name (sensor signals -> ``inputs``, reference
    -> ``outputs``, whichever side of the card declares them)."""
    train, val = [], []
    dt = ds.dt
    for s, info in enumerate(ds.segments):
        stem = Path(str(info.get("path", f"run {s}"))).stem
        for role in ("train", "validate"):
            m = (ds.segment == s) & (ds.role == role)
            if m.sum() < 2:
                continue
            split = not str(info.get("role", "")) in ("train", "validate")
            rec = Record(name=f"{stem}:{role}" if split else stem,
                         u=np.column_stack([ds.channel(c)[m] for c in inputs]),
                         y=np.column_stack([ds.channel(c)[m] for c in outputs]), dt=dt,
                         inputs=tuple(inputs), outputs=tuple(outputs))
            (train if role == "train" else val).append(rec)
    if not train:
        raise DataError("the dataset has no training samples (role = \"train\" or a [split])")
    return train, val


def records_from_card(path: str | Path, inputs: Sequence[str], outputs: Sequence[str]
                      ) -> tuple[list[Record], list[Record]]:
    """(train, validate) records from a dataset card (TOML), see :func:`records_from_dataset`."""
    from designlab.measured.dataset import load_card

    return records_from_dataset(load_card(path), inputs, outputs)


def write_outputs(result: CompensationResult, records: Sequence[Record],
                  out_dir: str | Path) -> list[Path]:
    """``compensation.json`` (metrics, fits, Wilcoxon tables) and ``compensation.png``
    (measured vs estimated outputs), written as a set: a failed write (a full disk, a folder
    by either name) leaves both as they were."""
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    jpath, ppath = out / "compensation.json", out / "compensation.png"
    fig = plot(result, records)
    try:
        with FileSet() as files:
            tmp = files.path(ppath)
            try:
                fig.savefig(str(tmp), dpi=90, format="png")
            except OSError as exc:
                raise os_error(ppath, exc) from None
            files.write_json(jpath, result.to_json())
    finally:
        plt.close(fig)
    return [jpath, ppath]


def plot(result: CompensationResult, records: Sequence[Record]):
    """Figure: one panel per record and output, measured vs each model's estimate over time."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    models = sorted({m for m, _ in result.predictions}, key=lambda m: MODELS.index(m)
                    if m in MODELS else 99)
    panels = [(r, j) for r in records for j in range(r.y.shape[1])]
    fig, axes = plt.subplots(len(panels), 1, figsize=(11, 2.6 * len(panels)), squeeze=False)
    met = {(r["model"], r["task"], r["output"]): r for r in result.rows}
    for ax, (rec, j) in zip(axes[:, 0], panels):
        t = np.arange(rec.y.shape[0]) * rec.dt
        ax.plot(t, rec.y[:, j], color="k", lw=1.2, label="measured")
        for m in models:
            r = met[(m, rec.name, rec.outputs[j])]
            ax.plot(t, result.predictions[(m, rec.name)][:, j], lw=0.8,
                    label=f"{m} (RMSE {r['rmse']:.3g}, NCC {r['ncc']:.3f})")
        role = "train" if met[(models[0], rec.name, rec.outputs[j])]["role"] == "train" \
            else "validate"
        ax.set_title(f"{rec.name} [{role}]: {rec.outputs[j]}", fontsize=9)
        ax.set_xlabel("t (s)")
        ax.legend(fontsize=7, loc="upper right")
    fig.tight_layout()
    return fig
