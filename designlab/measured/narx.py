"""NARX neural network compensator of seed 000 (10 hidden neurons, 50 delays, 2 in, 2 out).

Seed 000 trains its network with Matlab's ``ntstool`` choosing the *nonlinear input-output*
problem, i.e. ``y(t) = f(x(t-1), ..., x(t-d))`` with no output feedback (a time-delay network):
for such a network open- and closed-loop use coincide. This module implements the general NARX
form ``y(t) = f(x(t), ..., x(t-d_x), y(t-1), ..., y(t-d_y))`` with one hidden tanh layer
(scikit-learn ``MLPRegressor``, L-BFGS instead of Matlab's Levenberg-Marquardt):

* ``output_delays=0`` is the paper's input-output network;
* ``output_delays>0`` is trained *series-parallel* (open loop: the measured past outputs are
  features) and used/evaluated *parallel* (closed loop: its own past estimates are fed back),
  because a compensator never sees the measured force.

Lagged features are built with ``numpy.lib.stride_tricks.sliding_window_view`` (no Python loop);
inputs and outputs are standardised per channel. The input taps include the current sample
(lag 0) besides the ``input_delays`` past ones: a compensator must respond instantaneously.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.lib.stride_tricks import sliding_window_view

from designlab.measured.linear_fit import as_2d
from designlab.errors import DataError
from designlab.params import rng, validate


@dataclass(frozen=True)
class NARXParams:
    """Network size and training settings (defaults: seed 000's input-output network, 10
    neurons, 50 input delays, no output feedback)."""

    hidden: int = field(default=10, metadata=rng(1, 1000, doc="hidden tanh neurons"))
    input_delays: int = field(default=50, metadata=rng(0, 5000, doc="past input samples"))
    output_delays: int = field(default=0, metadata=rng(
        0, 5000, doc="past output samples fed back (0: input-output network of seed 000)"))
    alpha: float = field(default=1e-3, metadata=rng(0, 100, doc="L2 penalty"))
    max_iter: int = field(default=400, metadata=rng(1, 100000, doc="L-BFGS iterations"))
    seed: int = field(default=0, metadata=rng(0, 2**31 - 1))

    def __post_init__(self):
        validate(self)

    @property
    def max_delay(self) -> int:
        return max(self.input_delays, self.output_delays)


@dataclass(frozen=True)
class NARXFitReport:
    iterations: int
    converged: bool
    rows: int               # training rows (samples with a full history)
    features: int
    open_loop_rmse: tuple[float, ...]   # one-step-ahead training RMSE per output, output unit
    time_s: float
    stride: int = 1         # trained on every stride-th row (a memory budget, ``max_rows``)


@dataclass(frozen=True, eq=False)
class NARXModel:
    """A trained network: per-channel scaling and the MLP weights (plain arrays)."""

    params: NARXParams
    u_mean: np.ndarray
    u_std: np.ndarray
    y_mean: np.ndarray
    y_std: np.ndarray
    W1: np.ndarray          # (features, hidden)
    b1: np.ndarray
    W2: np.ndarray          # (hidden, n_out)
    b2: np.ndarray
    y_init: np.ndarray      # output assumed before the first sample (output unit)

    @property
    def n_inputs(self) -> int:
        return self.u_mean.size

    @property
    def n_outputs(self) -> int:
        return self.y_mean.size

    def _u_part(self, u: np.ndarray) -> np.ndarray:
        """Hidden pre-activation from the input taps for every sample (edge-padded start),
        (T, hidden). The lagged taps are built :data:`CHUNK` rows at a time: never the whole
        (T, inputs x delays) matrix."""
        T = u.shape[0]
        out = np.empty((T, self.W1.shape[1]))
        for a, b, h in self._u_chunks(u):
            out[a:b] = h
        return out

    def _u_chunks(self, u: np.ndarray):
        """(first row, end row, hidden pre-activation of those rows), :data:`CHUNK` rows at a
        time."""
        p = self.params
        us = (u - self.u_mean) / self.u_std
        us = np.concatenate([np.repeat(us[:1], p.input_delays, 0), us])
        T = u.shape[0]
        W = self.W1[:us.shape[1] * (p.input_delays + 1)]
        for a in range(0, T, CHUNK):
            b = min(a + CHUNK, T)
            X = lagged(us[a:b + p.input_delays], 0, p.input_delays, p.input_delays)
            yield a, b, X @ W + self.b1

    def predict(self, u, *, y_init=None) -> np.ndarray:
        """Closed-loop (parallel) estimates (T, n_out) from inputs u (T, n_in).

        Past outputs are the model's own estimates; before the first sample they are
        ``y_init`` (default: the mean first output of the training records).
        """
        u = self._check_u(u)
        p = self.params
        if p.output_delays == 0:   # no feedback: chunk by chunk, no (T, hidden) array kept
            out = np.empty((u.shape[0], self.n_outputs))
            for a, b, h in self._u_chunks(u):
                out[a:b] = (np.tanh(h) @ self.W2 + self.b2) * self.y_std + self.y_mean
            return out
        h_u = self._u_part(u)
        na, T, c = p.output_delays, u.shape[0], self.n_outputs
        y0 = self.y_init if y_init is None else np.broadcast_to(np.asarray(y_init, float), (c,))
        buf = np.empty((na + T, c))
        buf[:na] = (y0 - self.y_mean) / self.y_std
        W1y = self.W1[-c * na:].reshape(c, na, -1).transpose(1, 0, 2).reshape(na * c, -1)
        W2, b2 = self.W2, self.b2
        for k in range(T):
            h = np.tanh(h_u[k] + buf[k:k + na].ravel() @ W1y)
            buf[na + k] = h @ W2 + b2
        return buf[na:] * self.y_std + self.y_mean

    def predict_open_loop(self, u, y) -> np.ndarray:
        """One-step-ahead (series-parallel) estimates using the *measured* past outputs y."""
        u = self._check_u(u)
        y = as_2d(y, "y")
        if y.shape != (u.shape[0], self.n_outputs):
            raise DataError(f"y must have shape ({u.shape[0]}, {self.n_outputs}), got {y.shape}")
        p = self.params
        h = self._u_part(u)
        if p.output_delays:
            ys = (y - self.y_mean) / self.y_std
            ys = np.concatenate([np.repeat(ys[:1], p.output_delays, 0), ys])
            h = h + lagged(ys, 1, p.output_delays, p.output_delays) @ \
                self.W1[-self.n_outputs * p.output_delays:]
        return (np.tanh(h) @ self.W2 + self.b2) * self.y_std + self.y_mean

    def _check_u(self, u) -> np.ndarray:
        u = as_2d(u, "u")
        if u.shape[1] != self.n_inputs:
            raise DataError(f"u has {u.shape[1]} channels, the network expects {self.n_inputs}")
        return u


def lagged(x: np.ndarray, first: int, last: int, start: int) -> np.ndarray:
    """Rows k = start..T-1 of the lagged copies x[k-last..k-first] of every channel.

    ``x`` (T, c) -> (T - start, c * (last - first + 1)), per channel in ascending time;
    requires ``start >= last``. A strided view, copied once by the reshape.
    """
    T, c = x.shape
    L = last - first
    win = sliding_window_view(x, L + 1, axis=0)          # (T - L, c, L + 1): x[i .. i+L]
    i0 = start - last
    return win[i0:i0 + T - start].reshape(T - start, c * (L + 1))


def lagged_rows(x: np.ndarray, first: int, last: int, start: int,
                rows: np.ndarray) -> np.ndarray:
    """:func:`lagged` at the rows ``rows`` (indices into its ``T - start`` rows) only: the
    other rows are never copied."""
    T, c = x.shape
    L = last - first
    win = sliding_window_view(x, L + 1, axis=0)
    return win[start - last + np.asarray(rows, int)].reshape(len(rows), c * (L + 1))


def features(u: np.ndarray, y: np.ndarray, params: NARXParams,
             rows: np.ndarray | None = None) -> np.ndarray:
    """Series-parallel design matrix of one standardised record (rows with a full history;
    only the rows ``rows``, indices among them, when given)."""
    D = params.max_delay
    if rows is None:
        X = [lagged(u, 0, params.input_delays, D)]
        if params.output_delays:
            X.append(lagged(y, 1, params.output_delays, D))
    else:
        X = [lagged_rows(u, 0, params.input_delays, D, rows)]
        if params.output_delays:
            X.append(lagged_rows(y, 1, params.output_delays, D, rows))
    return np.hstack(X)


#: rows of lagged taps built at a time when a network is applied to a long record
CHUNK = 65_536


def row_stride(n_rows: int, max_rows: int | None) -> int:
    """The stride of a deterministic subset of at most ``max_rows`` training rows out of
    ``n_rows`` (every ``stride``-th row of each record; 1: all rows)."""
    if max_rows is None or n_rows <= max_rows:
        return 1
    return -(-n_rows // max_rows)


def fit(u, y, params: NARXParams = NARXParams(),
        max_rows: int | None = None) -> tuple[NARXModel, NARXFitReport]:
    """Train the network series-parallel on inputs u (T, n_in) and targets y (T, n_out).

    ``u``/``y`` may be lists of records (each contributes its rows with a full history).
    ``max_rows``: a memory budget; with more training rows than that the network trains on
    every ``stride``-th row of each record (a deterministic subset, each row keeping its full
    history; ``NARXFitReport.stride``), the scaling still from every sample.
    """
    from sklearn.exceptions import ConvergenceWarning
    from sklearn.neural_network import MLPRegressor

    t0 = time.perf_counter()
    us, ys = (u, y) if isinstance(u, (list, tuple)) else ([u], [y])
    if not isinstance(ys, (list, tuple)) or len(ys) != len(us) or not us:
        raise DataError("u and y must both be arrays or lists of as many records")
    us = [as_2d(a, "u") for a in us]
    ys = [as_2d(b, "y") for b in ys]
    for i, (a, b) in enumerate(zip(us, ys)):
        if a.shape[0] != b.shape[0]:
            raise DataError(f"record {i}: u and y lengths differ ({a.shape[0]} vs {b.shape[0]})")
        if a.shape[1] != us[0].shape[1] or b.shape[1] != ys[0].shape[1]:
            raise DataError(f"record {i}: channel counts differ from record 0")
        if a.shape[0] <= params.max_delay + 1:
            raise DataError(f"record {i} has {a.shape[0]} samples; the NARX network needs more than "
                            f"{params.max_delay + 1} (input_delays={params.input_delays}, "
                            f"output_delays={params.output_delays})")
    U, Y = np.vstack(us), np.vstack(ys)
    u_mean, u_std = U.mean(0), _std(U)
    y_mean, y_std = Y.mean(0), _std(Y)
    D = params.max_delay
    stride = row_stride(sum(a.shape[0] - D for a in us), max_rows)
    sel = [None if stride == 1 else np.arange(0, a.shape[0] - D, stride) for a in us]
    X = np.vstack([features((a - u_mean) / u_std, (b - y_mean) / y_std, params, r)
                   for a, b, r in zip(us, ys, sel)])
    T = np.vstack([((b - y_mean) / y_std)[D:] if r is None else ((b[D:][r] - y_mean) / y_std)
                   for b, r in zip(ys, sel)])
    mlp = MLPRegressor(hidden_layer_sizes=(params.hidden,), activation="tanh", solver="lbfgs",
                       alpha=params.alpha, max_iter=params.max_iter, tol=1e-7,
                       random_state=params.seed)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", ConvergenceWarning)
        mlp.fit(X, T if T.shape[1] > 1 else T[:, 0])
    converged = not any(issubclass(w.category, ConvergenceWarning) for w in caught)
    W2 = mlp.coefs_[1].reshape(params.hidden, -1)
    model = NARXModel(params=params, u_mean=u_mean, u_std=u_std, y_mean=y_mean, y_std=y_std,
                      W1=mlp.coefs_[0], b1=mlp.intercepts_[0], W2=W2,
                      b2=np.atleast_1d(mlp.intercepts_[1]),
                      y_init=np.mean([b[0] for b in ys], axis=0))
    pred = mlp.predict(X).reshape(T.shape)
    ol = np.sqrt(np.mean((pred - T) ** 2, axis=0)) * y_std
    report = NARXFitReport(iterations=int(mlp.n_iter_), converged=converged, rows=X.shape[0],
                           features=X.shape[1], open_loop_rmse=tuple(float(v) for v in ol),
                           time_s=time.perf_counter() - t0, stride=stride)
    return model, report


def _std(a: np.ndarray, names: Sequence[str] | None = None) -> np.ndarray:
    """Per-channel standard deviation (the network's scaling); a one-line DataError naming the
    channels (``names``, else their indices) that are constant or vary too little to scale:
    a spread below :data:`~designlab.measured.dataset.MIN_SPREAD`, whose squares underflow."""
    from designlab.measured.dataset import MIN_SPREAD

    with np.errstate(under="ignore"):
        s = a.std(0)
    spread = np.ptp(a, axis=0)
    label = (lambda j: repr(names[j])) if names is not None else str
    flat = [label(j) for j in np.flatnonzero(spread == 0)]
    if flat:
        raise DataError(f"channel(s) {', '.join(flat)} are constant: nothing to learn from")
    tiny = np.flatnonzero(~(s >= MIN_SPREAD) | (spread < MIN_SPREAD))
    if tiny.size:
        j = tiny[0]
        raise DataError(f"channel(s) {', '.join(label(k) for k in tiny)} vary by "
                        f"{float(spread[j]):.3g} only; allowed: a spread >= {MIN_SPREAD:g}: a "
                        "smaller one is below the precision a fit needs (its squares "
                        "underflow to 0; is the unit right?)")
    return s
