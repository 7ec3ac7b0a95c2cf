"""Compensation benchmark (seed 000): fit times on 13,500 samples and real-data accuracy.

Seed 000 reports ~1 min for an mPL fit and 4-6 min for the NARX network (Matlab, 2.6 GHz
dual-core i5, 180 s tasks at 75 Hz = 13,500 samples). Goals here: mPL < 5 s, NARX < 30 s.

Part 1 -- synthetic, the paper's shape: two hysteretic gauges (forward mPL models of
Ch1 <- F_n + F_x and Ch2 <- F_n - F_x), 13,500 samples at dt = 13.3 ms; compensators
u = (Ch1, Ch2) -> y = (F_n, F_x). Peers in the same run: the mPL fit with scipy's own one-
parameter-at-a-time finite differences (``jacobian="2-point"``) instead of the batched
Jacobian; the scan simulation against the forward-Euler time loop and a plain Python loop.

Part 2 -- real stretch data (../shared/data/stretch): estimate the load-cell force F (N) from
the 4-wire resistance Ri; train on multisine_600s_1, validate on multisine_300s_2 and the random
sawtooth; linear vs mPL vs NARX (input-output net of seed 000) vs NARX with 50 fed-back output
delays (closed loop). Loaded through a dataset card (designlab.measured.dataset).

Run from the project root:  OMP_NUM_THREADS=1 python benchmarks/bench_compensation.py
"""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from designlab.measured import compensation as comp  # noqa: E402
from designlab.measured import mpl, narx  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
STRETCH = ROOT.parent / "shared" / "data" / "stretch"


def synthetic_gauges(T: int = 13_500, dt: float = mpl.DT_PAPER, seed: int = 0):
    """Forces (T, 2) and two hysteretic gauge signals (T, 2), in N and V."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * dt
    fn = np.zeros(T)
    fx = np.zeros(T)
    for f in rng.uniform(0.05, 1.5, 6):
        fn += rng.uniform(0.5, 1.5) * np.sin(2 * np.pi * f * t + rng.uniform(0, 6))
        fx += rng.uniform(0.1, 0.4) * np.sin(2 * np.pi * f * 1.3 * t + rng.uniform(0, 6))
    fn = 4 + fn * (t % 30 < 24)              # holds (creep) every 30 s
    gauge = mpl.MPLParams(w0=1.0, w=(-0.25, -0.1), V_b=0.0, P_T=(0.3, 0.5),
                          P_S=(0.3 / (2 * 0.4), 0.5 / (2 * 8.0)), g=(0.0, 0.05, 0.004))
    ch1 = gauge.simulate(fn + fx, dt)
    ch2 = gauge.simulate(fn - fx, dt)
    return np.column_stack([ch1, ch2]), np.column_stack([fn, fx]), dt


def _rmse(a, b):
    return float(np.sqrt(np.mean((np.asarray(a) - np.asarray(b)) ** 2)))


def part1() -> None:
    U, Y, dt = synthetic_gauges()
    T = U.shape[0]
    print(f"## synthetic: {T} samples, dt = {dt * 1e3:.1f} ms, 2 gauges -> (F_n, F_x); "
          f"F_n {Y[:, 0].min():.2f}..{Y[:, 0].max():.2f} N, F_x {Y[:, 1].min():.2f}..{Y[:, 1].max():.2f} N\n")
    print("| step | wall (s) | CPU (s) | result |")
    print("|---|---:|---:|---|")
    c = U[:, 0] + U[:, 1]                   # seed 000: F_n from Ch1 + Ch2
    for jac in ("batched", "2-point"):
        t0, c0 = time.perf_counter(), time.process_time()
        p, rep = mpl.fit(c, Y[:, 0], dt, cells=2, order=4, jacobian=jac)
        el, cpu = time.perf_counter() - t0, time.process_time() - c0
        print(f"| mPL fit F_n <- Ch1+Ch2, 2 cells, order 4, jacobian={jac} | {el:.2f} | {cpu:.2f} | "
              f"train RMSE {rep.rmse:.4f} N, {rep.starts} starts, {rep.iterations} evaluations, "
              f"{rep.jacobians} Jacobians |")
    t0, c0 = time.perf_counter(), time.process_time()
    p, rep = mpl.fit(c, Y[:, 0], dt, order=4)
    el, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"| mPL fit F_n, cells chosen on held-out 20 % | {el:.2f} | {cpu:.2f} | {rep.n_cells} cells, "
          f"train RMSE {rep.rmse:.4f} N, held-out RMSE by cells "
          f"{', '.join(f'{n}: {v:.4f}' for n, _, v in rep.history)} N |")
    for od in (0, 50):
        t0, c0 = time.perf_counter(), time.process_time()
        net, nrep = narx.fit(U, Y, narx.NARXParams(output_delays=od))
        el, cpu = time.perf_counter() - t0, time.process_time() - c0
        yc = net.predict(U)
        print(f"| NARX fit 2 in/2 out, 10 neurons, 50 input delays, {od} output delays | {el:.2f} | {cpu:.2f} | "
              f"{nrep.iterations} L-BFGS iterations; closed-loop RMSE F_n {_rmse(yc[:, 0], Y[:, 0]):.4f} N "
              f"(open loop {nrep.open_loop_rmse[0]:.4f} N) |")
    # simulation peers
    for update in ("exact", "euler"):
        q = mpl.with_update(p, update)
        t0, c0 = time.perf_counter(), time.process_time()
        for _ in range(5):
            q.states(c, dt)
        el, cpu = time.perf_counter() - t0, time.process_time() - c0
        crit = mpl.euler_stability(p, c, dt)
        note = ("vectorised scan, never overshoots" if update == "exact" else
                f"time loop; Euler criterion max dt(2P_S/P_T)cosh((u-s)/P_T) = {crit:.3g} "
                f"({'stable' if crit < 2 else 'UNSTABLE: simulate() refuses'})")
        print(f"| states of the fitted {p.n_cells}-cell model, {update} update (x5) | {el:.3f} | {cpu:.3f} | {note} |")
    t0, c0 = time.perf_counter(), time.process_time()
    s = np.empty((p.n_cells, T))
    s[:, 0] = c[0]
    pt, tau = np.array(p.P_T), np.array(p.tau)
    for k in range(T - 1):
        for i in range(p.n_cells):
            x = c[k] - s[i, k]
            s[i, k + 1] = c[k] - 2 * pt[i] * np.arctanh(np.tanh(x / (2 * pt[i])) *
                                                       np.exp(-dt / tau[i]))
    el, cpu = time.perf_counter() - t0, time.process_time() - c0
    print(f"| plain Python loop, exact update (x1) | {el:.3f} | {cpu:.3f} | max |scan - loop| = "
          f"{np.abs(p.states(c, dt) - s).max():.2e} |")
    print()


CARD = ROOT / "examples" / "cards" / "stretch_compensation.toml"


def part2() -> None:
    if not STRETCH.is_dir():
        print(f"(no real data: {STRETCH} missing)")
        return
    train, val = comp.records_from_card(CARD, ["resistance"], ["force"])
    print(f"## real stretch data: F (N) from Ri (ohm), {train[0].u.shape[0]} training samples at "
          f"{1 / train[0].dt:.2f} Hz\n")
    runs = [("linear", "linear", comp.CompensationOptions()),
            ("mpl", "mpl", comp.CompensationOptions()),
            ("narx (input-output)", "narx", comp.CompensationOptions()),
            ("narx (50 fed-back outputs, closed loop)", "narx",
             comp.CompensationOptions(narx_output_delays=50))]
    print("| model | fit wall (s) | " + " | ".join(f"{r.name} RMSE (N) / NCC" for r in train + val) + " |")
    print("|---|---:|" + "---:|" * (len(train) + len(val)))
    segs = {}
    for label, model, opts in runs:
        c, rep = comp.fit_compensator(model, train, opts)
        cells = []
        for r in train + val:
            yh = c.predict(r.u, r.dt)[:, 0]
            cells.append(f"{_rmse(yh, r.y[:, 0]):.3f} / {np.corrcoef(yh, r.y[:, 0])[0, 1]:.3f}")
        extra = ""
        if model == "mpl":
            po = rep["per_output"][0]
            extra = f" ({po['n_cells']} cell(s), tau {', '.join(f'{t:.3g}' for t in po['tau_s'])} s)"
        print(f"| {label}{extra} | {rep['time_s']:.2f} | " + " | ".join(cells) + " |")
        segs[label] = c
    res = comp.evaluate({k: segs[k] for k in ("linear", "mpl", "narx (input-output)")}, train + val,
                        train_names={r.name for r in train})
    print("\nWilcoxon signed-rank on 10 paired segment RMSEs (p-values):\n")
    for w in res.between_models:
        print(f"- {w['task']}: {w['a']} vs {w['b']}: p = {w['rmse']['p_value']:.3g}")
    print()


if __name__ == "__main__":
    print(f"# bench_compensation  (python {sys.version.split()[0]}, "
          f"OMP_NUM_THREADS={os.environ.get('OMP_NUM_THREADS')}, {os.cpu_count()} CPUs, shared machine)\n")
    part1()
    part2()
