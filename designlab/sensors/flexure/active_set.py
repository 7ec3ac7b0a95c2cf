"""Unilateral penalty contacts on a linear structure with a 6-dof master, solved by an
active-set iteration, frictionless or with Coulomb friction (return map).

Shared by the beam chain (:mod:`designlab.sensors.flexure.beam_chain`) and the condensed solid
FEM (:mod:`designlab.sensors.flexure.helix_fem`).
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from threadpoolctl import ThreadpoolController

from designlab.errors import ModelError


#: master order (u_x, u_y, u_z, th_x, th_y, th_z) -> twist/wrench order (w, v) / (m, f)
PERM = np.array([3, 4, 5, 0, 1, 2])


def _block_diag(blocks: np.ndarray) -> np.ndarray:
    """Dense block-diagonal matrix of ``blocks`` (k, a, b) -> (k a, k b)."""
    k, a, b = blocks.shape
    out = np.zeros((k * a, k * b))
    for i in range(k):
        out[i * a:(i + 1) * a, i * b:(i + 1) * b] = blocks[i]
    return out


def _next_closed(g: np.ndarray, closed: np.ndarray, tol: float, seen: set, runs=None):
    """The next normal active set from the gaps ``g`` (mm): closed where ``g < -tol``, open
    where ``g > tol``, kept in between. A set met before (a cycle) flips only the contact with
    the largest gap instead. ``runs`` (line contacts: an id per contact, equal for neighbours
    along one contact line): from an all-open set only the deepest contact of each run of
    penetrated neighbours closes (a line contact zone then grows from its centre instead of
    shrinking from all the penetrated points, one edge point per solve). Returns (set, whether
    it is unchanged)."""
    new = np.where(g < -tol, True, np.where(g > tol, False, closed))
    if runs is not None and not closed.any() and np.count_nonzero(new) > 1:
        pen = np.nonzero(new)[0]
        brk = np.nonzero((np.diff(pen) > 1) | (np.diff(runs[pen]) != 0))[0] + 1
        new = np.zeros_like(closed)
        for seg in np.split(pen, brk):
            new[seg[np.argmin(g[seg])]] = True
    if np.array_equal(new, closed):
        return closed, True
    key = new.tobytes()
    if key in seen:
        bad = np.nonzero(new != closed)[0]
        new = closed.copy()
        k = bad[np.argmax(np.abs(g[bad]))]
        new[k] = not closed[k]
    seen.add(key)
    return new, False


_CONTROLLER: list = []


def _blas_controller() -> ThreadpoolController:
    """One threadpool controller for the process (building one scans the loaded libraries)."""
    if not _CONTROLLER:
        _CONTROLLER.append(ThreadpoolController())
    return _CONTROLLER[0]


class ActiveSet:
    """Unilateral penalty contacts on a linear structure with a 6-dof master (u, th), solved by
    an active-set iteration. A subclass sets ``Kq`` (sparse, n_q square: the structure),
    ``N`` (n_c, n_q: the gap opening per dof), ``kn``, ``g0`` (penalty N/mm and initial gap mm
    per contact), ``m`` (the master's 6 indices into q), ``nq`` and ``s`` (a
    :class:`ChainSettings`: perturbations, iteration limit). Shared by the beam chain and the
    condensed solid FEM (:mod:`designlab.sensors.flexure.helix_fem`)."""

    # ------------------------------------------------------------------ solves
    def _settle(self, closed: np.ndarray, step) -> tuple[np.ndarray, np.ndarray, np.ndarray, int]:
        """The active-set iteration: ``step(closed) -> (q, g)`` solves the structure with the
        contacts ``closed``; repeat until the set keeps its state (a band of +-tol around zero
        gap: no chatter at g ~ 0); on a cycle change only the contact that violates its state
        most. Returns (q, g, closed, iterations)."""
        tol = 1e-6 * self.s.perturbation_mm
        seen = set()
        runs = getattr(self, "runs", None)
        # the solves' dense products are small: BLAS threads only add overhead
        with _blas_controller().limit(limits=1, user_api="blas"):
            for it in range(self.s.max_iterations):
                q, g = step(closed)
                closed, settled = _next_closed(g, closed, tol, seen, runs)
                if settled:
                    return q, g, closed, it + 1
        raise ModelError(f"beam chain: contact active set did not settle in "
                         f"{self.s.max_iterations} iterations")

    def solve(self, q_master=None, f_master=None, ref: dict | None = None) -> dict:
        """Active-set solve with the master displaced to ``q_master`` (u, th) or loaded by
        ``f_master`` (f, m; the master free), starting from the active set of ``ref``."""
        nq, m = self.nq, self.m
        nc = len(self.kn)
        closed = np.zeros(nc, bool) if ref is None else ref["closed"].copy()
        q = np.zeros(nq) if ref is None else ref["q"].copy()
        fext = np.zeros(nq)
        if f_master is not None:
            fext[m] = f_master
        free = np.arange(nq) if q_master is None else np.setdiff1d(np.arange(nq), m)
        if q_master is not None:
            q[m] = q_master
        N, kn, g0 = self.N, self.kn, self.g0
        system = {}

        line = getattr(self, "runs", None) is not None

        def step(closed):
            w = kn * closed
            if line:                 # many contacts, few closed: assemble the closed ones only
                i = np.nonzero(closed)[0]
                A = (self.Kq + N[i].T @ sp.diags(w[i]) @ N[i]).tocsc()
            else:
                A = (self.Kq + N.T @ sp.diags(w) @ N).tocsc()
            b = fext - N.T @ (w * g0)
            rhs = b[free] - (A[free][:, m] @ q[m] if q_master is not None else 0.0)
            Aff = A[free][:, free]
            try:
                lu = spla.splu(Aff)
            except RuntimeError:
                raise ModelError("beam chain: singular stiffness (a spring end is not held)") from None
            x = lu.solve(rhs)
            q[free] = x + lu.solve(rhs - Aff @ x)     # one refinement step (stiff penalties)
            system.update(A=A, b=b)
            return q, g0 + N @ q

        q, g, closed, its = self._settle(closed, step)
        reaction = (system["A"] @ q - system["b"])[m] + (fext[m] if q_master is None else 0.0)
        return {"q": q.copy(), "closed": closed, "f_n": np.where(closed, -kn * np.minimum(g, 0), 0.0),
                "reaction": reaction, "iterations": its}

    def solve_force(self, f_master) -> dict:
        """The master loaded by ``f_master`` (f, m; free) from the open state, as :meth:`solve`
        but with one factorisation of the structure for every call: each active set's
        contacts enter as a low-rank update (Woodbury), so many load cases cost little."""
        lu = getattr(self, "_lu_free", None)
        if lu is None:
            lu = self._lu_free = spla.splu(sp.csc_matrix(self.Kq))
        fext = np.zeros(self.nq)
        fext[self.m] = f_master
        N = self.N.tocsr()
        kn, g0 = self.kn, self.g0
        x0 = lu.solve(fext)
        line = getattr(self, "runs", None) is not None

        def step(closed):
            idx = np.nonzero(closed)[0]
            if not len(idx):
                return x0, g0 + N @ x0
            if len(idx) > 40:                               # many contacts: factor directly
                Ni = N[idx]
                A = (self.Kq + Ni.T @ sp.diags(kn[idx]) @ Ni).tocsc()
                b = fext - Ni.T @ (kn[idx] * g0[idx])
                lu_a = spla.splu(A)
                q = lu_a.solve(b)
                q += lu_a.solve(b - A @ q)                  # one refinement step
                return q, g0 + N @ q
            U = N[idx].T.toarray()                          # (nq, k)
            KU = lu.solve(U)
            w = kn[idx]
            S = np.diag(1.0 / w) + U.T @ KU

            def wsolve(rhs):
                xb = lu.solve(rhs)
                return xb - KU @ np.linalg.solve(S, U.T @ xb)

            b = fext - U @ (w * g0[idx])
            q = wsolve(b)
            if line:                                        # one refinement step (stiff
                q += wsolve(b - self.Kq @ q - U @ (w * (U.T @ q)))   # short beams, penalties)
            return q, g0 + N @ q

        q, g, closed, its = self._settle(np.zeros(len(kn), bool), step)
        return {"q": q.copy(), "closed": closed, "f_n": np.where(closed, -kn * np.minimum(g, 0), 0.0),
                "iterations": its}

    def stiffness(self, ref: dict | None = None) -> tuple[np.ndarray, list]:
        """6x6 (twist -> wrench order) by symmetric master perturbations around ``ref``."""
        amp = np.r_[[self.s.perturbation_mm] * 3, [self.s.perturbation_rad] * 3]
        q0 = np.zeros(6) if ref is None else ref["q"][self.m]
        Kq = np.zeros((6, 6))
        closed = []
        for j in range(6):
            res = []
            for sgn in (1.0, -1.0):
                r = self.solve(q_master=q0 + sgn * amp[j] * np.eye(6)[j], ref=ref)
                res.append(r)
                closed.append(int(np.count_nonzero(r["closed"])))
            Kq[:, j] = (res[0]["reaction"] - res[1]["reaction"]) / (2 * amp[j])
        K = Kq[np.ix_(PERM, PERM)]
        return (K + K.T) / 2, closed

    # ------------------------------------------------------------------ Coulomb friction
    def rest_state(self) -> dict:
        """The unloaded, undeformed state: no contact force, no tangential traction."""
        nc = len(self.kn)
        return {"q": np.zeros(self.nq), "closed": np.zeros(nc, bool), "t": np.zeros((nc, 2)),
                "fext": np.zeros(self.nq), "reaction": np.zeros(6), "stick": np.zeros(nc, bool)}

    def solve_friction(self, mu: float, kt, q_master=None, f_master=None, ref: dict | None = None,
                       steps: int = 1) -> dict:
        """Frictional contact solved incrementally from the state ``ref`` (default: at rest) to
        the master displaced to ``q_master`` (u, th; the other dofs free) or loaded by
        ``f_master`` (f, m; the master free), in ``steps`` equal increments.

        Each closed contact carries, besides its normal penalty force ``f_n``, a tangential
        traction ``t`` (2 components, the contact's ``rt`` directions) by a penalty ``kt`` (N/mm
        per contact) and Coulomb's law, integrated by the return map (Simo & Hughes,
        *Computational Inelasticity*, 1998, sec. 1.2 and 2.7 for the 1-D/plasticity form; Wriggers,
        *Computational Contact Mechanics*, 2006, sec. 5.2 for contact): the trial
        ``t_tr = t_n + kt * (slip increment)``; stick if ``|t_tr| <= mu f_n``, else slip with
        ``t = mu f_n t_tr / |t_tr|``. Each increment is a Newton iteration with the consistent
        (unsymmetric) tangent, the normal active set updated as in :meth:`_settle`; an increment
        that does not converge is halved (up to 12 times). A contact that opens loses its
        traction. ``mu = 0`` is the frictionless :meth:`solve` (to round-off).
        Returns ``q``, ``closed``, ``t`` (nc, 2), ``f_n``, ``stick``, ``reaction`` (the master's
        load, master order f, m), ``fext`` and ``iterations``."""
        st = self.rest_state() if ref is None else ref
        kt = np.broadcast_to(np.asarray(kt, float), self.kn.shape)
        if q_master is not None:
            q1 = np.asarray(q_master, float)
            q0 = st["q"][self.m]
            target = lambda a: (q0 + a * (q1 - q0), np.zeros(self.nq))       # noqa: E731
        else:
            f1 = np.zeros(self.nq)
            f1[self.m] = f_master
            f0 = st["fext"] if "fext" in st else np.zeros(self.nq)
            target = lambda a: (None, f0 + a * (f1 - f0))                     # noqa: E731
        its = 0
        todo = [(k / steps, (k + 1) / steps, 0) for k in range(steps)][::-1]
        while todo:
            a0, a1, depth = todo.pop()
            qm, fext = target(a1)
            new = self._friction_increment(st, qm, fext, mu, kt)
            if new is None:
                if depth >= 12:
                    raise ModelError("beam chain: frictional contact did not converge (the "
                                     "increment was halved 12 times)")
                mid = (a0 + a1) / 2
                todo += [(mid, a1, depth + 1), (a0, mid, depth + 1)]
                continue
            its += new["iterations"]
            st = new
        return dict(st, iterations=its)

    def _free_parts(self, master_free: bool):
        """Structure, gap and slip operators on the free dofs (the master free or prescribed),
        cached."""
        cache = self.__dict__.setdefault("_free_cache", {})
        if master_free not in cache:
            free = (np.arange(self.nq) if master_free
                    else np.setdiff1d(np.arange(self.nq), self.m))
            Kq = sp.csr_matrix(self.Kq)
            cache[master_free] = (Kq[free][:, free].tocsc(), sp.csr_matrix(self.N)[:, free],
                                  sp.csr_matrix(self.Rt)[:, free])
        return cache[master_free]

    def _friction_increment(self, st: dict, q_m, fext, mu: float, kt) -> dict | None:
        """One increment from the converged state ``st``: Newton on the equilibrium with the
        return-mapped tractions; None when it does not converge (the caller halves it)."""
        nq, m = self.nq, self.m
        N, kn, g0 = self.N, self.kn, self.g0
        Rt = self.Rt
        nc = len(kn)
        free = np.arange(nq) if q_m is None else np.setdiff1d(np.arange(nq), m)
        q = st["q"].copy()
        if q_m is not None:
            q[m] = q_m
        qn, tn = st["q"], np.where(st["closed"][:, None], st["t"], 0.0)
        closed = st["closed"].copy()
        tol = 1e-6 * self.s.perturbation_mm
        seen = set()

        def state(q, closed):
            g = g0 + N @ q
            w = kn * closed
            fn = np.maximum(-w * g, 0.0)
            ttr = np.where(closed[:, None], tn + kt[:, None] * (Rt @ (q - qn)).reshape(nc, 2), 0.0)
            nt = np.linalg.norm(ttr, axis=1)
            lim = mu * fn
            stick = closed & (nt <= lim) & (lim > 0)
            scale = np.where(stick, 1.0, np.where(nt > 0, lim / np.where(nt > 0, nt, 1.0), 0.0))
            t = ttr * scale[:, None]
            fi = self.Kq @ q + N.T @ (w * g) + Rt.T @ t.ravel()
            return g, w, fn, ttr, nt, stick, t, fi

        for it in range(self.s.max_iterations):
            g, w, fn, ttr, nt, stick, t, fi = state(q, closed)
            # consistent tangent of the tractions: stick kt I; slip kt (mu f_n / |t_tr|)
            # (I - n n^T) on the slip and -mu k_n n on the normal gap
            D = np.zeros((nc, 2, 2))
            Cn = np.zeros((nc, 2))
            slip = closed & ~stick & (nt > 0)
            D[stick] = kt[stick, None, None] * np.eye(2)
            if slip.any():
                n = ttr[slip] / nt[slip, None]
                sc = kt[slip] * mu * fn[slip] / nt[slip]
                D[slip] = sc[:, None, None] * (np.eye(2) - n[:, :, None] * n[:, None, :])
                Cn[slip] = np.where((fn[slip] > 0)[:, None], -mu * kn[slip, None] * n, 0.0)
            # the tangent on the free dofs: the structure plus the closed contacts' terms
            idx = np.nonzero(closed)[0]
            Kff, Nf, Rf = self._free_parts(q_m is None)
            A = Kff
            if len(idx):
                Nc = Nf[idx]
                Rc = Rf[np.ravel(np.column_stack([2 * idx, 2 * idx + 1]))]
                Db = sp.csr_matrix(_block_diag(D[idx]))
                Cb = sp.csr_matrix(_block_diag(Cn[idx][:, :, None]))
                A = A + Nc.T @ sp.diags(kn[idx]) @ Nc + Rc.T @ (Db @ Rc + Cb @ Nc)
            r = fi - fext
            try:
                lu = spla.splu(sp.csc_matrix(A))
                dq = lu.solve(-r[free])
                dq += lu.solve(-r[free] - A @ dq)       # one refinement step (stiff penalties)
            except RuntimeError:
                raise ModelError("beam chain: singular stiffness (a spring end is not held)") from None
            # backtracking on the residual (slip directions turn: a full Newton step can cycle)
            r0, alpha = np.linalg.norm(r[free]), 1.0
            for _ in range(30):
                qt = q.copy()
                qt[free] += alpha * dq
                if np.linalg.norm((state(qt, closed)[-1] - fext)[free]) < r0:
                    break
                alpha /= 2
            q = qt
            g_new = g0 + N @ q
            closed, settled = _next_closed(g_new, closed, tol, seen)
            if not settled:
                continue
            # same normal set: converged when the residual is round-off and the stick/slip
            # split of the new state is the one the step was taken with
            g2, w2, fn2, ttr2, nt2, stick2, t2, fi2 = state(q, closed)
            res = np.linalg.norm((fi2 - fext)[free])
            ref_scale = max(np.linalg.norm(fi2), np.linalg.norm(fext), 1e-12)
            if res <= 1e-9 * ref_scale:      # (the return map is continuous at |t_tr| = mu f_n)
                return {"q": q.copy(), "closed": closed, "t": t2, "f_n": fn2, "stick": stick2,
                        "fext": np.asarray(fext, float).copy(), "reaction": fi2[m].copy(),
                        "iterations": it + 1}
        return None

    def friction_stiffness(self, mu: float, kt, ref: dict | None = None, steps: int = 1,
                           amplitude: float = 1.0) -> tuple[np.ndarray, list]:
        """6x6 (twist -> wrench order) by symmetric master perturbations around the frictional
        state ``ref`` (each solved from ``ref`` with its tractions by :meth:`solve_friction`),
        perturbations ``amplitude`` times the settings' (0.02 mm, 2 mrad). With friction this
        is the secant of the two one-sided paths, which depends on the amplitude (a sliding
        contact adds up to ``2 mu f_n`` across the two) and need not be symmetric (returned as
        computed, with the (closed, stuck) contact counts of every path)."""
        amp = amplitude * np.r_[[self.s.perturbation_mm] * 3, [self.s.perturbation_rad] * 3]
        st = self.rest_state() if ref is None else ref
        q0 = st["q"][self.m]
        Kq = np.zeros((6, 6))
        info = []
        for j in range(6):
            res = [self.solve_friction(mu, kt, q_master=q0 + sgn * amp[j] * np.eye(6)[j],
                                       ref=st, steps=steps) for sgn in (1.0, -1.0)]
            info += [(int(np.count_nonzero(r["closed"])), int(np.count_nonzero(r["stick"])))
                     for r in res]
            Kq[:, j] = (res[0]["reaction"] - res[1]["reaction"]) / (2 * amp[j])
        return Kq[np.ix_(PERM, PERM)], info
