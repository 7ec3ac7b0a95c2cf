"""Seed 002: the pose reference point from the measured K_c, found by the loop.

    python examples/flexure_kc_loop.py --out out/kc_loop [--seed 0] [--folds 5] [--no-peer]
                                       [--pose-at centre|camera] [--output v_x ...]

Seed 002 fitted its 6x6 K_c by least squares on (pose, wrench) data of its hysteresis tests,
with mirrored data for the axis the 5-dof LIPMM does not drive (Sec. V-B-2), and its wrench map
from 92 (X_c, F_c) pairs at poses "chosen randomly within the workspace", tested on 410 more
(Sec. V-B-3; a global linear fit did as well as the nonlinear ones): the LIPMM set the dome's
pose, the ATI sensor read the wrench in the camera frame {c}. The pairs are not published,
only the fitted matrix, so this example *reconstructs* such an experiment from the measured K_c
and lets the loop look for the pose reference point in it:

1. poses drawn uniformly at random, 92 training + 410 validation: translations over the ranges
   of Sec. V-A (1 mm along x_c and y_c, 4 mm along z_c: +-0.5 / +-0.5 / +-2 mm; Sec. V-B-3 says
   only "randomly within the workspace"), rotations +-0.05 rad about each axis (the paper gives
   no rotation range; +-0.05 rad is the loop amplitude of docs/validation/flexure.md);
2. wrench = measured K_c (its 21 fitted upper-triangular entries, mirrored as the paper does)
   x pose, SI -> N mm, N; noise: the LIPMM's repeatability on the pose (1 um, 0.001 deg, Sec.
   V) and on the wrench the ATI-like noise assumed by examples/flexure_stiffness.py (3 N mm,
   0.05 N: an assumption, the paper gives none);
3. a dataset card + two CSVs (train / validate) in ``OUT/data``; the base is the compliance
   ``designlab predict flexure`` writes as model.json (default design: the beam chain at the
   10 N working load, frame {f} at the spring centre) with the wrench taken in the camera
   frame at the paper's 11.09 mm offset (seed 002 eq. 3) and the twist left about the spring
   centre (``--pose-at centre``, default: the pose point is what the loop fits) or moved to
   the camera frame too (``--pose-at camera``), written as ``OUT/base_model.json``
   (:func:`design_base`);
4. the loop as ``designlab loop --data OUT/data/kc_card.toml --base OUT/base_model.json
   --folds 5 --out OUT/loop`` runs it (the same library calls): 92 training rows are too few
   for the default 10 blocks (10 rows per block needed).

The loop finds the offset in a signal generated from the measured K_c, not in raw
measurements. Printed: the effects accepted per output, the fitted ``pose_reference`` offsets
``e`` (v_x from w_y, v_y from w_x, and their mean) -> the height of the model's spring
centre above the point the data's pose is about (``-e``; ``11.09 mm - e`` with ``--pose-at
camera``) beside the measured K_c's zero-coupling point (5.45 mm), the paper's 11.09 mm and
``fit_camera_offset`` of the same model; validation RMSE before/after per output; and what is
left (the rocking terms: rotations do not depend on the point a pose is reported about).
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

import numpy as np

TWIST = ("w_x", "w_y", "w_z", "v_x", "v_y", "v_z")
WRENCH = ("m_x", "m_y", "m_z", "f_x", "f_y", "f_z")
N_TRAIN, N_VALIDATE = 92, 410            #: seed 002 Sec. V-B-3
POSE_RANGE = (0.05, 0.05, 0.05, 0.5, 0.5, 2.0)   #: +- rad, rad, rad, mm, mm, mm (see above)
POSE_NOISE = (math.radians(0.001),) * 3 + (1e-3,) * 3   #: LIPMM repeatability (rad, mm)
WRENCH_NOISE = (3.0,) * 3 + (0.05,) * 3  #: N mm, N (examples/flexure_stiffness.py's assumption)


def measured_kc() -> np.ndarray:
    """Seed 002's measured K_c in designlab units (N mm/rad, N/mm, N): the upper triangle as
    fitted, mirrored (the printed matrix differs from its mirror at (2,5)/(5,2), 1-based)."""
    from designlab.sensors.flexure.report import load_paper
    from designlab.sensors.flexure.spring import from_si

    M = load_paper()["K_c_measured"]
    return from_si(np.triu(M) + np.triu(M, 1).T)


def draw(rng: np.random.Generator, n: int, K: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``n`` random poses (rad, mm) and their wrenches ``K X`` (N mm, N), both with noise."""
    X = rng.uniform(-1.0, 1.0, (n, 6)) * np.asarray(POSE_RANGE)
    W = X @ K.T + rng.normal(size=(n, 6)) * np.asarray(WRENCH_NOISE)
    return X + rng.normal(size=(n, 6)) * np.asarray(POSE_NOISE), W


def write_data(folder: Path, seed: int = 0) -> Path:
    """Train/validate CSVs and their dataset card in ``folder``; returns the card."""
    rng = np.random.default_rng(seed)
    K = measured_kc()
    folder.mkdir(parents=True, exist_ok=True)
    head = "t," + ",".join(WRENCH + TWIST)
    for name, n in (("train", N_TRAIN), ("validate", N_VALIDATE)):
        X, W = draw(rng, n, K)
        rows = np.column_stack([np.arange(n, dtype=float), W, X])   # one pose per second
        np.savetxt(folder / f"kc_{name}.csv", rows, delimiter=",", header=head, comments="",
                   fmt="%.9g")
    chan = lambda names, unit: "\n".join(  # noqa: E731
        f'{c} = {{ column = "{c}", unit = "{unit(c)}" }}' for c in names)
    card = folder / "kc_card.toml"
    card.write_text(
        "# Seed 002's force-sensing experiment reconstructed from its measured K_c\n"
        f"# (examples/flexure_kc_loop.py, seed {seed}): random poses, wrench = K_c x pose.\n"
        '[[files]]\npath = "kc_train.csv"\nrole = "train"\n'
        '[[files]]\npath = "kc_validate.csv"\nrole = "validate"\n'
        '[time]\ncolumn = "t"\nunit = "s"\n'
        "[inputs]\n" + chan(WRENCH, lambda c: "Nmm" if c.startswith("m") else "N") + "\n"
        "[outputs]\n" + chan(TWIST, lambda c: "rad" if c.startswith("w") else "mm") + "\n"
        "[repair]\ndropouts = false\nspikes = false\n")
    return card


def design_base(path: Path, pose_at: str = "centre") -> dict:
    """``designlab predict flexure``'s model (default design: compliance ``C_f`` in {f}, the
    spring centre) with the wrench taken in the camera frame {c}, the spring centre 11.09 mm
    above the camera origin along z (the paper's K_f -> K_c): ``W_f = Ad(T_cf)^T W_c``. The
    twist is given about the spring centre (``pose_at="centre"``: ``C_f Ad^T``, the pose point
    left to the loop: ``pose_reference`` then reads ``e = -11.09 mm`` on data of this model in
    {c}) or in {c} (``"camera"``: ``Ad C_f Ad^T``, seed 002 eq. 3; ``e`` is then the
    correction to 11.09 mm). Saved at ``path``; returns what it is."""
    from designlab.frames import adjoint, transform
    from designlab.sensors.flexure.report import camera_offset, fit_camera_offset, load_paper
    from designlab.sensors.flexure.spring import to_si
    from designlab.predict.run import predict

    if pose_at not in ("centre", "camera"):
        raise SystemExit(f"--pose-at {pose_at!r}: centre or camera")
    pred = predict("flexure")
    model = pred.sensor_model()
    p = model.base.parameters
    C_f = np.array([[p[o]["gains"][w] for w in WRENCH] for o in TWIST])
    h_mm = 1e3 * camera_offset(load_paper())
    Ad = adjoint(transform(translation=(0.0, 0.0, h_mm)))
    C = C_f @ Ad.T if pose_at == "centre" else Ad @ C_f @ Ad.T
    for i, o in enumerate(TWIST):
        p[o]["gains"] = {w: float(C[i, j]) for j, w in enumerate(WRENCH)}
    model.provenance = {**model.provenance, "frame": (
        f"wrench in the camera frame {{c}} (the spring centre {h_mm:.2f} mm above its origin, "
        "seed 002 eq. 3), twist " + ("about the spring centre" if pose_at == "centre"
                                     else "in {c}"))}
    model.save(path)
    K_f_si = to_si(np.linalg.inv(C_f))
    return {"h_mm": h_mm, "pose_at": pose_at, "C": C, "K_f_source": pred.metrics.get("K_f_source"),
            "chain": pred.metrics.get("chain"), "K_f_si": K_f_si,
            "fit_camera_offset": fit_camera_offset(K_f_si, load_paper()["K_c_measured"])}


def rocking(K_si: np.ndarray) -> dict:
    """Zero-coupling point (mm above the frame's origin) and the rocking stiffness k_wx, k_wy
    (N m/rad) at the elastic centre (``report.rocking_at_elastic_centre``: ``1 / C[i, i]``, the
    same about every point): what no pose point can reach."""
    from designlab.sensors.flexure.report import rocking_at_elastic_centre, zero_coupling_point

    k_wx, k_wy = rocking_at_elastic_centre(K_si)
    return {"zero_coupling_mm": 1e3 * zero_coupling_point(K_si), "k_wx": k_wx, "k_wy": k_wy}


def population_offsets(C: np.ndarray, K: np.ndarray) -> dict:
    """The least-squares ``e`` of an endless sample of these data (independent uniform poses,
    no noise, ``pose_reference`` fitted first): ``w`` is one pose coordinate, so ``e`` is the
    residual map ``I - C K`` at (translation, partner rotation) times the sign: v_x from w_y
    (+1), v_y from w_x (-1), v_z from w_y along x (-1). mm."""
    R = np.eye(6) - C @ K
    return {"v_x": float(R[3, 1]), "v_y": float(-R[4, 0]), "v_z (axis x)": float(-R[5, 1])}


def other_order(train, model, outputs: list[str]) -> dict:
    """``pose_reference`` fitted on all training data before and after ``gain_offset`` (the
    loop takes it first): ``e`` (mm) each way and the gain fitted first."""
    from designlab.loop import effects as fx

    rows = np.ones(len(train), bool)
    out = {}
    for o in outputs:
        y, yhat, inputs = train.outputs[o], model.predict(train, o), model.base.inputs[o]
        ctx = fx.Context(train, o, yhat, inputs)
        pose = fx.fit(fx.EFFECTS["pose_reference"](), ctx, y - yhat, rows)
        gain = fx.fit(fx.EFFECTS["gain_offset"](), ctx, y - yhat, rows)
        y2 = yhat + fx.contribution(gain, ctx)
        after = fx.fit(fx.EFFECTS["pose_reference"](), fx.Context(train, o, y2, inputs),
                       y - y2, rows)
        out[o] = {"e_first": pose.beta[0], "axis_first": pose.theta["axis"],
                  "relative_gain_first": gain.beta[1], "e_after_gain": after.beta[0],
                  "axis_after_gain": after.theta["axis"]}
    return out


def run(out: Path, seed: int = 0, folds: int = 5, peer: bool = True,
        pose_at: str = "centre", outputs: list[str] | None = None) -> dict:
    """Data, base and the loop (``designlab loop``'s library calls); returns the numbers."""
    from designlab.loop.loop import run_loop
    from designlab.loop.model import load_model
    from designlab.loop.report import write_outputs
    from designlab.measured.dataset import load_card
    from designlab.sensors.flexure.report import load_paper

    out = Path(out)
    card = write_data(out / "data", seed)
    base_path = out / "base_model.json"
    base = design_base(base_path, pose_at)
    result = run_loop(load_card(card), load_model(base_path), outputs=outputs, folds=folds,
                      peer=peer)
    write_outputs(result, out / "loop")
    rep = result.report["outputs"]
    offsets, rejected = {}, {}
    for o in [o for o in ("v_x", "v_y", "v_z") if o in rep]:
        tried = [rd["candidates"]["pose_reference"] for rd in rep[o]["rounds"]
                 if "pose_reference" in rd["candidates"]]
        if tried:
            rejected[o] = tried[0]
        for e in rep[o]["effects"]:
            if e["name"] == "pose_reference":
                offsets[o] = {k: e["parameters"][k] for k in ("offset", "axis", "partner")}
    ref = base["h_mm"] if pose_at == "camera" else 0.0
    order = other_order(load_card(card).train(), load_model(base_path),
                        [o for o in ("v_x", "v_y") if o in rep])
    implied = {o: ref - v["offset"] for o, v in offsets.items() if v["axis"] == "z"}
    return {"base": base, "base_path": base_path, "report": result.report, "offsets": offsets,
            "first_cv": rejected, "other_order": order,
            "population": population_offsets(base["C"], measured_kc()),
            "implied_zero_coupling_mm": implied,
            "implied_mean_mm": float(np.mean(list(implied.values()))) if implied else None,
            "measured": rocking(load_paper()["K_c_measured"]),
            "model": rocking(base["K_f_si"]), "card": card}


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, required=True)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--pose-at", default="centre", choices=("centre", "camera"))
    ap.add_argument("--no-peer", action="store_true")
    ap.add_argument("--output", action="append", choices=TWIST,
                    help="output(s) to run the loop on (default: all six)")
    a = ap.parse_args(argv)
    r = run(a.out, a.seed, a.folds, not a.no_peer, a.pose_at, a.output)
    b, rep = r["base"], r["report"]["outputs"]
    print(f"data: {r['card']} ({N_TRAIN} training + {N_VALIDATE} validation poses, seed "
          f"{a.seed}; reconstructed from the measured K_c, not raw measurements)")
    chain = b["chain"] or {}
    print(f"base: designlab predict flexure (truth {b['K_f_source']}, seat {chain.get('seat')}, "
          f"{chain.get('working_load_N')} N working load; K_f diagonal (SI) "
          + ", ".join(f"{v:.4g}" for v in np.diag(b["K_f_si"]))
          + f"), wrench in the camera frame (h = {b['h_mm']:.2f} mm), twist "
          + ("about the spring centre" if b["pose_at"] == "centre" else "in the camera frame"))
    print(f"loop: designlab loop --data {r['card']} --base {r['base_path']} --folds {a.folds} "
          f"--out {a.out / 'loop'}")
    for o in [o for o in TWIST if o in rep]:
        x = rep[o]
        print(f"{o}: validation RMSE {x['error_before']:.4g} -> {x['error_after']:.4g} "
              f"{x['unit']} (unexplained {100 * x['unexplained_fraction']:.1f} %"
              + (f"; {x['peer']['kind']} peer {x['peer']['error']:.4g}" if x.get("peer")
                 else "") + ")")
        for e in x["effects"]:
            cv = e["evidence"]["cv"]
            print(f"    {e['key']}: {_params(e['parameters'])}; CV {100 * cv['relative']:+.1f} % "
                  f"({cv['fit']}), validation {e['error_before']:.4g} -> {e['error_after']:.4g}")
        print(f"    stopped: {x['stopped']}")
        for k, rd in enumerate(x["rounds"], 1):
            alone = [c["relative"] for c in rd["candidates"].values()
                     if c.get("fit") == "alone" and c.get("relative") is not None]
            if alone and rd["accepted"]:
                print(f"    round {k}: {len(alone)} per-input candidates (an intercept beside "
                      f"each, the loaded base's gains kept): CV median "
                      f"{100 * np.median(alone):+.1f} %, best "
                      f"{100 * max(alone):+.1f} % (accepted {rd['accepted']})")
    for o, v in r["offsets"].items():
        z = r["implied_zero_coupling_mm"].get(o)
        print(f"pose_reference on {o}: e = {v['offset']:+.3f} mm along {v['axis']} (partner "
              f"{v['partner']})" + (f" -> pose point {z:.2f} mm below the model's spring centre"
                                    if z is not None else ""))
    for o, cv in r["first_cv"].items():
        if o not in r["offsets"]:
            print(f"pose_reference on {o}: not accepted (first round: CV "
                  f"{100 * cv['relative']:+.1f} %, {cv['z']:.2f} standard errors, better in "
                  f"{cv['blocks_improved']} of {cv['blocks']} blocks)")
    for o, v in r["other_order"].items():
        print(f"order on {o} (all training data): pose_reference first e = {v['e_first']:+.2f} mm "
              f"(axis {v['axis_first']}); gain_offset first (relative gain "
              f"{v['relative_gain_first']:+.3f}), then e = {v['e_after_gain']:+.2f} mm (axis "
              f"{v['axis_after_gain']})")
    print("e of an endless sample of these data (population_offsets): " + ", ".join(
        f"{k} {v:+.2f} mm" for k, v in r["population"].items()))
    m, d = r["measured"], r["model"]
    if r["implied_mean_mm"] is not None:
        n = len(r["implied_zero_coupling_mm"])
        print(f"mean over the {n} output(s) with an offset along z: {r['implied_mean_mm']:.2f} "
              f"mm; measured K_c's zero-coupling point {m['zero_coupling_mm']:.2f} mm above the "
              f"camera origin; paper geometry {b['h_mm']:.2f} mm")
    f = b["fit_camera_offset"]
    print(f"fit_camera_offset (same model, 8 K_c entries): {1e3 * f['offset_m']:.2f} mm")
    print(f"rocking (rotations are the same about every point: no pose point changes w_x, w_y): "
          f"at the elastic centre, measured K_c k_wx {m['k_wx']:.3f}, k_wy {m['k_wy']:.3f} "
          f"N m/rad; the model {d['k_wx']:.3f}, {d['k_wy']:.3f} (its zero-coupling point "
          f"{d['zero_coupling_mm']:+.2f} mm from the spring centre)")


def _params(p: dict) -> str:
    keep = {k: v for k, v in p.items() if k not in ("unit", "base_adjust", "form")}
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                     for k, v in keep.items())


if __name__ == "__main__":
    main()
