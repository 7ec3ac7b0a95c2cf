"""Virtual transducers: what the sensors of the three seeds would read from an FEM solution.

Each transducer has ``read(result)`` for a :class:`~designlab.fem.static.StaticResult`
(one row per load case) or a :class:`~designlab.fem.history.HistoryResult` (one row per
time step). Linear ones are also linear maps of the displacement columns: ``from_u(U)``.

- :class:`StrainGauge` (seed 000): volume-weighted mean strain along the trace direction over a
  region, dR/R = GF eps + c2 eps^2, optional TCR, and the voltage-divider readout.
- :class:`ForceButton` (seed 001): force of a spring along its axis (compression positive when
  the spring's axis points into the sensor).
- :class:`RigidPose` (seed 002): twist (w_x, w_y, w_z, v_x, v_y, v_z) of a rigid reference point.
- :class:`ReactionWrench`: (m_x, m_y, m_z, f_x, f_y, f_z) of the reactions on a set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from designlab.errors import ModelError, ParameterError
from designlab.fem.model import Model, RefPoint

#: seed 000 readout (../shared/data/papers/fingertip_strap_tpu.json, tables readout and strap)
DIVIDER_OHM = 2200.0
SUPPLY_V = 5.0
GAUGE_OHM = 1800.0


#: Boltzmann constant, J/K (CODATA 2018, exact)
K_BOLTZMANN = 1.380649e-23


def sheet_resistance(resistivity: float, thickness: float) -> float:
    """Sheet resistance (ohm per square) of a conductor layer: rho / t (ohm*mm, mm)."""
    if not resistivity > 0:
        raise ParameterError("resistivity", resistivity, "> 0 ohm*mm")
    if not thickness > 0:
        raise ParameterError("thickness", thickness, "> 0 mm")
    return resistivity / thickness


def resistivity_from(R: float, squares: float, thickness: float) -> float:
    """Effective resistivity (ohm*mm) that gives resistance ``R`` (ohm) on a path of
    ``squares`` squares of a layer ``thickness`` thick: R t / squares (R = rho L / A)."""
    if not R > 0:
        raise ParameterError("R", R, "> 0 ohm")
    if not squares > 0:
        raise ParameterError("squares", squares, "> 0")
    return R * thickness / squares


def divider_slope(R, R_fixed: float = DIVIDER_OHM, V_s: float = SUPPLY_V):
    """dV/dR (V per ohm) of the voltage across the gauge in a divider with ``R_fixed``:
    V_s R_fixed / (R + R_fixed)^2 (same magnitude across the fixed resistor)."""
    R = np.asarray(R, float)
    return V_s * R_fixed / (R + R_fixed) ** 2


def optimal_divider_resistor(R) -> float:
    """Fixed resistor that maximises the divider's voltage change per relative resistance
    change, R dV/dR = V_s R R_f / (R + R_f)^2: d/dR_f = 0 at R_f = R."""
    return float(R)


def divider_current(R, R_fixed: float = DIVIDER_OHM, V_s: float = SUPPLY_V):
    """Current through the divider, A (ohm, V)."""
    return V_s / (np.asarray(R, float) + R_fixed)


def johnson_noise_vrms(R, bandwidth_hz: float, T_kelvin: float) -> float:
    """Thermal (Johnson-Nyquist) noise voltage, V rms: sqrt(4 k T R B)."""
    if not bandwidth_hz > 0 or not T_kelvin > 0 or not R >= 0:
        raise ParameterError("johnson_noise", (R, bandwidth_hz, T_kelvin),
                             "R >= 0 ohm, bandwidth > 0 Hz, T > 0 K")
    return float(np.sqrt(4 * K_BOLTZMANN * T_kelvin * R * bandwidth_hz))


def quantization_noise_vrms(full_scale_V: float, bits: int) -> float:
    """Quantisation noise of an ideal ADC, V rms: LSB / sqrt(12), LSB = full scale / 2^bits."""
    if not full_scale_V > 0 or not 1 <= int(bits) <= 32:
        raise ParameterError("adc", (full_scale_V, bits), "full scale > 0 V, 1 <= bits <= 32")
    return full_scale_V / 2 ** int(bits) / np.sqrt(12.0)


def _columns(result) -> np.ndarray:
    """(n_dofs, k) displacement columns of a static (cases) or history (steps) result."""
    return np.asarray(result.U)


def divider_voltage(R, R_fixed: float = DIVIDER_OHM, V_s: float = SUPPLY_V,
                    across: str = "gauge"):
    """Output of a voltage divider gauge + fixed resistor on supply ``V_s`` (V): the voltage
    across the gauge, V_s R / (R + R_fixed), or across the fixed resistor (``across=
    "resistor"``), V_s R_fixed / (R + R_fixed). Seed 000 (Fig. 3) reads one channel per gauge
    with 2.2 kOhm at 5 V; it does not say which node is sampled, we default to the gauge."""
    R = np.asarray(R, float)
    if across == "gauge":
        return V_s * R / (R + R_fixed)
    if across == "resistor":
        return V_s * R_fixed / (R + R_fixed)
    raise ParameterError("across", across, "'gauge' or 'resistor'")


@dataclass(frozen=True, eq=False)
class StrainGauge:
    """Strain gauge on the cells of ``region`` (a body name, or a boolean/int cell selection).

    ``direction``: constant (3,) axis or callable ``d(x) -> (..., 3)`` of the quadrature point
    coordinates (normalised here), e.g. the tangent of a curved trace. ``gauge_factor``,
    ``gauge_quadratic`` and ``tcr`` default to the region's material. ``R0`` in ohm (1.8 kOhm,
    seed 000; a sensor may derive it from its conductor geometry), ``T0`` reference temperature
    (deg C), ``R_fixed`` and ``V_s`` the divider's fixed resistor (ohm) and supply (V)."""

    model: Model
    region: object
    direction: object = (1.0, 0.0, 0.0)
    gauge_factor: float | None = None
    gauge_quadratic: float | None = None
    tcr: float | None = None
    R0: float = GAUGE_OHM
    T0: float = 20.0
    name: str = "gauge"
    R_fixed: float = DIVIDER_OHM
    V_s: float = SUPPLY_V

    def __post_init__(self):
        mesh = self.model.mesh
        if isinstance(self.region, str):
            rid = mesh.region_id(self.region)
            cells = np.nonzero(mesh.region == rid)[0]
            mat = self.model.region_materials[rid]
        else:
            sel = np.asarray(self.region)
            cells = np.nonzero(sel)[0] if sel.dtype == bool else np.unique(sel)
            mats = {self.model.region_materials[int(r)].name: self.model.region_materials[int(r)]
                    for r in np.unique(mesh.region[cells])} if len(cells) else {}
            mat = next(iter(mats.values())) if len(mats) == 1 else None
        if len(cells) == 0:
            raise ModelError(f"strain gauge '{self.name}' covers no cells")
        gf = self.gauge_factor if self.gauge_factor is not None else (
            mat.gauge_factor if mat is not None else None)
        if gf is None:
            raise ParameterError("gauge_factor", None, "a number: the gauge material "
                                 f"{mat.name if mat else '(mixed)'} has no gauge factor")
        object.__setattr__(self, "gauge_factor", float(gf))
        if self.gauge_quadratic is None:
            object.__setattr__(self, "gauge_quadratic", mat.gauge_quadratic if mat else 0.0)
        if self.tcr is None:
            object.__setattr__(self, "tcr", mat.tcr if mat else 0.0)
        basis = self.model.basis
        x = basis.x[cells]                                            # (k, nq, 3)
        d = self.direction(x) if callable(self.direction) else np.broadcast_to(
            np.asarray(self.direction, float), x.shape)
        nrm = np.linalg.norm(d, axis=-1, keepdims=True)
        if not np.all(nrm > 0):
            raise ParameterError("direction", self.direction, "non-zero vectors")
        d = d / nrm
        # e.eps.e with engineering shears: xx yy zz + xy, xz, yz products
        proj = np.stack([d[..., 0] ** 2, d[..., 1] ** 2, d[..., 2] ** 2, d[..., 0] * d[..., 1],
                         d[..., 0] * d[..., 2], d[..., 1] * d[..., 2]], axis=-1)
        w = basis.dx[cells] / basis.dx[cells].sum()
        nq = basis.dx.shape[1]
        rows = (6 * (cells[:, None, None] * nq + np.arange(nq)[None, :, None])
                + np.arange(6)).ravel()
        vec = sp.csr_matrix(((w[..., None] * proj).ravel(), (np.zeros(rows.size, int), rows)),
                            shape=(1, self.model.B.shape[0]))
        op = (vec @ self.model.B).tocsr()
        object.__setattr__(self, "_op", op)
        object.__setattr__(self, "cells", cells)

    def strain(self, U) -> np.ndarray:
        """Mean strain along the direction for each displacement column of U (n_dofs, ...)."""
        U = np.asarray(U)
        n3 = 3 * self.model.n_points
        out = np.asarray(self._op @ U[:n3].reshape(n3, -1))
        return out.reshape(U.shape[1:]) if U.ndim > 1 else out.reshape(())

    def dR_R(self, strain, temperature=None) -> np.ndarray:
        """Relative resistance change: (1 + GF eps + c2 eps^2)(1 + tcr (T - T0)) - 1."""
        eps = np.asarray(strain, float)
        r = 1.0 + self.gauge_factor * eps + self.gauge_quadratic * eps**2
        if temperature is not None:
            r = r * (1.0 + self.tcr * (np.asarray(temperature, float) - self.T0))
        return r - 1.0

    def resistance(self, strain, temperature=None) -> np.ndarray:
        """Gauge resistance, ohm."""
        return self.R0 * (1.0 + self.dR_R(strain, temperature))

    def voltage(self, strain, temperature=None, across: str = "gauge") -> np.ndarray:
        """Seed-000 divider output (V), see :func:`divider_voltage`."""
        return divider_voltage(self.resistance(strain, temperature), R_fixed=self.R_fixed,
                               V_s=self.V_s, across=across)

    def read(self, result, temperature=None) -> dict[str, np.ndarray]:
        """{"strain", "dR_R", "resistance_ohm", "voltage_V"} per case/step."""
        eps = self.strain(_columns(result))
        return {"strain": eps, "dR_R": self.dR_R(eps, temperature),
                "resistance_ohm": self.resistance(eps, temperature),
                "voltage_V": self.voltage(eps, temperature)}


@dataclass(frozen=True)
class ForceButton:
    """Force sensor modelled as a stiff spring of the model (see Model.spring)."""

    spring: str

    def read(self, result) -> np.ndarray:
        """Force (N) per case/step."""
        f = result.spring_force(self.spring) if hasattr(result, "history") else np.array(
            [result.spring_force(self.spring, c) for c in result.cases])
        return np.asarray(f, float)


@dataclass(frozen=True)
class RigidPose:
    """Twist (w_x, w_y, w_z, v_x, v_y, v_z) of a reference point (rad, mm)."""

    ref: str | RefPoint

    def read(self, result) -> np.ndarray:
        if hasattr(result, "history"):
            return result.twist(self.ref)
        return np.array([result.twist(self.ref, c) for c in result.cases])


@dataclass(frozen=True)
class ReactionWrench:
    """Reaction resultant (m_x, m_y, m_z, f_x, f_y, f_z) on a set about ``about`` (N mm, N)."""

    where: object
    about: tuple = (0.0, 0.0, 0.0)

    def read(self, result) -> np.ndarray:
        if hasattr(result, "history"):
            return result.wrench(self.where, about=self.about)
        return np.array([result.wrench(self.where, c, about=self.about) for c in result.cases])
