"""Black-box peers of the loop: what a model with no physics learns from the same training runs.

Two families, each fitted until its error on an inner split stops falling (the last
:data:`INNER_FRACTION` of every training run is held out of the fit; the validation data are
never seen):

- ``narx``: seed 000's time-delay network (:mod:`designlab.measured.narx`: tanh neurons on the
  current and past inputs), L-BFGS in steps of :data:`NARX_STEP` iterations from the weights
  reached, the weights with the lowest inner-split error kept;
- ``gbt``: gradient-boosted trees (scikit-learn ``HistGradientBoostingRegressor``) on lagged
  inputs and history features (running maximum and minimum in the run, rate, exponential
  moving averages), the number of trees chosen on the inner split.

Each peer reports its inner-split and validation errors and how its fit ended (``converged``:
the inner error stopped falling or the optimiser converged before the iteration cap).
"""

from __future__ import annotations

import time
import warnings

import numpy as np
from threadpoolctl import threadpool_limits

from designlab.calibration.metrics import rmse
from designlab.errors import DataError
from designlab.measured.dataset import Dataset

#: share of each training run (its end) held out of a peer's fit to stop it
INNER_FRACTION = 0.2
#: L-BFGS iterations between two looks at the NARX peer's inner-split error
NARX_STEP = 50
#: the NARX peer's iteration cap
NARX_MAX_ITER = 3000
#: steps without a lower inner-split error before the NARX peer stops
NARX_PATIENCE = 3
#: the tree peer's cap on boosting iterations (trees)
GBT_MAX_ITER = 1000
#: input lags of the tree peer (s)
GBT_LAGS_S = (0.0, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0)
#: time constants of the tree peer's moving averages (s)
GBT_TAUS_S = (1.0, 10.0)


def varying_inputs(data: Dataset) -> list[str]:
    """The inputs that vary in the training data (a peer learns from those)."""
    tr = data.role == "train"
    names = [n for n in data.inputs if np.ptp(data.inputs[n][tr]) > 0]
    if not names:
        raise DataError("no input varies in the training data: the peer has nothing to learn")
    return names


def inner_split(data: Dataset) -> tuple[np.ndarray, np.ndarray]:
    """(inner fit, inner held-out) masks over ``data``: each training run's last
    :data:`INNER_FRACTION` of its training samples held out."""
    tr = data.role == "train"
    fit, held = np.zeros(len(data), bool), np.zeros(len(data), bool)
    for s in np.unique(data.segment[tr]):
        idx = np.flatnonzero(tr & (data.segment == s))
        cut = idx[int(round((1 - INNER_FRACTION) * idx.size))] if idx.size > 1 else idx[-1] + 1
        fit[idx[idx < cut]] = True
        held[idx[idx >= cut]] = True
    return fit, held


def fit_peers(data: Dataset, output: str, max_rows: int | None) -> list[tuple[np.ndarray, dict]]:
    """Every peer's prediction of every sample of ``data`` and its record (kind, errors on
    the inner split and the validation data, how its fit ended, time)."""
    vmask = data.role == "validate"
    y = data.outputs[output]
    out = []
    for fit in (narx_peer, gbt_peer):
        t0 = time.perf_counter()
        # one thread: small fits, and on a shared machine threads cost far more than they give
        with threadpool_limits(1):
            pred, info = fit(data, output, max_rows)
        info["error"] = rmse(y[vmask], pred[vmask])
        info["time_s"] = time.perf_counter() - t0
        out.append((pred, info))
    return out


def _records(data: Dataset, names: list[str], output: str, mask: np.ndarray):
    """(inputs, outputs) of each run's samples in ``mask``, one record per run."""
    us, ys = [], []
    for s in np.unique(data.segment[mask]):
        m = mask & (data.segment == s)
        us.append(np.column_stack([data.inputs[n][m] for n in names]))
        ys.append(data.outputs[output][m][:, None])
    return us, ys


def narx_peer(data: Dataset, output: str, max_rows: int | None) -> tuple[np.ndarray, dict]:
    """The NARX network (seed 000's size) fitted by L-BFGS until its inner-split error stops
    falling; its prediction of every sample (each run from its start)."""
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor

    from designlab.measured import narx

    names = varying_inputs(data)
    params = narx.NARXParams()
    fit_m, held_m = inner_split(data)
    us, ys = _records(data, names, output, fit_m)
    short = [u.shape[0] for u in us if u.shape[0] <= params.max_delay + 1]
    if short:
        raise DataError(f"a training run's inner fit part has {short[0]} samples; the NARX "
                        f"peer needs more than {params.max_delay + 1}")
    U, Y = np.vstack(us), np.vstack(ys)
    u_mean, u_std = U.mean(0), narx._std(U, names)
    y_mean, y_std = Y.mean(0), narx._std(Y, [output])
    D = params.max_delay
    stride = narx.row_stride(sum(a.shape[0] - D for a in us), max_rows)
    sel = [None if stride == 1 else np.arange(0, a.shape[0] - D, stride) for a in us]
    X = np.vstack([narx.features((a - u_mean) / u_std, (b - y_mean) / y_std, params, r)
                   for a, b, r in zip(us, ys, sel)])
    T = np.concatenate([(((b - y_mean) / y_std)[D:] if r is None
                         else (b[D:][r] - y_mean) / y_std)[:, 0] for b, r in zip(ys, sel)])
    mlp = MLPRegressor(hidden_layer_sizes=(params.hidden,), activation="tanh", solver="lbfgs",
                       alpha=params.alpha, max_iter=NARX_STEP, tol=1e-7,
                       random_state=params.seed, warm_start=True)

    def model_of(m) -> narx.NARXModel:
        return narx.NARXModel(params=params, u_mean=u_mean, u_std=u_std, y_mean=y_mean,
                              y_std=y_std, W1=m.coefs_[0].copy(), b1=m.intercepts_[0].copy(),
                              W2=m.coefs_[1].reshape(params.hidden, -1).copy(),
                              b2=np.atleast_1d(m.intercepts_[1]).copy(),
                              y_init=np.mean([b[0] for b in ys], axis=0))

    best, best_err, best_it, it, since, how = None, np.inf, 0, 0, 0, "iteration cap"
    while it < NARX_MAX_ITER:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", ConvergenceWarning)
            mlp.fit(X, T)
        it += int(mlp.n_iter_)
        model = model_of(mlp)
        err = _inner_error(data, names, output, held_m, model.predict, run_wise=True)
        if err < best_err:
            best, best_err, best_it, since = model, err, it, 0
        else:
            since += 1
        if not any(issubclass(w.category, ConvergenceWarning) for w in caught):
            how = "L-BFGS converged"
            break
        if since >= NARX_PATIENCE:
            how = "early stopping: the inner-split error stopped falling"
            break
    pred = _run_wise(data, names, best.predict)
    info = {"kind": "narx", "inputs": names, "hidden": params.hidden,
            "input_delays": params.input_delays, "delay_s": params.input_delays * data.dt,
            "seed": params.seed, "iterations": it, "best_iteration": best_it,
            "converged": how != "iteration cap", "stopped": how, "inner_error": best_err,
            "rows": int(X.shape[0]), "stride": stride}
    return pred, info


def _run_wise(data: Dataset, names: list[str], predict) -> np.ndarray:
    """A sequence model's prediction of every sample, each run from its start."""
    pred = np.empty(len(data))
    for s in np.unique(data.segment):
        m = data.segment == s
        pred[m] = predict(np.column_stack([data.inputs[n][m] for n in names]))[:, 0]
    return pred


def _inner_error(data: Dataset, names: list[str], output: str, held: np.ndarray, predict,
                 run_wise: bool) -> float:
    """RMSE of ``predict`` on the inner held-out samples (the runs predicted from their start
    when ``run_wise``)."""
    pred = _run_wise(data, names, predict) if run_wise else predict(held)
    return rmse(data.outputs[output][held], pred[held])


def history_features(data: Dataset, names: list[str]) -> np.ndarray:
    """The tree peer's features of every sample: each input at :data:`GBT_LAGS_S`, its rate,
    its running maximum and minimum in the run and its moving averages (:data:`GBT_TAUS_S`)."""
    from designlab.loop import effects as fx
    from designlab.loop.effects.mullins import running_max

    cols = []
    for n in names:
        x = data.inputs[n]
        cols += [fx.shift(x, L, data.t, data.segment) if L > 0 else x for L in GBT_LAGS_S]
        cols.append(fx.rate(x, data.dt, data.segment))
        cols += [running_max(x, data.segment), -running_max(-x, data.segment)]
        cols += [x - fx.highpass(x, tau, data.dt, data.segment) for tau in GBT_TAUS_S]
    return np.column_stack(cols)


def gbt_peer(data: Dataset, output: str, max_rows: int | None) -> tuple[np.ndarray, dict]:
    """Gradient-boosted trees on lagged inputs and history features; the number of trees is
    the one with the lowest inner-split error (at most :data:`GBT_MAX_ITER`)."""
    from sklearn.ensemble import HistGradientBoostingRegressor

    names = varying_inputs(data)
    X = history_features(data, names)
    y = data.outputs[output]
    fit_m, held_m = inner_split(data)
    rows = np.flatnonzero(fit_m)
    stride = 1 if max_rows is None or rows.size <= max_rows else -(-rows.size // max_rows)
    rows = rows[::stride]
    hgb = HistGradientBoostingRegressor(max_iter=GBT_MAX_ITER, learning_rate=0.1,
                                        early_stopping=False, random_state=0)
    hgb.fit(X[rows], y[rows])
    yh = y[held_m]
    errs = np.array([rmse(yh, p) for p in hgb.staged_predict(X[held_m])])
    best = int(np.argmin(errs)) + 1
    converged = best < GBT_MAX_ITER
    pred = next(p for k, p in enumerate(hgb.staged_predict(X), 1) if k == best)
    info = {"kind": "gbt", "inputs": names, "features": int(X.shape[1]),
            "lags_s": list(GBT_LAGS_S), "moving_average_tau_s": list(GBT_TAUS_S),
            "history": ["running maximum", "running minimum", "rate", "moving averages"],
            "iterations": GBT_MAX_ITER, "best_iteration": best, "converged": converged,
            "stopped": ("early stopping: the inner-split error is lowest at "
                        f"{best} trees" if converged else "iteration cap"),
            "inner_error": float(errs[best - 1]), "rows": int(rows.size), "stride": stride}
    return pred, info
