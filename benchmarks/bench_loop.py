"""Loop benchmark: `designlab loop` on the 600 s stretch log (goal: under 60 s on a 2-core
machine with its peers, the NARX network and gradient-boosted trees, and the backward pass).

Times the stages of one loop on multisine_600s_1 (training, ~6,300 samples at 10 Hz after
resampling) validated on multisine_300s_2: reading the card (repair + resampling), the
stretch-fem base (FEM stiffness of the specimen), and the greedy effect search for force and
resistance, with the NARX peer (the default) side by side with the same loop without it and
with the plain NARX fit alone (seed 000's network, both outputs: what the peer costs), and each
peer's fit time inside the loop (per output). Peers in the same run: the loop with the closed-form base (no FEM), the loop from the `linear` base,
and the loop at the logs' own ~12 Hz rate. Prints one table.

Run from the project root:  OMP_NUM_THREADS=1 python benchmarks/bench_loop.py
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

os.environ.setdefault("OMP_NUM_THREADS", "1")

from designlab.loop import base_models  # noqa: E402
from designlab.measured.dataset import load_card  # noqa: E402
from designlab.loop.loop import fit_peer, run_loop  # noqa: E402
from designlab.loop.report import write_outputs  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CARD = ROOT / "examples" / "stretch_card.toml"


def timed(fn):
    t = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t


def main() -> None:
    rows = []
    ds, t_load = timed(lambda: load_card(CARD))
    rows.append(("read card (repair, 3 clocks -> 10 Hz)", t_load, f"{len(ds)} samples", ""))
    base_models.specimen_stiffness_factor.cache_clear()
    k, t_fem = timed(lambda: base_models.specimen_stiffness_factor())
    rows.append(("FEM stiffness of the specimen (TET10)", t_fem, f"factor {k:.4f}", ""))
    for label, base, card_ds in (("loop, base stretch-fem", "stretch-fem", ds),
                                 ("loop, base stretch-closed (peer)", "stretch-closed", ds),
                                 ("loop, base linear (peer)", "linear", ds)):
        res, t = timed(lambda: run_loop(card_ds, base))
        errs = "; ".join(f"{o} {r['error_before']:.4g} -> {r['error_after']:.4g} {r['unit']}"
                         for o, r in res.report["outputs"].items())
        eff = "; ".join(f"{o}: " + (", ".join(e["key"] for e in r["effects"]) or "none")
                        for o, r in res.report["outputs"].items())
        rows.append((label, t, errs, eff))
        if base == "stretch-fem":
            res0, t0 = timed(lambda: run_loop(card_ds, base, peer=False))
            errs0 = "; ".join(f"{o} {r['error_after']:.4g} {r['unit']}"
                              for o, r in res0.report["outputs"].items())
            rows.append(("  the same loop without the NARX peer", t0, errs0, ""))
            peers, t_n = timed(lambda: {o: fit_peer(card_ds, o) for o in card_ds.outputs})
            perr = "; ".join(f"{o} peer {r['peer']['error']:.4g} {r['unit']}"
                             for o, r in res.report["outputs"].items())
            rows.append(("  plain NARX fit alone (both outputs)", t_n, perr,
                         ", ".join(f"{o}: {info['iterations']} iterations"
                                   for o, (_, info) in peers.items())))
            for o, r in res.report["outputs"].items():
                for p in r["peers"]:
                    rows.append((f"  peer {p['kind']} of {o} (inside the loop)", p["time_s"],
                                 f"{p['error']:.4g} {r['unit']}",
                                 "best" if p["kind"] == r["best_peer"] else ""))
                dropped = ", ".join(d["key"] for d in r["dropped"]) or "nothing"
                rows.append((f"  backward pass on {o}", float("nan"), f"dropped {dropped}", ""))
            with tempfile.TemporaryDirectory() as tmp:
                _, t_w = timed(lambda: write_outputs(res, tmp))
            rows.append(("write loop.json, model.json, plots", t_w, "", ""))
    text = CARD.read_text().replace("rate = 10.0", "# rate: the logs' own")
    with tempfile.TemporaryDirectory() as tmp:
        card12 = Path(tmp) / "card12.toml"
        card12.write_text(text.replace("../../shared", str(ROOT.parent / "shared")))
        ds12 = load_card(card12)
        res, t = timed(lambda: run_loop(ds12, "stretch-fem"))
    errs = "; ".join(f"{o} {r['error_before']:.4g} -> {r['error_after']:.4g} {r['unit']}"
                     for o, r in res.report["outputs"].items())
    rows.append((f"loop at {ds12.report['rate_hz']:.1f} Hz (peer)", t, errs, ""))
    total = t_load + t_fem + sum(r[1] for r in rows if r[0] in ("loop, base stretch-fem",
                                                        "write loop.json, model.json, plots"))
    w = max(len(r[0]) for r in rows)
    print(f"{'stage':<{w}}  {'time (s)':>8}  result")
    for name, t, res_text, eff in rows:
        when = f"{'-':>8}" if math.isnan(t) else f"{t:8.2f}"   # nan: not timed on its own
        print(f"{name:<{w}}  {when}  {res_text}" + (f"  [{eff}]" if eff else ""))
    loop_t = next(r[1] for r in rows if r[0] == "loop, base stretch-fem")
    print(f"{'loop of the 600 s log, peers included (goal under 60 s)':<{w}}  "
          f"{loop_t:8.2f}  {'OK' if loop_t < 60 else 'SLOW'}")
    print(f"{'card -> loop -> outputs':<{w}}  {total:8.2f}")


if __name__ == "__main__":
    main()
