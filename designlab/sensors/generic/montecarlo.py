"""The Monte Carlo model of a sensor definition (``Sensor.uncertainty``): each virtual build
scales every transducer's gain and the bodies' modulus by its drawn values, adds the
transducers' noise to the protocol's readings, and calibrates; the FEM stage is the design's
virtual test, once per design."""

from __future__ import annotations

from typing import Any

import numpy as np

from designlab.calibration.calibration_matrix import condition_number
from designlab.sensors.distributions import Distribution, Input, MonteCarloModel
from designlab.sensors.generic import metrics

GAIN_SOURCE = ("off by default: a transducer's gain tolerance is the designer's to state from "
               "its data sheet (a foil gauge's gauge-factor tolerance, a force sensor's "
               "sensitivity tolerance), e.g. { dist = \"normal\", mean = 1, std = 0.01 }")
MODULUS_SOURCE = ("off by default: the printed parts' modulus scatter depends on printer and "
                  "settings; state it, e.g. { dist = \"normal\", mean = 1, std = 0.05 }. Every "
                  "body's modulus scales together (exact for one material: readings scale as "
                  "1 / modulus)")
METRICS = ("condition_number", "sensitivity_norm", "force_error_rms")


def _transducer_names(cls: type) -> list[str]:
    return [getattr(t, "name", f"t{k}") for k, t in enumerate(cls().transducers())]


def monte_carlo_model(cls: type) -> MonteCarloModel:
    """The Monte Carlo model of definition class ``cls`` (its default design's transducers)."""
    inputs = tuple(Input(f"gain_{n}", Distribution("fixed", value=1.0, source=GAIN_SOURCE),
                         f"gain of transducer {n} relative to its nominal")
                   for n in _transducer_names(cls))
    inputs += (Input("modulus_scale", Distribution("fixed", value=1.0, source=MODULUS_SOURCE),
                     "the bodies' Young's modulus relative to the library's"),)
    return MonteCarloModel(inputs=inputs, metrics=METRICS, fem_stage=_fem_stage_of(cls),
                           build=build, paper={})


def _fem_stage_of(cls: type):
    def fem_stage(part, settings: dict | None, protocol: dict | None, cache) -> dict[str, Any]:
        from designlab.sensors.generic.virtual import DefinitionProtocol, run, settings_class
        from designlab.sensors.sensor import settings_from

        proto = DefinitionProtocol(**(protocol or {}))
        sett = settings_from(settings_class(cls), settings)
        res = run(part, proto, sett)
        P, active = metrics.active_loads(res.loads, res.load_names)
        owner = [c.transducer for c in res.channels]
        return {"S": res.readings, "P": P, "loads": active, "owner": owner,
                "noise": np.array([c.noise for c in res.channels], float)}
    return fem_stage


def build(ctx: dict[str, Any], values: dict[str, Any], seed: int) -> dict[str, float]:
    """One virtual build: gains and modulus drawn, readings with noise, calibrated on one noise
    draw and checked on another."""
    gain = np.array([float(values.get(f"gain_{o}", 1.0)) for o in ctx["owner"]])
    S = ctx["S"] * gain[None, :] / float(values.get("modulus_scale", 1.0))
    rng = np.random.default_rng(seed)
    noise = ctx["noise"]
    S1 = S + rng.standard_normal(S.shape) * noise
    S2 = S + rng.standard_normal(S.shape) * noise
    P = ctx["P"]
    C, _ = metrics.fit_matrix(S1, P, noise)
    K = metrics.sensitivity(S1, P)
    err = np.sqrt(np.mean((S2 @ C - P) ** 2))
    return {"condition_number": condition_number(C),
            "sensitivity_norm": float(np.linalg.norm(K)), "force_error_rms": float(err)}
