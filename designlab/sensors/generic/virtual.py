"""The generic virtual test of a :class:`~designlab.sensors.definition.SensorDefinition`: the FEM
stage once per distinct model, the protocol's held loads through the viscoelastic history, the
transducers' readings, and the report every built-in sensor gives (calibration, condition
number, sensitivity, cross-talk, hysteresis, noise budget, force error, stress)."""

from __future__ import annotations

import dataclasses
import json
import time
from collections import OrderedDict
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from designlab.fem.settings import FEMSettings
from designlab.params import as_dict, rng
from designlab.sensors import definition as d
from designlab.sensors.generic import metrics
from designlab.sensors.generic.fem import COMPONENTS, UNITS, fem_stage, static_response


@dataclass(frozen=True)
class DefinitionProtocol:
    """How the generic virtual test runs the definition's protocol."""

    hold_s: float = field(default=0.0, metadata=rng(0, 3600, unit="s", doc=(
        "hold of each load; 0: the definition's protocol's own")))
    noise_repeats: int = field(default=20, metadata=rng(2, 10000, doc=(
        "noisy calibrations drawn for the force error and its spread")))
    seed: int = field(default=0, metadata=rng(0, 2**31 - 1, doc="seed of the noise draws"))


@dataclass(frozen=True)
class DefinitionSettings(FEMSettings):
    """Mesh and solver settings of a definition's virtual test."""

    viscoelastic: bool = field(default=True, metadata=rng(doc=(
        "march the protocol through the materials' Prony series (hysteresis); false: "
        "instantaneous elastic readings")))

    def __reduce__(self):
        # a definition's settings class is made at run time (settings_class): an instance
        # travels (to a forked or spawned process) as its definition and its values
        defn = getattr(type(self), "definition", None)
        if defn is None:
            return super().__reduce__()
        return _settings_of, (defn, as_dict(self))


#: {definition class: its settings class}, one class per definition
_SETTINGS: dict[type, type] = {}


def settings_class(cls: type) -> type:
    """The settings class of definition ``cls``: its own default edge length."""
    if cls not in _SETTINGS:
        _SETTINGS[cls] = dataclasses.make_dataclass(
            f"{cls.__name__}Settings",
            [("edge_length", float, field(default=float(cls.edge_length), metadata=rng(
                0.05, 50, unit="mm", doc="ideal tetrahedron edge length")))],
            bases=(DefinitionSettings,), frozen=True, namespace={"definition": cls})
    return _SETTINGS[cls]


def _settings_of(cls: type, values: dict):
    return settings_class(cls)(**values)


@dataclass
class GenericResult:
    """A definition's virtual test: the report and what plots, VTU and stress need."""

    report: dict[str, Any]
    mesh: Any
    displacement: np.ndarray
    loads: np.ndarray
    load_names: list[str]
    readings: np.ndarray
    channels: list
    stage: dict = field(repr=False, default_factory=dict)
    state_U: np.ndarray | None = field(repr=False, default=None)


_STAGES: "OrderedDict[str, dict]" = OrderedDict()
_KEEP = 4


def stage_key(defn, settings) -> str:
    """What the FEM stage depends on: the definition's class, its parameters but those that
    only move loads, the mesh and solver settings, and the material library."""
    from designlab.fem.cache import fem_key

    params = {k: v for k, v in as_dict(defn).items() if k not in defn.load_only()}
    sett = {k: v for k, v in as_dict(settings).items()
            if k not in ("mesh_convergence", "coarse_factor", "viscoelastic")}
    cls = type(defn)
    from designlab.fem.materials import MATERIALS

    return fem_key("definition", cls=f"{cls.__module__}:{cls.__qualname__}",
                   file=getattr(cls, "_designlab_spec", ""), params=params, settings=sett,
                   materials=repr(sorted(MATERIALS.items())))


def _stage(defn, settings, progress) -> tuple[dict, bool]:
    key = stage_key(defn, settings)
    if key in _STAGES:
        _STAGES.move_to_end(key)
        return _STAGES[key], True
    st = fem_stage(defn, settings, progress)
    _STAGES[key] = st
    while len(_STAGES) > _KEEP:
        _STAGES.popitem(last=False)
    return st, False


def protocol_states(defn) -> list:
    """The held loads of the definition's protocol (a staircase's pulled along its load
    points' own directions)."""
    proto = defn.protocol()
    if isinstance(proto, d.Staircase):
        return proto.states({lp.name: lp.direction for lp in defn.loads() if lp.direction})
    return proto.states()


def _unit_wrenches(defn, stage, states) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(W (n_states, n_cases) in the unit cases at the faces' centroids, P (n_states, 6 n_loads)
    the loads at the load points as the protocol states them, their names)."""
    points = {lp.name: lp for lp in defn.loads()}
    cases = stage["cases"]
    names = [f"{lp}_{c}" for lp in points for c in COMPONENTS]
    W = np.zeros((len(states), len(cases)))
    P = np.zeros((len(states), len(names)))
    for i, s in enumerate(states):
        if s.load not in points:
            from designlab.errors import ParameterError

            raise ParameterError("protocol.load", s.load, "a load point: " + ", ".join(points))
        c = stage["centroids"][s.load]
        at = c if points[s.load].at is None else np.asarray(points[s.load].at, float)
        F, M = np.asarray(s.force_N, float), np.asarray(s.moment_Nmm, float)
        Mc = M + np.cross(at - c, F)
        for j, v in enumerate(np.r_[F, Mc]):
            W[i, cases.index(f"{s.load}.{COMPONENTS[j]}")] = v
        k = list(points).index(s.load) * 6
        P[i, k:k + 6] = np.r_[F, M]
    return W, P, names


def _history(stage, W: np.ndarray, hold: float, solver: str) -> np.ndarray:
    """Readings (n_states, n_channels) at the end of each hold of the protocol through the
    viscoelastic march: the response of each unit load case to a held step, marched once (all
    cases in one march, read at every multiple of the hold), superposed over the protocol's
    load changes. The march is linear and time-invariant on a uniform grid, so the
    superposition equals marching the protocol itself on the same steps."""
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history

    n = len(W)
    settled = _settled_holds(stage["model"], hold)
    m = min(n, settled)
    sub = _steps_per_hold(stage["model"], hold)
    t = hold * np.arange(m * sub + 1) / sub
    hist = History(t, {c: np.ones(len(t)) for c in stage["cases"]})
    res = solve_history(stage["model"], hist, solver=solver, forces=False, batch=True,
                        factor_each_step=True)
    U = np.asarray(res.U)[:, :, ::sub]                          # (n_dofs, n_cases, m + 1)
    R = _read_steps(stage["read"], U)
    if m < n:       # every Prony term has decayed to round-off: the response stays put
        R = np.concatenate([R, np.repeat(R[-1:], n - m, axis=0)])
    if m == settled:
        # the unit steps have settled: their last response is the long-time one (relaxed
        # moduli; equal to its own solve to 1e-10 on the examples), without a factorisation
        stage.setdefault("U_long", U[:, :, -1].copy())
    dW = np.diff(np.vstack([np.zeros(W.shape[1]), W]), axis=0)  # the load change at each hold
    S = np.zeros((n, R.shape[1]))
    for j in range(n):
        k = np.arange(j + 1)
        S[j] = np.einsum("kc,krc->r", dW[k], R[j - k + 1])
    return S


#: a relaxation term e^(-t / tau) below this is taken as decayed (round-off of the readings)
SETTLED = 1e-13


def _taus(model) -> list[float]:
    return [t for m in model.region_materials.values() if m.prony is not None
            for t in (*m.prony.tau, *m.prony.k_tau)]


#: time steps per relaxation time of the fastest Prony term (on the load cell's staircase the
#: hysteresis is then within about 2 % of its value on steps ten times finer)
STEPS_PER_TAU = 1
MAX_STEPS_PER_HOLD = 50


def _steps_per_hold(model, hold: float) -> int:
    """Steps of the march in one hold: :data:`STEPS_PER_TAU` per fastest relaxation time."""
    taus = _taus(model)
    if not taus:
        return 1
    return int(min(MAX_STEPS_PER_HOLD, max(1, np.ceil(STEPS_PER_TAU * hold / min(taus)))))


def _settled_holds(model, hold: float) -> int:
    """Holds after which the slowest Prony term of every material has decayed below
    :data:`SETTLED` (the step response is then constant to round-off)."""
    taus = _taus(model)
    if not taus:
        return 1
    return int(np.ceil(max(taus) * np.log(1.0 / SETTLED) / hold)) + 1


def _read_steps(read, U: np.ndarray) -> np.ndarray:
    """(n_times, n_channels, n_cases) readings of every unit case at every time."""
    n_dofs, n_cases, n_t = U.shape
    flat = np.asarray(read @ U.reshape(n_dofs, n_cases * n_t))   # (n_ch, n_cases * n_t)
    return flat.reshape(-1, n_cases, n_t).transpose(2, 0, 1)


def _long_time(stage, solver: str) -> np.ndarray:
    """The unit cases' long-time displacements (relaxed moduli), once per FEM stage: what the
    stress and the deformed shape of a held load are taken from."""
    if "U_long" not in stage:
        from designlab.fem.viscoelastic import long_time_displacements

        stage["U_long"] = long_time_displacements(stage["model"], solver)
    return stage["U_long"]


def _relaxes(model) -> bool:
    return any(m.prony is not None for m in model.region_materials.values())


def run(part, protocol: DefinitionProtocol | None = None, settings=None, progress=None
        ) -> GenericResult:
    """The virtual test of definition ``part`` (an instance of a SensorDefinition subclass)."""
    protocol = protocol or DefinitionProtocol()
    settings = settings or settings_class(type(part))()
    say = progress or (lambda s: None)
    stage, reused = _stage(part, settings, say)
    proto = part.protocol()
    hold = protocol.hold_s or proto.hold_s
    states = protocol_states(part)
    W, P_all, names = _unit_wrenches(part, stage, states)
    visco = bool(settings.viscoelastic and _relaxes(stage["model"]))
    t0 = time.perf_counter()
    if visco:
        say(f"viscoelastic march: {len(states)} holds of {hold:g} s")
        S = _history(stage, W, hold, settings.solver)
        U_states = _long_time(stage, settings.solver) @ W.T
    else:
        U, R = static_response(stage, settings.solver, say)
        S, U_states = W @ R.T, U @ W.T
    report = _report(part, stage, states, S, P_all, names, protocol, settings, visco, hold, reused)
    report["timings_s"]["solve"] = time.perf_counter() - t0
    peak = int(np.argmax(np.abs(P_all).max(axis=1)))
    n3 = 3 * stage["mesh"].n_points
    return GenericResult(report, stage["mesh"], U_states[:n3, peak].reshape(-1, 3), P_all, names,
                         S, stage["channels"], stage, U_states)


def _report(defn, stage, states, S, P_all, names, protocol, settings, visco, hold, reused
            ) -> dict[str, Any]:
    P, active = metrics.active_loads(P_all, names)
    chans = stage["channels"]
    noise = np.array([c.noise for c in chans], float)
    moment_cols = [i for i, n in enumerate(active) if n.rsplit("_", 1)[-1].startswith("M")]
    cal = metrics.calibration(S, P, moment_cols, getattr(defn, "moment_scale_mm", None), noise)
    K = metrics.sensitivity(S, P)
    C = np.asarray(cal["matrix"])
    unit_of = dict(zip(names, UNITS * (len(names) // 6)))
    proto = defn.protocol()
    loops = proto.loops() if isinstance(proto, d.Staircase) else []
    hyst = metrics.hysteresis(loops, S) if visco else None
    return {
        "sensor": defn.name,
        "channels": [{"name": c.name, "unit": c.unit, "noise": c.noise} for c in chans],
        "loads": [{"name": n, "unit": unit_of[n]} for n in active],
        "n_load_states": len(states),
        "hold_s": hold,
        "viscoelastic": visco,
        "calibration_matrix": cal["matrix"],
        "calibration_directions": cal["directions"],
        "condition_number": cal["condition_number"],
        **({"condition_number_scaled": cal["condition_number_scaled"],
            "moment_scale_mm": cal["moment_scale_mm"]} if "moment_scale_mm" in cal else {}),
        "calibration_fit_rms": dict(zip(active, cal["fit_rms"])),
        "cross_talk_percent": dict(zip(active, cal["cross_talk_percent"])),
        "sensitivity": {c.name: dict(zip(active, map(float, K[i]))) for i, c in enumerate(chans)},
        "sensitivity_units": {c.name: {n: f"{c.unit}/{unit_of[n]}" for n in active}
                              for c in chans},
        "sensitivity_norm": float(np.linalg.norm(K)),
        **metrics.sensitivity_shapes(K, [c.name for c in chans], active, moment_cols,
                                     getattr(defn, "moment_scale_mm", None),
                                     getattr(defn, "normalise_rows_by", None)),
        "noise_budget": dict(zip(active, map(float, metrics.noise_budget(C, noise)))),
        "force_error": _force_error(S, P, noise, protocol, active),
        "hysteresis_percent": hyst if hyst is not None else {
            "overall": None, "why": "no hysteresis: " + (
                "the protocol is not a staircase" if not loops else
                "no material of the sensor relaxes (no Prony terms) or the march is off")},
        "mesh": stage["mesh_result"].report() | {"fem_reused": reused},
        "timings_s": dict(stage["timings_s"]),
    }


def _force_error(S, P, noise, protocol, active) -> dict[str, Any]:
    fe = metrics.force_error(S, P, noise, protocol.noise_repeats, protocol.seed)
    return {"method": "calibrate on one noise draw of the protocol's readings, estimate the "
                      "loads of another; RMS over the load states, mean and spread over draws",
            "rms": dict(zip(active, fe["rms"])), "rms_std": dict(zip(active, fe["rms_std"])),
            "rms_percent_of_range": dict(zip(active, fe["rms_percent_of_range"])),
            "repeats": fe["repeats"], "seed": fe["seed"]}


# ----------------------------------------------------------------------------- record hooks

def gains(report: dict[str, Any], result: GenericResult) -> tuple[dict, dict]:
    """The virtual test as a linear model: each channel's reading per unit load."""
    units = {c["name"]: c["unit"] for c in report["channels"]}
    return {ch: dict(g) for ch, g in report["sensitivity"].items()}, units


#: at most this many of the protocol's load states are stress load cases
MAX_STRESS_STATES = 64


def load_cases(part, protocol, settings, result: GenericResult, cache=None) -> list:
    """The protocol's load states as stress load cases, the largest first (every state up to
    :data:`MAX_STRESS_STATES`, else the largest by their loads relative to each load's range);
    the three largest are VTU fields."""
    from designlab.sensors.sensor import LoadCase

    P = result.loads
    scale = np.where(np.ptp(P, axis=0) > 0, np.abs(P).max(axis=0), np.inf)
    size = np.linalg.norm(P / scale, axis=1)
    picks = [int(k) for k in np.argsort(-size, kind="stable")[:MAX_STRESS_STATES] if size[k] > 0]
    n3 = 3 * result.mesh.n_points
    states = protocol_states(part)
    out = []
    for k in picks:
        s = states[k]
        desc = (f"{s.label or k}: F = {np.round(s.force_N, 3).tolist()} N, M = "
                f"{np.round(s.moment_Nmm, 1).tolist()} N mm at {s.load}")
        out.append(LoadCase(f"state {k}", desc, result.state_U[:n3, k].reshape(-1, 3),
                            vtu=len(out) < 3))
    return out


def plots(result: GenericResult, report: dict | None, out_dir: str | Path, only=None
          ) -> list[Path]:
    """calibration_matrix.png (C with its loads and channels) and readings.png (each
    channel's reading over the protocol's load states)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    report = report or result.report
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    C = np.asarray(report["calibration_matrix"])
    loads = [f"{x['name']} ({x['unit']})" for x in report["loads"]]
    chans = [f"{c['name']} ({c['unit']})" for c in report["channels"]]
    fig, ax = plt.subplots(figsize=(1.2 + 0.6 * len(loads), 1.2 + 0.4 * len(chans)))
    lim = float(np.abs(C).max()) or 1.0
    im = ax.imshow(C, cmap="RdBu_r", vmin=-lim, vmax=lim, aspect="auto")
    ax.set_xticks(range(len(loads)), loads, rotation=45, ha="right")
    ax.set_yticks(range(len(chans)), chans)
    ax.set_title(f"calibration matrix (load per reading), cond {report['condition_number']:.3g}")
    fig.colorbar(im, ax=ax, label="load unit per reading unit")
    fig.tight_layout()
    files = [out / "calibration_matrix.png"]
    fig.savefig(files[0], dpi=110)
    plt.close(fig)
    fig, ax = plt.subplots(figsize=(7, 4))
    for i, c in enumerate(report["channels"]):
        ax.plot(result.readings[:, i], marker=".", label=f"{c['name']} ({c['unit']})")
    ax.set_xlabel("load state (protocol order)")
    ax.set_ylabel("reading (each channel in its unit)")
    ax.set_title(f"{report['sensor']}: readings over the protocol")
    if len(report["channels"]) <= 12:
        ax.legend(fontsize=7)
    fig.tight_layout()
    files.append(out / "readings.png")
    fig.savefig(files[1], dpi=110)
    plt.close(fig)
    return files


def report_json(result: GenericResult) -> str:
    """The report as JSON text."""
    return json.dumps(result.report, indent=1, default=float)
