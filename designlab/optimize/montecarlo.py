"""``designlab predict PART --samples N``: the Monte Carlo of :mod:`designlab.predict.uncertainty`
on the sweep executors (local processes or a Dask cluster), stored as it goes and resumable.

Layout of ``OUT``::

    fem/<key>.npz                 the design's FEM stage (computed once, by the parent)
    samples/<run>.<batch>.json    the builds of one batch (atomic; a rerun skips them)
    uncertainty.json              the summary (:func:`designlab.predict.uncertainty.summarize`)

``<run>`` hashes the spec, the design, settings, protocol and the designlab version: a changed
input never reuses old builds.
"""

from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any, Callable

from designlab.errors import ModelError, OutputError, ParameterError
from designlab.optimize.failures import is_write_failure, write_failure_message
from designlab.predict.uncertainty import (UncertaintySpec, _fem_stage, build_values, draw,
                                           run_batch, summarize)


def _run_key(spec: UncertaintySpec, params, settings, protocol) -> str:
    from designlab.version import __version__
    from designlab.atomic import jsonable

    blob = json.dumps(jsonable({"spec": spec.to_json(), "params": params,
                                "settings": settings or {}, "protocol": protocol or {},
                                "designlab": __version__}), sort_keys=True)
    return hashlib.sha256(blob.encode()).hexdigest()[:20]


def no_build_message(summary: dict[str, Any], rows: list[dict[str, Any]]) -> str:
    """One line for a Monte Carlo whose every build failed: how many, and the first error."""
    first = next((r.get("error") for r in rows if r.get("status") != "ok"), None) or "?"
    kinds = len(summary.get("failed_errors") or {})
    return (f"all {summary['builds']} builds of the Monte Carlo failed, so it has no result "
            f"(first error: {first}" + (f"; {kinds} different errors" if kinds > 1 else "")
            + "): check the [uncertainty] distributions against the inputs' ranges")


def monte_carlo(sensor: str, spec: UncertaintySpec, out: str | Path, *,
                params: dict[str, Any] | None = None, settings: dict[str, Any] | None = None,
                protocol: dict[str, Any] | None = None, executor=None,
                progress: Callable[[int, int], None] | None = None,
                files=None) -> dict[str, Any]:
    """N virtual builds of one design on ``executor`` (local processes by default), stored in
    ``out`` as they finish and resumed from it; returns (and writes ``out/uncertainty.json``)
    the summary of :func:`summarize`; a Monte Carlo whose every build failed is a one-line
    :class:`~designlab.errors.ModelError` naming the first error (no summary written), and a
    write the file system refused (a full disk) a one-line
    :class:`~designlab.errors.OutputError`. ``files`` (a :class:`~designlab.atomic.FileSet`): the
    summary is staged with it (the CLI commits it with its report)."""
    from designlab.atomic import atomic_write_json, ensure_dir, out_lock
    from designlab.geometry.parts import make_part
    from designlab.optimize.executors import LocalExecutor
    from designlab.params import as_dict

    if spec.sensor != sensor:
        raise ParameterError("uncertainty", spec.sensor, f"a spec of the {sensor}")
    out = Path(out)
    params = as_dict(make_part(sensor, params or {}))
    executor = executor or LocalExecutor()
    with out_lock(out, "designlab predict --samples"):
        key = _run_key(spec, params, settings, protocol)
        fem_dir = str(out / "fem")
        t0 = time.perf_counter()
        _, parent_solves = _fem_stage(sensor, params, settings, protocol, fem_dir)
        t_fem = time.perf_counter() - t0
        ensure_dir(out / "samples")            # after the FEM stage: a refused design writes none
        cols, V = draw(spec)
        n = len(V)
        batches = [list(range(i, min(i + spec.batch, n))) for i in range(0, n, spec.batch)]
        done: dict[int, dict] = {}
        for b, idx in enumerate(batches):
            p = out / "samples" / f"{key}.{b:06d}.json"
            if p.is_file():
                try:
                    doc = json.loads(p.read_text())
                    for r in doc["rows"]:
                        done[int(r["index"])] = r
                except (OSError, ValueError, KeyError, TypeError):
                    p.unlink(missing_ok=True)          # unreadable: evaluated again
        todo = [b for b, idx in enumerate(batches) if not all(i in done for i in idx)]
        tasks = [{"sensor": sensor, "params": params, "settings": settings,
                  "protocol": protocol, "fem_cache": fem_dir, "seed": spec.seed,
                  "indices": batches[b],
                  "values": [build_values(spec, cols, V[i]) for i in batches[b]]} for b in todo]
        worker_solves = 0
        t0 = time.perf_counter()
        if progress:
            progress(len(done), n)
        for j, res, err in executor.run(run_batch, tasks):
            b = todo[j]
            if is_write_failure(err):      # a full disk: not the builds' failure, none stored
                raise OutputError(write_failure_message(err, "builds"))
            if err is not None:
                res = {"rows": [{"index": i, "status": "failed", "error": err}
                                for i in batches[b]], "fem_solves": 0}
            worker_solves += int(res.get("fem_solves", 0))
            atomic_write_json(out / "samples" / f"{key}.{b:06d}.json", res)
            for r in res["rows"]:
                done[int(r["index"])] = r
            if progress:
                progress(len(done), n)
        rows = [done[i] for i in range(n)]
        summary = summarize(spec, cols, V, rows)
        if not summary["ok"]:
            raise ModelError(no_build_message(summary, rows))
        summary["fem"] = {"solves_this_run": int(parent_solves + worker_solves),
                          "parent_s": t_fem, "cache": fem_dir}
        summary["wall_s"] = time.perf_counter() - t0
        summary["reused_builds"] = n - sum(len(batches[b]) for b in todo)
        summary["run_key"] = key
        (atomic_write_json if files is None else files.write_json)(out / "uncertainty.json",
                                                                    summary)
    return summary
