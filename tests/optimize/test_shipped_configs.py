"""Every design of every shipped sweep/optimize config (``examples/*.toml`` with a
``[parameters]`` table) constructs: a shipped example never fails a design on a parameter
bound. Cheap: the parametric parts only (no CAD build, no FEM)."""

from __future__ import annotations

import tomllib

import pytest

from conftest import ROOT

CONFIGS = sorted(p for p in (ROOT / "examples").glob("*.toml")
                 if "parameters" in tomllib.loads(p.read_text()))


def test_the_shipped_sweep_configs_are_found():
    assert {"sweep_strap.toml", "uncertainty_sweep_flexure.toml"} <= {p.name for p in CONFIGS}


@pytest.mark.parametrize("path", CONFIGS, ids=[p.name for p in CONFIGS])
def test_every_design_of_a_shipped_sweep_config_constructs(path):
    from designlab.geometry.parts import make_part
    from designlab.optimize.robust import load_sweep
    from designlab.sensors.registry import resolve

    cfg, _ = load_sweep(path)
    part = resolve(cfg.part)
    refused = []
    for swept in cfg.designs():
        try:
            make_part(part, {**cfg.fixed, **swept})
        except ValueError as exc:
            refused.append(f"{swept}: {exc}")
    assert not refused, f"{path.name}: {len(refused)} design(s) refused: {refused[0]}"
