"""The numbers of the printed F/T sensor's page (docs/sensors/printed_ft.md): the predicted
sensitivity (edge rise per N and per N m at each fork), its Fz-normalised rows, the condition
numbers, the force and moment error from the forks' noise over the 60 load states, stress and
safety factor, and how each open assumption of the description moves them.

    python examples/sensors/printed_ft_study.py            # everything (several FEM runs)
    python examples/sensors/printed_ft_study.py --quick    # the default design only
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from designlab.fem.materials import get_material
from designlab.fem.stress import case_stresses, stress_report
from designlab.geometry.parts import make_part
from designlab.sensors.generic.virtual import run, settings_class
from designlab.sensors.registry import resolve

HERE = Path(__file__).resolve().parent
LOADS = ("Fx", "Fy", "Fz", "Mx", "My", "Mz")
#: N m -> N mm: the moment columns are printed per N m
PER_N_M = np.array([1, 1, 1, 1e3, 1e3, 1e3])


def design(**kw):
    return make_part(resolve(str(HERE / "printed_ft.py")), kw)


def elastic(part, **kw):
    """The virtual test with instantaneous elastic readings (no viscoelastic march)."""
    return run(part, settings=settings_class(type(part))(viscoelastic=False, **kw))


def matrix(report, key="sensitivity"):
    """(8, 6) of a report's per-channel dict, columns Fx..Mz."""
    rows = report[key]
    return np.array([[v for v in rows[c["name"]].values()] for c in report["channels"]])


def cond(K, scale_mm=None):
    s = np.ones(6) if scale_mm is None else np.r_[1, 1, 1, [scale_mm] * 3]
    sv = np.linalg.svd(K * s, compute_uv=False)
    return float(sv[0] / sv[-1])


def show(title, K, names, fmt="{:9.4f}"):
    print(f"\n{title}")
    print(" " * 10 + "".join(f"{n:>10}" for n in LOADS))
    for n, row in zip(names, K):
        print(f"{n:<10}" + "".join(fmt.format(v).rjust(10) for v in row))


def rotation_error(K):
    """Largest departure from the 4-fold symmetry: fork j + 2 (next module, same side) under a
    wrench equals fork j under that wrench turned back by the module spacing (+90 deg about
    z_T, -90 deg about z_S), relative to the largest entry."""
    R = np.array([[0.0, 1, 0], [-1, 0, 0], [0, 0, 1]])        # -90 deg about z_S
    R6 = np.kron(np.eye(2), R)
    pred = np.roll(K, 2, axis=0) @ R6.T
    return float(np.abs(pred - K).max() / np.abs(K).max())


def default_run():
    part = design()
    t0 = time.perf_counter()
    res = run(part)
    dt = time.perf_counter() - t0
    rep = res.report
    names = [c["name"] for c in rep["channels"]]
    K = matrix(rep)
    print(f"default design: {rep['mesh']['dof']} DOF ({rep['mesh']['n_cells']} cells, edge "
          f"{type(part).edge_length:g} mm, arms {part.arm_edge:g} mm), run() {dt:.0f} s "
          f"(viscoelastic march {'on' if rep['viscoelastic'] else 'off'})")
    show("sensitivity, counts per N and per N m (frame S)", K * PER_N_M, names, "{:9.2f}")
    show("edge rise, um per N and per N m", K * PER_N_M / part.gain * 1e3, names, "{:9.2f}")
    show("rows divided by their Fz entry (gain-free)", matrix(rep, "sensitivity_normalised"),
         names)
    print(f"\ncondition number of the sensitivity: raw (N, N mm) "
          f"{rep['sensitivity_condition_number']:.1f}, moments per 55 mm "
          f"{rep['sensitivity_condition_number_scaled']:.2f}")
    print(f"condition number of the least-squares calibration matrix: raw "
          f"{rep['condition_number']:.3g}, scaled {rep['condition_number_scaled']:.3g}")
    print(f"4-fold symmetry: largest departure {rotation_error(K):.2%} of the largest entry")
    fe = rep["force_error"]
    print(f"force and moment error from {part.noise:g} count(s) rms per reading, over the 60 "
          f"states ({fe['repeats']} noise draws): " + ", ".join(
              f"{k.split('_')[-1]} {v * (1 if k[-2] == 'F' else 1e-3):.3g} "
              f"{'N' if k[-2] == 'F' else 'N m'}" for k, v in fe["rms"].items()))
    P = res.loads
    print(f"largest load of the protocol: |F| {np.linalg.norm(P[:, :3], axis=1).max():.2f} N, "
          f"|M| {np.linalg.norm(P[:, 3:], axis=1).max() / 1e3:.3f} N m")
    rise = np.abs(res.readings).max(axis=0) / part.gain
    print(f"largest edge rise over the protocol: {rise.max():.3f} mm (fork "
          f"{names[int(np.argmax(rise))]}; the forks' 10-90 % window is about 0.6 mm)")
    n3 = 3 * res.mesh.n_points
    cases = {f"state {k}": ("", res.state_U[:n3, k].reshape(-1, 3)) for k in range(len(P))}
    st = stress_report(res.mesh, case_stresses(res.mesh, cases))
    crit = st["critical"]
    print(f"stress over the 60 states: largest von Mises {st['max_von_mises_MPa']:.2f} MPa "
          f"({crit['body']}, {crit['load_case']}), min safety factor "
          f"{st['min_safety_factor']:.1f} against {crit['strength_MPa']:g} MPa")
    return part, res


def compare(label, K, K0):
    """A variant's condition numbers and how far its normalised rows move from the base's."""
    N, N0 = K / K[:, [2]], K0 / K0[:, [2]]
    mov = np.abs(N - N0).max()
    print(f"  {label:<42} cond raw {cond(K):6.1f}  scaled {cond(K, 55):5.2f}  |K|/|K0| "
          f"{np.linalg.norm(K) / np.linalg.norm(K0):5.3f}  normalised rows move {mov:.4f}")


def assumptions(res0):
    base = elastic(design())
    K0 = matrix(base.report)
    print("\nopen assumptions (elastic readings; the base design first)")
    compare("base: PLA, hub face clamped, mid-edge", K0, K0)
    compare("viscoelastic march (the default run)", matrix(res0.report), K0)
    abs_ = elastic(design(material="ABS"))
    pla, abs_m = get_material("PLA"), get_material("ABS")
    compare(f"ABS (E {abs_m.E:g} vs {pla.E:g} MPa)", matrix(abs_.report), K0)
    print(f"    E_PLA / E_ABS = {pla.E / abs_m.E:.3f}: a single isotropic material scales every "
          f"displacement by 1/E (nu aside)")
    for a in (0.8, 0.6):
        Ka = K0.copy()
        Ka[:, [2, 3, 4]] /= a       # Fz, Mx, My bend the arms across the layers
        compare(f"across-layer modulus x {a:g} (column scaling)", Ka, K0)
    for op in (0.25, 0.75):
        compare(f"operating point {op:g} along the 45-deg edge",
                matrix(elastic(design(operating_point=op)).report), K0)
    compare("clamped at the four bolts only", matrix(elastic(design(clamp="bolts")).report), K0)
    compare("finer arms (arm_edge 2.0 mm)", matrix(elastic(design(arm_edge=2.0)).report), K0)
    rng = np.random.default_rng(0)
    conds = []
    for _ in range(200):
        g = rng.uniform(0.5, 1.5, 8) * rng.choice((-1, 1), 8)
        Kg = g[:, None] * K0
        assert np.allclose(Kg / Kg[:, [2]], K0 / K0[:, [2]])
        conds.append((cond(Kg), cond(Kg, 55)))
    c = np.array(conds)
    print(f"  per-channel gains x U(0.5, 1.5) with random signs (200 draws): normalised rows "
          f"unchanged; cond raw {c[:, 0].min():.1f}..{c[:, 0].max():.1f}, scaled "
          f"{c[:, 1].min():.2f}..{c[:, 1].max():.2f}")
    tool_side_mass(res0, K0)


def tool_side_mass(res0, K0):
    """The tool side's own weight (ring, fin pads, fins; 100 % infill) left out of the labels:
    the calibration fits readings that carry it to loads that do not."""
    part = design()
    b = part.bodies()
    vol = b["ring"].shape.volume + b["fins"].shape.volume             # mm^3
    m = vol * get_material(part.material).density * 1e3               # t -> kg
    cog = np.array([0.0, 0.0, -7.5])                                 # the ring's middle, S
    P = res0.loads
    F = m * 9.81 * P[:, :3] / np.linalg.norm(P[:, :3], axis=1, keepdims=True)  # along g
    Pt = P + np.c_[F, np.cross(cog, F)]
    S = Pt @ K0.T
    C, *_ = np.linalg.lstsq(S, P, rcond=None)
    err = np.sqrt(np.mean((S @ C - P) ** 2, axis=0))
    print(f"  tool side's own weight not in the labels ({m * 1e3:.0f} g at z_S -7.5 mm): "
          f"calibration residual rms " + ", ".join(
              f"{n} {e * (1 if i < 3 else 1e-3):.3g}" for i, (n, e) in enumerate(zip(LOADS, err)))
          + " (N, N m)")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="the default design only")
    a = ap.parse_args()
    np.set_printoptions(precision=4, suppress=True, linewidth=140)
    _, res0 = default_run()
    if not a.quick:
        assumptions(res0)


if __name__ == "__main__":
    main()
