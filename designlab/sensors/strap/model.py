"""Virtual load test of the seed 000 arch strap: F_n and F_x on the finger pad -> Ch1, Ch2.

The strap's model below its sensor record: the settings (:class:`StrapModelSettings`), the
channels and load cases, the wrap geometry, the mesh and the FEM model, the FEM stage and its
key, the readout, :func:`run` and its metrics (:func:`evaluate`). The FEM model, why the strap
is modelled worn and how the history is marched: docs/models/strap_model.md.
"""

from __future__ import annotations

import dataclasses
import math
import time
import warnings
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from designlab.calibration.calibration_matrix import (condition_number, fit_calibration_matrix,
                                                      linearity_percent)
from designlab.calibration.hysteresis import hysteresis_percent, loop_from_steps
from designlab.sensors.protocols import StrapLoadTest
from designlab.errors import ParameterError
from designlab.fem.settings import FEMSettings
from designlab.params import rng, validate, whole_numbers
from designlab.sensors.strap.electrical import DividerGauge
from designlab.sensors.strap.wrap_stress import wrap_stress, wrap_stress_warnings

CHANNELS = ("Ch1", "Ch2")          #: Ch1 = left gauge (x < 0), Ch2 = right gauge (x > 0)
GAUGE_REGIONS = ("trace_left", "trace_right")
CASES = ("F_n", "F_x")


@dataclass(frozen=True)
class StrapModelSettings(FEMSettings):
    """FEM settings of the strap test (mm). Why these mesh and tissue defaults:
    docs/models/strap_model.md."""

    edge_length: float = field(default=1.5, metadata=rng(0.2, 5, unit="mm"))
    refinement_edge: float = field(default=0.0, metadata=rng(0, 5, unit="mm",
                                   doc="edge at the gauges/pads, 0 = no refinement"))
    epsilon: float = field(default=0.05, metadata=rng(0.001, 0.2, unit="mm",
                           doc="fTetWild envelope"))
    configuration: str = field(default="worn", metadata=rng(choices=("worn", "flat")))
    finger_radius: float = field(default=9.0, metadata=rng(3, 20, unit="mm",
                                 doc="finger radius under the strap centreline (index: ~9)"))
    load: str = field(default="coupling", metadata=rng(choices=("coupling", "traction")))
    tissue_stiffness: float = field(default=0.02, metadata=rng(0, 10, unit="N/mm^3",
                                    doc="finger support under the strap outside the pad "
                                        "(Winkler springs normal to the inner face), 0 = none"))
    finger_model: str = field(default="winkler", metadata=rng(
        choices=("winkler", "solid"), doc="the finger under the strap: Winkler springs "
        "(tissue_stiffness) or a solid pulp layer bonded to the inner face, its far face fixed "
        "(strap_pulp)"))
    pulp_depth: float = field(default=3.0, metadata=rng(0.5, 8, unit="mm",
                              doc="solid pulp: layer depth to the bone (assumed)"))
    pulp_modulus: float = field(default=0.06, metadata=rng(0.001, 10, unit="MPa",
                                doc="solid pulp: Young's modulus (default: the Winkler "
                                    "default's unconfined equivalent 0.02 N/mm^3 x 3 mm, not a "
                                    "literature value)"))
    pulp_poisson: float = field(default=0.49, metadata=rng(0.0, 0.499, doc="solid pulp: "
                                "Poisson's ratio (nearly incompressible)"))
    pulp_layers: int = field(default=2, metadata=rng(1, 20, doc="solid pulp: element layers"))
    read_fraction: float = field(default=0.2, metadata=rng(0, 1, lo_open=True,
                                 doc="end part of each staircase hold that is averaged"))
    slot: int = field(default=0, metadata=rng(0, 6, doc="engaged slot (1 = nearest the strap "
                      "end): the wrap's initial strain (strap_fit); 0 = stress-free wrap"))
    wrap_length: float = field(default=0.0, metadata=rng(0, 300, unit="mm",
                               doc="custom engaged length instead of a slot, 0 = none"))
    contact_ohm: float = field(default=0.0, metadata=rng(0, 899, unit="ohm",
                               doc="per pad; 0 = lumped into rho_eff (strap_electrical)"))
    divider_ohm: float = field(default=2200.0, metadata=rng(10, 1e7, unit="ohm",
                               doc="fixed divider resistor (seed 000 Fig. 3: 2.2 kOhm)"))
    supply_V: float = field(default=5.0, metadata=rng(0.1, 48, unit="V",
                            doc="divider supply (seed 000: 5 V)"))
    adc_bits: int = field(default=16, metadata=rng(8, 32, doc="ADC resolution (assumed)"))
    bandwidth_hz: float = field(default=10.0, metadata=rng(0.01, 1e4, unit="Hz",
                                doc="readout bandwidth (seed 000: 10 Hz low-pass)"))

    def __post_init__(self):
        whole_numbers(self, ("slot", "adc_bits", "pulp_layers"))
        validate(self)
        if self.slot and self.wrap_length:
            raise ParameterError("wrap_length", self.wrap_length,
                                 "0 when a slot is given (one or the other)")
        if (self.slot or self.wrap_length) and self.configuration != "worn":
            raise ParameterError("slot", self.slot, "0 in the flat configuration (no wrap)")

    @property
    def prestrained(self) -> bool:
        return bool(self.slot or self.wrap_length)


# ------------------------------------------------------------------------------------ geometry

def _polar(part, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Distance to the arch centre and angle from +y towards +x (rad) of flat points."""
    cx, cy = part.center
    dx, dy = x[..., 0] - cx, x[..., 1] - cy
    return np.hypot(dx, dy), np.arctan2(dx, dy)


def _cone(part, finger_radius: float) -> tuple[float, float]:
    sa = finger_radius / part.radius
    if not 0 < sa < 1:
        raise ParameterError("finger_radius", finger_radius,
                             f"< arch radius {part.radius:.3g} mm (the arch wraps a cone)")
    return sa, math.sqrt(1 - sa * sa)


def wrap_points(part, x: np.ndarray, finger_radius: float) -> np.ndarray:
    """Flat (printed) points -> worn: the planform on a cone around the finger axis (+y world),
    the pad side at +z, the right gauge towards +x; ``z`` becomes the distance from the inner
    face along the cone's outward normal. mm."""
    x = np.asarray(x, float)
    sa, ca = _cone(part, finger_radius)
    rho, phi = _polar(part, x)
    psi = phi / sa
    er = np.stack([np.sin(psi), np.zeros_like(psi), np.cos(psi)], -1)
    ey = np.array([0.0, 1.0, 0.0])
    surf = (rho * sa)[..., None] * er + (rho * ca)[..., None] * ey
    normal = ca * er - sa * ey
    return surf + x[..., 2:3] * normal


def worn_mesh(part, mesh, finger_radius: float):
    """The flat mesh mapped by :func:`wrap_points` (same cells, sets and regions)."""
    from designlab.mesh.tetmesh import TetMesh

    pts = wrap_points(part, mesh.points, finger_radius)
    return TetMesh(pts, mesh.cells, mesh.region, dict(mesh.region_names), dict(mesh.materials),
                   dict(mesh.facet_sets), dict(mesh.point_sets))


def centreline_direction(part, settings: StrapModelSettings) -> Callable[[np.ndarray], np.ndarray]:
    """d(x): unit direction of the strap centreline (the meander legs) at points of the model."""
    if settings.configuration == "flat":
        def flat(x):
            _, phi = _polar(part, x)
            return np.stack([np.cos(phi), -np.sin(phi), np.zeros_like(phi)], -1)
        return flat

    def worn(x):
        psi = np.arctan2(x[..., 0], x[..., 2])       # circles around the finger axis (y)
        return np.stack([np.cos(psi), np.zeros_like(psi), -np.sin(psi)], -1)
    return worn


def pad_frame(part, settings: StrapModelSettings) -> dict[str, np.ndarray]:
    """Pad centre (inner face at the apex), outward normal ``n`` (F_n) and centreline tangent
    ``t`` (F_x, towards the right gauge) in the model's frame."""
    apex = np.array([[0.0, part.arch_height, 0.0]])
    if settings.configuration == "flat":
        return {"centre": apex[0], "n": np.array([0.0, 0.0, 1.0]), "t": np.array([1.0, 0.0, 0.0])}
    sa, ca = _cone(part, settings.finger_radius)
    return {"centre": wrap_points(part, apex, settings.finger_radius)[0],
            "n": np.array([0.0, -sa, ca]), "t": np.array([1.0, 0.0, 0.0])}


def mesh_strap(part, settings: StrapModelSettings, detailed: bool = False):
    """Flat TET mesh of the strap and traces with the part's facet sets (see the settings);
    ``detailed``: the :class:`~designlab.mesh.meshing.MeshResult` (which mesher made it, the
    attempts)."""
    from designlab.mesh.meshing import mesh_bodies_detailed

    built = part.build()
    bodies = [built[n] for n in part.mesh_bodies()]
    ref = [(c, r, settings.refinement_edge) for c, r, _ in part.refinement()] \
        if settings.refinement_edge > 0 else []
    res = mesh_bodies_detailed(bodies, part.facet_sets(), edge_length=settings.edge_length,
                               refinement=ref, epsilon=settings.epsilon,
                               quality=settings.mesh_quality, order=settings.order,
                               mesher=settings.mesher)
    return res if detailed else res.mesh


# ------------------------------------------------------------------------------------ model

def gauge_cells(part, flat_mesh, region: str) -> np.ndarray:
    """Cells of a trace body that carry the gauge's resistance: the meander (legs, turns and
    leads) without the connection pads. The pads (2 x 3 mm, 0.4 mm high, rising to the top
    face) have a small fraction of the resistance of the 0.8 x 0.2 mm legs but ~40 % of the
    trace volume, and they sit off the mid-plane in the strap's bending zone: a volume mean
    including them reads their bending strain."""
    rid = flat_mesh.region_id(region)
    cells = np.nonzero(flat_mesh.region == rid)[0]
    c = flat_mesh.points[flat_mesh.cells[cells, :4]].mean(axis=1)
    _, phi = _polar(part, c)
    return cells[np.abs(phi) < part.gauge_angles()["p0"]]


def inner_face_triangles(part, flat_mesh) -> np.ndarray:
    """Corner triangles of the inner (finger-side) face outside the pad contact and the tabs:
    where the finger supports the strap (the Winkler springs' nodes, the solid pulp's top)."""
    from designlab.mesh.facets import centroids_normals

    tri = flat_mesh.boundary_facets()
    cen, nrm = centroids_normals(flat_mesh.points, tri)
    rho, phi = _polar(part, cen)
    inner = (nrm[:, 2] < -0.9) & (np.abs(cen[:, 2]) < part.layer_height / 2)
    arch = np.abs(phi) < part.half_angle
    contact = np.abs(phi) * part.radius <= part.contact_length / 2
    return tri[inner & arch & ~contact]


def inner_face_nodes(part, flat_mesh) -> tuple[np.ndarray, np.ndarray]:
    """Corner nodes of :func:`inner_face_triangles` and their lumped areas (mm^2)."""
    tri = inner_face_triangles(part, flat_mesh)
    p = flat_mesh.points[tri]
    area = 0.5 * np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
    w = np.bincount(tri.ravel(), weights=np.repeat(area / 3.0, 3), minlength=flat_mesh.n_points)
    ids = np.nonzero(w > 0)[0]
    return ids, w[ids]


def strap_with_pulp(part, flat_mesh, settings):
    """The flat strap mesh with the pulp under its support triangles
    (:mod:`designlab.sensors.strap.pulp_layer`)."""
    from designlab.sensors.strap.pulp_layer import add_pulp

    tri = inner_face_triangles(part, flat_mesh)
    return add_pulp(flat_mesh, tri, settings.pulp_depth, settings.pulp_layers)


def finger_materials(settings: StrapModelSettings, materials=None):
    """The material overrides with the solid pulp's material when ``finger_model = "solid"``
    (the pulp body is not a part body: its material comes from the settings)."""
    if settings.finger_model != "solid":
        return materials
    from designlab.sensors.strap.pulp_layer import PULP, pulp_material

    return {**(materials or {}), PULP: pulp_material(settings.pulp_modulus,
                                                     settings.pulp_poisson)}


def build_model(part, flat_mesh, settings: StrapModelSettings, materials=None):
    """Model of the strap on its finger from the flat (printed) mesh: worn (or flat) geometry,
    tabs fixed, the finger's support (``tissue_stiffness``), unit load cases ``F_n`` and ``F_x``
    (1 N) at the pad. Returns (model, gauges {channel: StrainGauge}, pad frame)."""
    from designlab.fem.model import Model
    from designlab.fem.facets import area_weights, facet_basis
    from designlab.fem.transducers import StrainGauge

    worn = settings.configuration == "worn"
    solid = settings.finger_model == "solid"
    if solid:       # the pulp layer under the support triangles, far face fixed (strap_pulp_layer)
        flat_mesh = strap_with_pulp(part, flat_mesh, settings)
    materials = finger_materials(settings, materials)
    mesh = worn_mesh(part, flat_mesh, settings.finger_radius) if worn else flat_mesh
    model = Model(mesh, materials)
    model.fix("nail_plate")
    if solid:
        from designlab.sensors.strap.pulp_layer import BONE

        model.fix(BONE)
    frame = pad_frame(part, settings)
    if settings.load == "coupling":
        pad = model.distributing_coupling("pad", "finger_contact", ref_point=frame["centre"])
        model.force(pad, force=frame["n"], case="F_n")
        model.force(pad, force=frame["t"], case="F_x")
    else:
        area = float(area_weights(mesh, facet_basis(mesh, model.facets("finger_contact"))).sum())
        model.traction("finger_contact", frame["n"] / area, case="F_n")
        model.traction("finger_contact", frame["t"] / area, case="F_x")
    if settings.tissue_stiffness > 0 and not solid:
        ids, area = inner_face_nodes(part, flat_mesh)
        if worn:
            sa, ca = _cone(part, settings.finger_radius)
            psi = np.arctan2(mesh.points[ids, 0], mesh.points[ids, 2])
            normals = np.column_stack([ca * np.sin(psi), np.full(len(ids), -sa),
                                       ca * np.cos(psi)])
        else:
            normals = np.tile([0.0, 0.0, 1.0], (len(ids), 1))
        for i, a, nv in zip(ids, area, normals):
            model.spring(f"tissue_{i}", a=int(i), k=settings.tissue_stiffness * a, axis=nv)
    from designlab.sensors.strap.electrical import gauge_resistance

    d = centreline_direction(part, settings)
    trace = model.region_materials[mesh.region_id(GAUGE_REGIONS[0])]
    R0 = gauge_resistance(part, settings.contact_ohm, trace)["total"]  # measured rho if given
    gauges = {ch: StrainGauge(model, gauge_cells(part, flat_mesh, reg), direction=d, name=ch,
                              R0=R0, R_fixed=settings.divider_ohm, V_s=settings.supply_V)
              for ch, reg in zip(CHANNELS, GAUGE_REGIONS)}
    return model, gauges, frame


@dataclass
class StrapPrediction:
    """Virtual test results: forces (N), gauge strains, channel voltages (V), report."""

    t: np.ndarray
    F_n: np.ndarray
    F_x: np.ndarray
    strain: np.ndarray          # (n_t, 2) mean strain along the legs, Ch1, Ch2
    voltage: np.ndarray         # (n_t, 2) divider output, V
    dV: np.ndarray              # (n_t, 2) change from the unloaded state, V
    report: dict[str, Any]
    mesh: Any = None            # the worn mesh and its displacement (n_points, 3) mm at the
    displacement: Any = None    # peak normal force, for the VTU of the deformed sensor
    #: (n_points, 3, 2) long-time displacement per newton of F_n and F_x (the stress check's
    #: load cases, :func:`load_cases`); None from a FEM stage stored without it
    unit_displacement: Any = None


#: settings that act after the FEM: the readout (electrical, divider, ADC), the staircase read
#: window and the wrap's prestrain (applied to the solved strains as an operating point and a
#: factor, strap_prestrain): designs that differ only in them share one FEM. Every other
#: setting (a new one too) is part of the FEM key.
READOUT_SETTINGS = ("read_fraction", "slot", "wrap_length", "contact_ohm", "divider_ohm",
                    "supply_V", "adc_bits", "bandwidth_hz")

#: settings of the solid pulp (``finger_model = "solid"``, strap_pulp_layer)
PULP_SETTINGS = ("pulp_depth", "pulp_modulus", "pulp_poisson", "pulp_layers")

#: part parameters the FEM does not depend on: they shape the nail plate, which is not meshed
#: (its tabs are fixed: the ``nail_plate`` facets of the strap); the readout still uses them
#: (tests/sensors/strap/test_strap_test.py checks that the meshed bodies' B-rep does not change with them)
LOAD_ONLY_PARAMS = ("nail_plate_length", "nail_plate_width", "nail_plate_thickness")


#: a mesh whose wrap turns a cell inside out is made again with edges this much shorter, at most
#: this many times
WRAP_REFINE = 0.8
WRAP_RETRIES = 3


def _viscous(part, materials=None) -> bool:
    """Whether a meshed body's material relaxes (a Prony series): then the FEM stage marches the
    protocol's history and depends on it."""
    from designlab.fem.materials import Material, get_material

    built = part.build()
    over = dict(materials or {})
    for name in part.mesh_bodies():
        spec = over.get(name, built[name].material)
        if (spec if isinstance(spec, Material) else get_material(spec)).prony is not None:
            return True
    return False


def elastic_materials(part) -> dict[str, Any]:
    """The part's meshed bodies' library materials without their Prony series."""
    from designlab.fem.materials import Material, get_material

    built = part.build()
    out = {}
    for name in part.mesh_bodies():
        spec = built[name].material
        m = spec if isinstance(spec, Material) else get_material(spec)
        out[name] = dataclasses.replace(m, prony=None)
    return out


def fem_key(part, protocol: StrapLoadTest, settings: StrapModelSettings, materials=None) -> str:
    """Key of the FEM stage: the part's parameters except :data:`LOAD_ONLY_PARAMS`, the model
    settings except :data:`READOUT_SETTINGS` and the error-bar level, the material library and
    overrides, and, when a material relaxes, the protocol (the solved history is its own)."""
    from designlab.fem.cache import fem_key as key
    from designlab.fem.materials import MATERIALS
    from designlab.params import as_dict

    params = {k: v for k, v in as_dict(part).items() if k not in LOAD_ONLY_PARAMS}
    skip = {"mesh_convergence", "coarse_factor", *READOUT_SETTINGS}
    # the finger: the springs' stiffness or the pulp's settings, not both (a Winkler run keeps
    # the key it had before the solid pulp existed)
    skip |= {"tissue_stiffness"} if settings.finger_model == "solid" else {"finger_model",
                                                                           *PULP_SETTINGS}
    sett = {k: v for k, v in as_dict(settings).items() if k not in skip}
    viscous = _viscous(part, materials)
    # stage 3: the stage also holds the long-time unit displacements (U_long) of the stress
    # and how the history was marched (march, rom_residual, rom_basis, long_time_residual)
    return key("strap-gauge-strain", stage=3, params=params, settings=sett,
               materials=repr(sorted(MATERIALS.items())),
               overrides=repr(sorted((materials or {}).items())),
               protocol=as_dict(protocol) if viscous else None)


def _mesh_and_build(part, settings: StrapModelSettings, materials, mesh, say, timings: dict):
    """Mesh (unless the flat ``mesh`` is given) and build the model; a wrap that turns a cell
    inside out is re-meshed finer (``WRAP_REFINE``, at most ``WRAP_RETRIES`` times). Returns
    (model, gauges, mesher, attempts, edge length)."""
    from designlab.errors import ModelError

    given = mesh is not None
    mesher, attempts, edge = "given", [], settings.edge_length
    for retry in range(WRAP_RETRIES + 1):
        t0 = time.perf_counter()
        if not given:
            say("meshing")
            made = mesh_strap(part, dataclasses.replace(settings, edge_length=edge),
                              detailed=True)
            mesh, mesher = made.mesh, made.mesher
            attempts += list(made.attempts)
        timings["mesh"] += time.perf_counter() - t0
        t0 = time.perf_counter()
        say("assembling")
        try:
            model, gauges, frame = build_model(part, mesh, settings, materials)
            break
        except ModelError as exc:
            # a flat sliver cell can turn inside out on the cone (the wrap stretches the outer
            # face by up to thickness / finger radius): re-mesh a little finer
            if given or "inverted" not in str(exc) or settings.configuration != "worn":
                raise
            if retry == WRAP_RETRIES:
                raise ModelError(f"edge_length {settings.edge_length:g} mm: wrapped onto the "
                                 f"finger the strap mesh has {exc} (also re-meshed down to "
                                 f"{edge:.3g} mm); try another edge_length") from None
            attempts.append(f"wrapped onto the finger: {exc}; re-meshed at edge "
                            f"{WRAP_REFINE * edge:.3g} mm")
            edge *= WRAP_REFINE
        finally:
            timings["assemble"] += time.perf_counter() - t0
    return model, gauges, mesher, attempts, edge


def solve_fem(part, protocol: StrapLoadTest, settings: StrapModelSettings, materials=None,
              mesh=None, say: Callable[[str], None] = lambda s: None) -> dict[str, Any]:
    """The FEM stage: mesh (unless the flat ``mesh`` is given), wrap, build, solve.

    Returns plain arrays: the worn mesh (``points``, ``cells``, ``region``, ``region_names``,
    ``region_materials``), ``dofs``, ``viscoelastic``, the gauges' ``gauge_factor`` and
    ``gauge_quadratic`` (Ch1, Ch2), and either the gauge strain history ``strain`` (n_t, 2) and
    the displacement ``u_peak`` at the peak normal force (a relaxing material: the protocol's
    history is marched) or the strain per newton ``unit`` (channel, case) and the displacement
    per newton of F_n ``U_n`` (elastic: one static solve of the unit cases); ``U_long``
    (n_points, 3, 2): the long-time displacement per newton of F_n and F_x (relaxed moduli: one
    more static solve when a material relaxes), the stress check's load cases; ``timings`` (mesh,
    assemble, solve s), ``mesher``, ``mesh_attempts``, ``solver`` (the one that ran)."""
    from designlab.fem.static import solve_static
    from designlab.fem.history import History
    from designlab.fem.viscoelastic import solve_history

    timings = {"mesh": 0.0, "assemble": 0.0}
    model, gauges, mesher, attempts, edge = _mesh_and_build(
        part, settings, materials, mesh, say, timings)
    t0 = time.perf_counter()
    mesh = model.mesh
    model.build()
    timings["assemble"] += time.perf_counter() - t0

    t, fn, fx = protocol.time_history()
    t0 = time.perf_counter()
    viscous = any(m.prony is not None for m in model.region_materials.values())
    out: dict[str, Any] = {}
    if viscous:
        say("viscoelastic history")
        # the reduced-order march when it pays off and certifies (fem.viscoelastic), else full
        res = solve_history(model, History(t, {"F_n": fn, "F_x": fx}), solver=settings.solver,
                            forces=False, method="auto")
        out["strain"] = np.column_stack([res.linear(gauges[c].strain) for c in CHANNELS])
        out["u_peak"] = res.displacement(int(np.argmax(fn)))
        out["march"] = np.array(res.march)
        out["rom_residual"] = np.array(np.nan if res.rom_residual is None
                                       else float(res.rom_residual))
        out["rom_basis"] = np.array(int(res.basis_size))
        solver = res.solvers[0].kind
    else:
        say("static solve")
        res = solve_static(model, solver=settings.solver)
        U = res.U[:, [res.system.case_index(c) for c in CASES]]
        out["unit"] = np.array([gauges[c].strain(U) for c in CHANNELS])   # (channel, case)
        out["U_n"] = res.displacement(CASES[0])
        out["U_long"] = np.stack([res.displacement(c) for c in CASES], axis=-1)
        solver = res.solver.kind
    if viscous:
        # the stress check's load cases: the long-time displacement per newton of each case
        # (relaxed moduli, the springs of the finger unchanged; fem.stress's convention), one
        # more static solve; superposed over the protocol's loads (exact for the linear model);
        # from the reduced march's basis when its residual certifies (no second factorisation)
        say("long-time unit loads (stress)")
        from designlab.fem.viscoelastic import long_time_displacements

        lt = res.long_time()
        out["long_time_residual"] = np.array(np.nan if lt is None else lt[1])
        U_long = (long_time_displacements(model, solver=settings.solver) if lt is None
                  else lt[0])[: 3 * model.n_points]
        out["U_long"] = np.stack([U_long[:, res.system.case_index(c)].reshape(-1, 3)
                                  for c in CASES], axis=-1)
    timings["solve"] = time.perf_counter() - t0
    if settings.finger_model == "solid":
        from designlab.sensors.strap.pulp_layer import principal_strain

        # the pulp's principal strain per newton of F_n (long-time: the largest), max and p95
        u_n = out["U_long"][:, :, 0].reshape(-1)
        out["pulp_strain_per_N"] = np.array([principal_strain(model, u_n),
                                             principal_strain(model, u_n, q=95.0)])
    names = [mesh.region_names[k] for k in sorted(mesh.region_names)]
    return {**out, "points": mesh.points, "cells": mesh.cells, "region": mesh.region,
            "region_names": np.array(names),
            "region_materials": np.array([mesh.materials[n] for n in names]),
            "dofs": np.array(model.n_dofs), "viscoelastic": np.array(bool(viscous)),
            "gauge_factor": np.array([gauges[c].gauge_factor for c in CHANNELS]),
            "gauge_quadratic": np.array([gauges[c].gauge_quadratic for c in CHANNELS]),
            "timings": np.array([timings["mesh"], timings["assemble"], timings["solve"]]),
            "mesher": np.array(mesher), "mesh_attempts": np.array(attempts, dtype=str),
            "edge_length": np.array(float(edge)), "solver": np.array(solver)}


def _prediction_mesh(fem: dict, settings: StrapModelSettings, materials=None):
    """The prediction's mesh (VTU, stress check): the strap, without the pulp's cells and
    nodes (appended after the strap's, strap_pulp_layer.add_pulp; the pulp is no library
    material and has no strength, report["finger"] has its strain). Returns (mesh, its node
    count, the region materials)."""
    from designlab.fem.model import Model
    from designlab.mesh.tetmesh import TetMesh

    names = [str(n) for n in fem["region_names"]]
    n_keep = len(fem["points"])
    keep = np.ones(len(fem["cells"]), bool)
    if settings.finger_model == "solid":
        from designlab.sensors.strap.pulp_layer import PULP

        keep = np.asarray(fem["region"]) != names.index(PULP)
        n_keep = int(np.asarray(fem["cells"])[keep].max()) + 1
    mesh = TetMesh(np.asarray(fem["points"])[:n_keep], np.asarray(fem["cells"])[keep],
                   np.asarray(fem["region"])[keep], dict(enumerate(names)),
                   dict(zip(names, (str(m) for m in fem["region_materials"]))))
    region_materials = Model(mesh, finger_materials(settings, materials)).region_materials
    return mesh, n_keep, region_materials


def _gauge_strains(fem: dict, fn: np.ndarray, fx: np.ndarray):
    """(viscous, gauge strain history, unit strains per N or None, displacement at the peak)."""
    viscous = bool(fem["viscoelastic"])
    if viscous:
        return viscous, np.array(fem["strain"], float), None, np.array(fem["u_peak"], float)
    unit = np.array(fem["unit"], float)
    strain = np.column_stack([fn, fx]) @ unit.T
    return viscous, strain, unit, np.array(fem["U_n"], float) * float(fn.max())


def _prestrained(part, settings: StrapModelSettings, trace_mat, R0: float, strain, unit, say):
    """The wrap's prestrain state and the strains it scales: (state or None, initial strain,
    strain, unit)."""
    if not settings.prestrained:
        return None, 0.0, strain, unit
    import designlab.sensors.strap.prestrain as ps

    say("prestrain")
    pre = ps.prestrain_state(part, 2 * math.pi * settings.finger_radius, trace_mat, R0,
                             settings.divider_ohm, slot=settings.slot or None,
                             length=settings.wrap_length or None)
    eps0 = 0.0
    if pre["initial_strain"] > 0:       # a slack strap reads stress-free
        eps0 = pre["initial_strain"]
        strain = strain * pre["mechanical_factor"]
        if unit is not None:
            unit = unit * pre["mechanical_factor"]
    return pre, eps0, strain, unit


def _readout_entries(part, settings: StrapModelSettings, trace_mat, g1: DividerGauge, eps0: float,
                     pre, sens: dict) -> dict:
    """The electrical report and (worn) the paper's slots on this finger, from this run's
    sensitivity without prestrain."""
    import designlab.sensors.strap.electrical as el
    import designlab.sensors.strap.prestrain as ps

    R_rest = float(g1.resistance(eps0))
    out = {"electrical": el.electrical_report(
        part, trace_mat, sens["sum"]["F_n"], sens["diff"]["F_x"],
        contact_ohm=settings.contact_ohm, R_fixed=settings.divider_ohm, V_s=settings.supply_V,
        adc_bits=settings.adc_bits, adc_full_scale_V=settings.supply_V,
        bandwidth_hz=settings.bandwidth_hz, R_rest=R_rest), "prestrain": pre}
    if settings.configuration == "worn":
        f = pre["sensitivity_factor"] if pre and pre["initial_strain"] > 0 else 1.0
        out["slots"] = ps.slot_table(part, 2 * math.pi * settings.finger_radius, trace_mat,
                                     g1.R0, settings.divider_ohm, sens["sum"]["F_n"] / f,
                                     sens["diff"]["F_x"] / f)
    return out


def _mesh_entry(mesh, fem: dict, settings: StrapModelSettings) -> dict:
    return {"points": int(mesh.n_points), "cells": int(mesh.n_cells),
            "order": int(mesh.order), "dofs": int(fem["dofs"]),
            "edge_length_mm": float(fem["edge_length"]),
            "refinement_edge_mm": settings.refinement_edge,
            "mesher": str(fem["mesher"]),
            "attempts": [str(a) for a in fem["mesh_attempts"]],
            "solver": str(fem["solver"])}


def _finger_entry(fem: dict, settings: StrapModelSettings, fn: np.ndarray) -> dict:
    """The finger model: the solid pulp's strain at the peak F_n, or the Winkler stiffness."""
    finger = {"finger_model": settings.finger_model}
    if settings.finger_model != "solid":
        finger["tissue_stiffness_N_per_mm3"] = settings.tissue_stiffness
        return finger
    per_n, p95 = (float(v) for v in fem["pulp_strain_per_N"])
    peak = float(np.abs(fn).max())
    finger |= {
        "pulp_depth_mm": settings.pulp_depth, "pulp_E_MPa": settings.pulp_modulus,
        "pulp_nu": settings.pulp_poisson, "pulp_layers": settings.pulp_layers,
        "pulp_max_principal_strain_per_N": per_n,
        "pulp_max_principal_strain_at_peak_F_n": per_n * peak,
        "pulp_p95_principal_strain_at_peak_F_n": p95 * peak,
        "note": "linear elastic pulp (a hyperelastic pulp linearised at rest, E = 3 mu); "
                "the pulp modulus is not a literature value (docs/strap.md)"}
    if settings.order == 1:
        finger["warning"] = ("TET4 cells lock the nearly incompressible pulp "
                             "(35 % too stiff on a bonded layer): use order 2")
    return finger


def _model_entry(settings: StrapModelSettings, frame: dict, gauges: dict, mesh,
                 region_materials) -> dict:
    return {
        "configuration": settings.configuration,
        "finger_radius_mm": settings.finger_radius if settings.configuration == "worn" else None,
        "load": settings.load, "pad_centre_mm": frame["centre"].tolist(),
        "F_n_direction": frame["n"].tolist(), "F_x_direction": frame["t"].tolist(),
        "gauge_factor": {c: gauges[c].gauge_factor for c in CHANNELS},
        "channels": {"Ch1": "trace_left", "Ch2": "trace_right"},
        "readout": f"voltage across the gauge, {settings.divider_ohm / 1e3:g} kOhm divider at "
                   f"{settings.supply_V:g} V (seed 000 Fig. 3: 2.2 kOhm, 5 V)",
        "materials": {mesh.region_names[r]: m.name for r, m in region_materials.items()},
    }


def _stand_ins(region_materials, viscous: bool) -> list:
    """The materials' stand-in notes (the Prony stand-in only where the history used it)."""
    from designlab.fem.materials import stand_in_note

    return sorted({n for m in region_materials.values()
                   if (n := stand_in_note(m if viscous else
                                          dataclasses.replace(m, stand_ins=tuple(
                                              q for q in m.stand_ins if q != "prony"))))})


def run(part=None, protocol: StrapLoadTest | None = None,
        settings: StrapModelSettings | None = None, *, materials=None, mesh=None,
        progress: Callable[[str], None] | None = None, cache=None) -> StrapPrediction:
    """Mesh (unless ``mesh``, the flat printed mesh, is given), wrap, build, run the protocol's
    history and evaluate the metrics. ``cache`` (:class:`~designlab.fem.cache.FEMCache`): the
    FEM stage (:func:`solve_fem`) is computed once per :func:`fem_key` and reused by every
    design that shares it (readout settings, the wrap's slot, the nail plate)."""
    from designlab.fem.cache import timed_stage
    from designlab.geometry.strap import ArchStrap
    from designlab.sensors.strap.electrical import gauge_resistance

    part = part or ArchStrap()
    protocol = protocol or StrapLoadTest()
    settings = settings or StrapModelSettings()
    say = progress or (lambda s: None)
    key = None if mesh is not None else fem_key(part, protocol, settings, materials)
    fem, reused, timings = timed_stage(
        lambda: solve_fem(part, protocol, settings, materials, mesh, say), key, cache)
    mesh, n_keep, region_materials = _prediction_mesh(fem, settings, materials)
    frame = pad_frame(part, settings)

    t, fn, fx = protocol.time_history()
    viscous, strain, unit, u_peak = _gauge_strains(fem, fn, fx)

    t0 = time.perf_counter()
    trace_mat = region_materials[mesh.region_id(GAUGE_REGIONS[0])]
    R0 = gauge_resistance(part, settings.contact_ohm, trace_mat)["total"]
    gauges = {c: DividerGauge(float(fem["gauge_factor"][i]), float(fem["gauge_quadratic"][i]), R0,
                        settings.divider_ohm, settings.supply_V)
              for i, c in enumerate(CHANNELS)}
    g1 = gauges[CHANNELS[0]]
    pre, eps0, strain, unit = _prestrained(part, settings, trace_mat, g1.R0, strain, unit, say)
    voltage = np.column_stack([gauges[c].voltage(eps0 + strain[:, i])
                               for i, c in enumerate(CHANNELS)])
    v0 = np.array([float(gauges[c].voltage(eps0)) for c in CHANNELS])
    dV = voltage - v0
    report = evaluate(protocol, settings, t, fn, fx, dV, strain)
    report.update(_readout_entries(part, settings, trace_mat, g1, eps0, pre,
                                   report["sensitivity"]["V_per_N"]))
    timings["metrics"] = time.perf_counter() - t0
    report["timings_s"] = timings
    report["mesh"] = _mesh_entry(mesh, fem, settings)
    report["fem_reused"] = reused
    report["finger"] = _finger_entry(fem, settings, fn)
    report["fem_key"] = key[:16] if key is not None else None
    report["model"] = _model_entry(settings, frame, gauges, mesh, region_materials)
    if unit is not None:
        report["strain_per_N"] = {c: {"F_n": float(unit[i, 0]), "F_x": float(unit[i, 1])}
                                  for i, c in enumerate(CHANNELS)}
    report["viscoelastic"] = bool(viscous)
    if viscous:     # how the history was marched (fem.viscoelastic.solve_history; NaN: none)
        report["march"] = {"method": str(fem["march"]), "basis": int(fem["rom_basis"]),
                           **{k: (None if np.isnan(v := float(fem[k])) else v)
                              for k in ("rom_residual", "long_time_residual")}}
    stand = _stand_ins(region_materials, viscous)
    report["material_stand_ins"] = stand
    report["notes"] = [] if viscous else [
        "materials have no Prony series: elastic response, hysteresis is 0 by construction "
        "(not a measurement of the printed part)"]
    report["notes"].extend(stand)
    if pre is not None:
        pre["stress"] = wrap_stress(region_materials, mesh, pre["initial_strain"])
        for w in wrap_stress_warnings(pre["stress"]):
            warnings.warn(w, stacklevel=2)
    U_long = np.array(fem["U_long"], float)[:n_keep] if "U_long" in fem else None
    return StrapPrediction(t, fn, fx, strain, voltage, dV, report, mesh, u_peak[:n_keep], U_long)


# ------------------------------------------------------------------------------------ metrics

def staircase_reads(protocol: StrapLoadTest, settings: StrapModelSettings, n: int):
    """Per staircase level: sample indices of the end part (``read_fraction``) of its hold."""
    n_hold = max(1, int(round(protocol.step_hold_s / protocol.dt_s)))
    n_read = max(1, int(round(settings.read_fraction * n_hold)))
    levels = 2 * protocol.n_steps + 1
    return [np.arange((k + 1) * n_hold - n_read, (k + 1) * n_hold) for k in range(levels)
            if (k + 1) * n_hold <= n]


def _fit_transfer(F: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """M (k, 2) with Y ~ F M^T (least squares, no offset: readings are changes from rest)."""
    Mt, *_ = np.linalg.lstsq(F, Y, rcond=None)
    return Mt.T


def evaluate(protocol: StrapLoadTest, settings: StrapModelSettings, t, fn, fx, dV,
             strain) -> dict[str, Any]:
    """Calibration matrix, sum/difference sensitivities, cross-talk, linearity, hysteresis."""
    F = np.column_stack([fn, fx])
    if np.linalg.matrix_rank(F, tol=1e-9 * max(np.abs(F).max(), 1e-300)) < 2:
        raise ParameterError("protocol", {"shear_N": protocol.shear_N, "cycles": protocol.cycles},
                             "shear_N > 0 and cycles >= 1 (the grasp cycles decorrelate F_n and "
                             "F_x, which the 2x2 calibration needs)")
    sd = np.column_stack([dV[:, 0] + dV[:, 1], dV[:, 0] - dV[:, 1]])
    A, fit = fit_calibration_matrix(dV, F)               # [F_n, F_x] = A [dCh1, dCh2]
    A_sd, fit_sd = fit_calibration_matrix(sd, F)         # [F_n, F_x] = A_sd [sum, diff]
    M = _fit_transfer(F, dV)                             # V per N: channels x (F_n, F_x)
    M_sd = _fit_transfer(F, sd)
    # the paper's separate first-order fits: F_n from the sum, F_x from the difference
    pn, px = np.polyfit(sd[:, 0], fn, 1), np.polyfit(sd[:, 1], fx, 1)
    rms_n = float(np.sqrt(np.mean((np.polyval(pn, sd[:, 0]) - fn) ** 2)))
    rms_x = float(np.sqrt(np.mean((np.polyval(px, sd[:, 1]) - fx) ** 2)))
    cross = {
        "F_x_in_sum_per_N_percent": float(100 * abs(M_sd[0, 1]) / abs(M_sd[0, 0])),
        "F_n_in_diff_per_N_percent": float(100 * abs(M_sd[1, 0]) / abs(M_sd[1, 1])),
        "F_x_in_sum_at_protocol_percent": float(100 * abs(M_sd[0, 1]) * protocol.shear_N
                                                / (abs(M_sd[0, 0]) * protocol.normal_N)),
        "F_n_in_diff_at_protocol_percent": float(100 * abs(M_sd[1, 0]) * protocol.normal_N
                                                 / (abs(M_sd[1, 1]) * protocol.shear_N)),
    }
    # staircase: hysteresis (seed 001 eq. 1) and linearity
    reads = staircase_reads(protocol, settings, len(t))
    lev_n = np.array([fn[r].mean() for r in reads])
    lev_x = np.array([fx[r].mean() for r in reads])
    S = np.array([np.r_[dV[r].mean(0), sd[r].mean(0)] for r in reads])    # Ch1 Ch2 sum diff
    names = ("Ch1", "Ch2", "sum", "diff")
    by: dict[str, float | None] = {k: None for k in names}
    lin: dict[str, float | None] = {k: None for k in names}
    loops: dict[str, Any] = {}
    if len(reads) == 2 * protocol.n_steps + 1 and protocol.n_steps >= 2:
        lu, su, ld, sdn = loop_from_steps(lev_n, S)
        h = hysteresis_percent(lu, su, ld, sdn)
        by = {k: float(v) for k, v in zip(names, h)}
        k_up = len(lu)
        load_up = np.c_[lev_n, lev_n, lev_n, lev_x][:k_up]
        lin = {k: linearity_percent(load_up[:, i], S[:k_up, i]) for i, k in enumerate(names)}
        loops = {"F_n_N": lev_n.tolist(), "F_x_N": lev_x.tolist(),
                 "readings_V": {k: S[:, i].tolist() for i, k in enumerate(names)}}
    ch_h = [by[c] for c in CHANNELS if by[c] is not None]
    signs = {"F_n": np.sign(M[:, 0]).tolist(), "F_x": np.sign(M[:, 1]).tolist()}
    return {
        "hysteresis_percent": {"overall": float(np.mean(ch_h)) if ch_h else None,
                               "by_location": by,
                               "definition": "seed 001 eq. (1) on the normal-force staircase, "
                                             "readings = mean of the end of each hold; overall = "
                                             "mean of Ch1 and Ch2"},
        "calibration_matrix": A.tolist(),
        "calibration_units": "N per V: [F_n, F_x] = A [dCh1, dCh2] (changes from rest)",
        "calibration_fit": fit,
        "condition_number": condition_number(A),
        "calibration_matrix_sum_diff": A_sd.tolist(),
        "calibration_sum_diff_fit": fit_sd,
        "condition_number_sum_diff": condition_number(A_sd),
        "sum_diff_linear_fits": {"F_n_per_V_sum": float(pn[0]), "F_n_offset_N": float(pn[1]),
                                 "F_n_rms_N": rms_n, "F_x_per_V_diff": float(px[0]),
                                 "F_x_offset_N": float(px[1]), "F_x_rms_N": rms_x},
        "sensitivity": {
            "V_per_N": {c: {"F_n": float(M[i, 0]), "F_x": float(M[i, 1])}
                        for i, c in enumerate(CHANNELS)}
            | {"sum": {"F_n": float(M_sd[0, 0]), "F_x": float(M_sd[0, 1])},
               "diff": {"F_n": float(M_sd[1, 0]), "F_x": float(M_sd[1, 1])}},
            "units": "V per N (channel voltage change per newton)"},
        "cross_talk_percent": cross,
        "linearity_percent_span": lin,
        "premise": {"signs": signs,
                    "normal_same_sign": bool(signs["F_n"][0] == signs["F_n"][1] != 0),
                    "shear_opposite_sign": bool(signs["F_x"][0] == -signs["F_x"][1] != 0)},
        "peak": {"strain": float(np.abs(strain).max()), "dV_V": float(np.abs(dV).max())},
        "loops": loops,
        "series": {"t_s": t.tolist(), "F_n_N": fn.tolist(), "F_x_N": fx.tolist(),
                   "dCh1_V": dV[:, 0].tolist(), "dCh2_V": dV[:, 1].tolist(),
                   "sum_V": sd[:, 0].tolist(), "diff_V": sd[:, 1].tolist()},
    }
