"""Prony series of a generalized Maxwell material (relative moduli, time constants in s).

G(t) = G_0 (g_inf + sum_i g_i exp(-t / tau_i)),  g_inf = 1 - sum_i g_i   (same for the bulk
modulus with ``k``/``k_tau`` when given). G_0 is the instantaneous (glassy) modulus.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from designlab.errors import ParameterError


@dataclass(frozen=True)
class Prony:
    """Relative Prony terms: ``g`` (dimensionless, each > 0, sum < 1) and ``tau`` (s, > 0)
    on the shear modulus; optional ``k``/``k_tau`` on the bulk modulus."""

    g: tuple[float, ...] = ()
    tau: tuple[float, ...] = ()
    k: tuple[float, ...] = ()
    k_tau: tuple[float, ...] = ()

    def __post_init__(self):
        for name, a, t in (("g", self.g, self.tau), ("k", self.k, self.k_tau)):
            if len(a) != len(t):
                raise ParameterError(name, a, f"as many terms as {name == 'g' and 'tau' or 'k_tau'}")
            if any(not (x > 0) for x in a) or sum(a) >= 1:
                raise ParameterError(name, a, "each term > 0 and their sum < 1")
            if any(not (x > 0) for x in t):
                raise ParameterError(name == "g" and "tau" or "k_tau", t, "each time constant > 0 s")

    @property
    def g_inf(self) -> float:
        """Long-term relative shear modulus, 1 - sum(g)."""
        return 1.0 - float(sum(self.g))

    @property
    def k_inf(self) -> float:
        """Long-term relative bulk modulus, 1 - sum(k)."""
        return 1.0 - float(sum(self.k))

    def relaxation(self, t: np.ndarray) -> np.ndarray:
        """Relative shear relaxation function G(t)/G_0 at times ``t`` (s)."""
        t = np.asarray(t, float)[..., None]
        return self.g_inf + (np.asarray(self.g) * np.exp(-t / np.asarray(self.tau))).sum(-1)
