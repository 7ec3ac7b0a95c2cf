"""Load histories of the viscoelastic march, the per-quadrature-point Prony tables it relaxes
with, and the marched response (:class:`HistoryResult`)."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
import numpy as np
import scipy.sparse as sp

from designlab.errors import ModelError, ParameterError
from designlab.fem.model import Model, RefPoint, Spring, System
from designlab.fem.solvers import LinearSolver


@dataclass(frozen=True)
class History:
    """Load history: times ``t`` (s, non-decreasing; a repeated time is a jump) and the
    amplitude of each load case (array like ``t`` or callable ``a(t)``); cases not named have
    amplitude 0. The state before ``t[0]`` is undeformed and relaxed."""

    t: np.ndarray
    amplitudes: dict[str, object] = field(default_factory=dict)

    def __post_init__(self):
        t = np.asarray(self.t, float)
        if t.ndim != 1 or len(t) < 1 or np.any(np.diff(t) < 0) or not np.all(np.isfinite(t)):
            raise ParameterError("t", self.t, "a non-empty, non-decreasing 1-D time array (s)")
        object.__setattr__(self, "t", t)

    def amplitude(self, case: str) -> np.ndarray:
        a = self.amplitudes.get(case)
        if a is None:
            return np.zeros(len(self.t))
        v = np.asarray(a(self.t) if callable(a) else a, float)
        if v.shape != self.t.shape:
            raise ParameterError(f"amplitude of {case}", v.shape, f"shape {self.t.shape}")
        return v

    @staticmethod
    def step_hold(t_end: float, n_steps: int, cases: dict[str, float] | None = None
                  ) -> "History":
        """Jump to ``cases`` amplitudes (default {"default": 1}) at t = 0, hold until t_end."""
        t = np.linspace(0.0, t_end, n_steps + 1)
        cases = cases or {"default": 1.0}
        return History(t, {c: np.full(len(t), v) for c, v in cases.items()})

    @staticmethod
    def piecewise(times, values, case: str = "default", dt: float | None = None) -> "History":
        """Piecewise-linear amplitude through the breakpoints ``(times, values)`` (a repeated
        time is a jump), sampled at every breakpoint and at most ``dt`` apart in between, so
        ramps and holds are exactly linear per step."""
        times, values = np.asarray(times, float), np.asarray(values, float)
        if times.shape != values.shape or times.ndim != 1 or len(times) < 1:
            raise ParameterError("times", times, "a 1-D array as long as values")
        ts, vs = [times[0]], [values[0]]
        for a, b, va, vb in zip(times[:-1], times[1:], values[:-1], values[1:]):
            n = 1 if dt is None or b <= a else max(int(np.ceil((b - a) / dt - 1e-9)), 1)
            s = np.linspace(0.0, 1.0, n + 1)[1:]
            ts += list(a + (b - a) * s)
            vs += list(va + (vb - va) * s)
        return History(np.array(ts), {case: np.array(vs)})


class PronyTables:
    """Per-quadrature-point Prony tables of the whole mesh (elastic cells: no branches)."""

    def __init__(self, model: Model):
        nq = model.basis.dx.shape[1]
        rep = lambda v: np.repeat(v, nq)  # noqa: E731
        self.G0 = rep(model.cell_values("G"))
        self.K0 = rep(model.cell_values("K"))
        self.ginf = np.ones_like(self.G0)
        self.kinf = np.ones_like(self.K0)
        qp_region = rep(model.mesh.region)
        self.dev: list[tuple[np.ndarray, float, float]] = []      # (qp ids, g_i, tau_i)
        self.vol: list[tuple[np.ndarray, float, float]] = []
        for rid, mat in model.region_materials.items():
            if mat.prony is None:
                continue
            q = np.nonzero(qp_region == rid)[0]
            self.ginf[q] = mat.prony.g_inf
            self.kinf[q] = mat.prony.k_inf
            self.dev += [(q, g, tau) for g, tau in zip(mat.prony.g, mat.prony.tau)]
            self.vol += [(q, k, tau) for k, tau in zip(mat.prony.k, mat.prony.k_tau)]

    def effective(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Per-qp algorithmic (G_eff, K_eff) for step ``dt``."""
        G, K = self.G0 * self.ginf, self.K0 * self.kinf
        for (q, g, tau), out, base in [(b, G, self.G0) for b in self.dev] + \
                                      [(b, K, self.K0) for b in self.vol]:
            out[q] += base[q] * g * step_gamma(dt, tau)
        return G, K


def step_gamma(dt: float, tau: float) -> float:
    return 1.0 if dt <= 0 else -np.expm1(-dt / tau) * tau / dt


@dataclass(frozen=True, eq=False)
class HistoryResult:
    """Response to a :class:`History`: ``U`` (n_dofs, n_steps) displacements and ``F_int``,
    ``F_ext`` (3 n_points, n_steps) internal / applied nodal forces (``F_int`` None when
    solved with ``forces=False``). In batch mode
    (``solve_history(..., batch=True)``) every load case is its own history with its own
    amplitude: ``U`` is (n_dofs, n_cases, n_steps) and every output gains a leading case axis
    (order ``cases``). Methods mirror StaticResult with a time axis."""

    system: System
    history: History
    U: np.ndarray
    F_int: np.ndarray
    factorizations: int
    solvers: tuple[LinearSolver, ...]
    batch: bool = False
    march: str = "full"                 #: "full", "reduced" or "full (why not reduced)"
    rom_residual: float | None = None   #: reduced march: its certified relative residual
    basis_size: int = 0                 #: reduced march: the basis' size

    @property
    def model(self) -> Model:
        return self.system.model

    @cached_property
    def F_ext(self) -> np.ndarray:
        """Applied nodal forces (3 n_points, n_steps) (batch: (3 n_points, n_cases, n_steps)),
        from the load cases and the history's amplitudes (made when first asked for)."""
        A = np.stack([self.history.amplitude(c) for c in self.cases], axis=1)
        F = self.system.F[: 3 * self.model.n_points]
        return F[:, :, None] * A.T[None] if self.batch else F @ A.T

    @property
    def t(self) -> np.ndarray:
        return self.history.t

    @property
    def cases(self) -> tuple[str, ...]:
        return self.system.cases

    def displacement(self, step: int = -1) -> np.ndarray:
        """(n_points, 3) displacements at ``step`` (batch: (n_cases, n_points, 3)), mm."""
        u = self._at(step)[: 3 * self.model.n_points]
        return np.moveaxis(u.reshape(-1, 3, *u.shape[1:]), (0, 1), (-2, -1))

    def reactions(self, step: int = -1) -> np.ndarray:
        """(n_points, 3) forces of supports/couplings/springs on the body at ``step``, N
        (batch: (n_cases, n_points, 3))."""
        r = self._f_int()[..., step] - self.F_ext[..., step]
        return np.moveaxis(r.reshape(-1, 3, *r.shape[1:]), (0, 1), (-2, -1))

    def wrench(self, where, about=(0.0, 0.0, 0.0)) -> np.ndarray:
        """(n_steps, 6) reaction resultant (m_x, m_y, m_z, f_x, f_y, f_z) on a set
        (batch: (n_cases, n_steps, 6))."""
        ids = self.model.nodes(where)
        d = 3 * ids[:, None] + np.arange(3)
        r = np.moveaxis(self._f_int()[d] - self.F_ext[d], (0, 1), (-2, -1))   # (..., steps, k, 3)
        arm = self.model.mesh.points[ids] - np.asarray(about, float)
        return np.concatenate([np.cross(arm, r).sum(-2), r.sum(-2)], axis=-1)

    def _f_int(self) -> np.ndarray:
        if self.F_int is None:
            raise ModelError("no internal forces: the history was solved with forces=False")
        return self.F_int

    def _at(self, step: int) -> np.ndarray:
        """Displacements (n_dofs,) (batch: (n_dofs, n_cases)) at ``step``."""
        return self.U[..., step]

    def long_time(self) -> tuple[np.ndarray, float] | None:
        """A reduced march's long-time (relaxed) displacements of every load case, (n_dofs,
        n_cases) as :func:`long_time_displacements` gives them, from its basis (Galerkin with
        the relaxed stiffness), with their certified relative residual; None for a full march
        or when the residual is above the march's ``rom_tol`` (then factor the relaxed
        stiffness: :func:`long_time_displacements`)."""
        return None

    def linear(self, f) -> np.ndarray:
        """``f(U)`` for a map ``f`` linear in each column that takes (n_dofs, k) to (..., k)
        (e.g. :meth:`~designlab.fem.transducers.StrainGauge.strain`): (..., n_steps) (batch:
        (..., n_cases, n_steps)). A reduced march applies it to its basis alone."""
        return f(self.U)

    def _apply(self, L) -> np.ndarray:
        """Linear map (k, n_dofs) of every column: (..., n_steps, k)."""
        U = self.U.reshape(self.U.shape[0], -1)
        out = np.asarray(L @ U).reshape(L.shape[0], *self.U.shape[1:])
        return np.moveaxis(out, 0, -1)

    def twist(self, ref: RefPoint | str) -> np.ndarray:
        """(n_steps, 6) (w, v) of a reference point (batch: (n_cases, n_steps, 6))."""
        ref = self.model.refs[ref] if isinstance(ref, str) else ref
        vw = self._apply(self.model.twist_map(ref))
        return np.concatenate([vw[..., 3:], vw[..., :3]], axis=-1)

    def spring_force(self, spring: Spring | str) -> np.ndarray:
        """(n_steps,) spring reading k * elongation + preload(t), N (batch: (n_cases,
        n_steps)); isotropic springs add a trailing axis of 3."""
        s = self.model.springs[spring] if isinstance(spring, str) else spring
        f = s.k * self._apply(self.model.spring_map(s))                 # (..., steps, 1|3)
        if s.preload:
            amp = self.history.amplitude(s.case)
            if self.batch:
                amp = np.where(np.array(self.cases)[:, None] == s.case, amp[None], 0.0)
            f = f + s.preload * amp[..., None]
        return f[..., 0] if s.axis is not None else f

    def beam_force(self, beam) -> np.ndarray:
        """(n_steps, 12) K (L u) of a beam (batch: (n_cases, n_steps, 12))."""
        b = self.model.beams[beam] if isinstance(beam, str) else beam
        return self._apply(sp.csr_matrix(b.K) @ self.model.beam_map(b))

    def dofs(self, dofs) -> np.ndarray:
        """(n_steps, k) history of selected dofs (batch: (n_cases, n_steps, k))."""
        return np.moveaxis(self.U[np.asarray(dofs)], 0, -1)


def prony_coefficients(dt: float, taus, tc: np.ndarray, tg, n_groups: int
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per time constant a_t = exp(-dt/tau_t) and gamma_t c_t (``tc``: the term's factor on its
    group's stiffness), and per group (``tg``: each term's group) the sum of gamma_t c_t."""
    a = np.array([np.exp(-dt / tau) for tau in taus])
    gc = np.array([step_gamma(dt, tau) for tau in taus]) * tc
    gsum = np.zeros(n_groups)
    np.add.at(gsum, tg, gc)
    return a, gc, gsum
