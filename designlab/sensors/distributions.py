"""The inputs of a Monte Carlo (:mod:`designlab.predict.uncertainty`): a :class:`Distribution`
(normal, lognormal, uniform, fixed; bounds truncate by inverse CDF), an uncertain
:class:`Input` of a sensor with its default distribution and source, and the
:class:`MonteCarloModel` each sensor brings in its ``Sensor.uncertainty``. Names no sensor and
runs nothing: the sensors' Monte Carlo modules build on it, the runner sits above the registry."""

from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

from designlab.errors import ParameterError
from designlab.params import did_you_mean

#: largest magnitude of a distribution's number (a std of 1e308 draws inf: every build fails)
MAX_ABS = 1e20
DISTRIBUTIONS = ("normal", "lognormal", "uniform", "fixed")
_KEYS = {"normal": ("mean", "std", "lo", "hi"), "lognormal": ("mean", "std", "lo", "hi"),
         "uniform": ("lo", "hi"), "fixed": ("value",)}


@dataclass(frozen=True)
class Distribution:
    """One input's distribution (see the module docstring); ``source`` says where it is from."""

    dist: str
    mean: float | None = None
    std: float | None = None
    lo: float | None = None
    hi: float | None = None
    value: float | None = None
    source: str = ""

    def check(self, name: str) -> "Distribution":
        """This distribution, its kind, numbers, required keys and bounds checked (``name``:
        the input's, for the messages)."""
        where = f"uncertainty.{name}"
        if self.dist not in DISTRIBUTIONS:
            raise ParameterError(f"{where}.dist", self.dist, "one of " + ", ".join(DISTRIBUTIONS)
                                 + did_you_mean(self.dist, DISTRIBUTIONS))
        self._check_numbers(where)
        self._check_spread(where)
        self._check_bounds(where)
        return self

    def _check_numbers(self, where: str) -> None:
        """Every number given is finite; the ones this kind needs are given."""
        for k in ("mean", "std", "lo", "hi", "value"):
            v = getattr(self, k)
            if v is not None and (isinstance(v, bool) or not isinstance(v, numbers.Real)
                                  or not abs(v) <= MAX_ABS):
                raise ParameterError(f"{where}.{k}", v, f"a finite number, |value| <= {MAX_ABS:g}")
        need = {"normal": ("mean", "std"), "lognormal": ("mean", "std"), "uniform": ("lo", "hi"),
                "fixed": ("value",)}[self.dist]
        for k in need:
            if getattr(self, k) is None:
                raise ParameterError(f"{where}.{k}", None, f"a number ({self.dist} needs "
                                     + ", ".join(need) + ")")

    def _check_spread(self, where: str) -> None:
        """A spread is never negative; a lognormal is positive."""
        if self.std is not None and self.std < 0:
            raise ParameterError(f"{where}.std", self.std, ">= 0 (a spread is never negative)")
        if self.dist == "lognormal" and not self.mean > 0:
            raise ParameterError(f"{where}.mean", self.mean, "> 0 for a lognormal")
        if self.dist == "lognormal" and self.lo is not None and self.lo < 0:
            raise ParameterError(f"{where}.lo", self.lo, ">= 0 for a lognormal")

    def _check_bounds(self, where: str) -> None:
        """lo < hi (equal only for a uniform) and a normal's or lognormal's mean inside them."""
        if self.lo is not None and self.hi is not None and not self.lo < self.hi:
            if not (self.dist == "uniform" and self.lo == self.hi):
                raise ParameterError(f"{where}.hi", self.hi, f"> lo ({self.lo:g})")
        if self.dist in ("normal", "lognormal"):
            if (self.lo is not None and self.mean < self.lo) or (
                    self.hi is not None and self.mean > self.hi):
                raise ParameterError(f"{where}.mean", self.mean,
                                     f"inside the bounds [{self.lo}, {self.hi}] (bounds that "
                                     "exclude the mean truncate away the distribution's centre)")

    def check_within(self, name: str, meta: dict[str, Any], value: str) -> None:
        """Refuse a distribution that puts a share of its draws outside the values a build
        accepts (``meta``: a field's lo/hi metadata): its 1st and 99th percentiles must lie
        inside them (each build outside fails; a std of 1e10 mm fails every one)."""
        from designlab.params import allowed_text, check_field

        p1, p99 = (float(x) for x in self.ppf(np.array([0.01, 0.99])))
        try:
            for x in (p1, p99):
                check_field(name, x, meta)
        except ParameterError:
            raise ParameterError(
                f"uncertainty.{name}", value,
                f"a distribution whose 1st to 99th percentiles ({p1:.4g} to {p99:.4g}) lie "
                f"within the input's range {allowed_text(meta)} (a build outside it "
                "fails)") from None

    def short(self) -> str:
        """The distribution as its TOML table, e.g. ``{dist="normal", mean=0.03, std=1e+10}``."""
        keys = [k for k in ("mean", "std", "lo", "hi", "value") if getattr(self, k) is not None]
        return "{" + ", ".join([f'dist="{self.dist}"'] + [f"{k}={getattr(self, k):g}"
                                                          for k in keys]) + "}"

    @property
    def center(self) -> float:
        if self.dist == "fixed":
            return float(self.value)
        if self.dist == "uniform":
            return 0.5 * (self.lo + self.hi)
        return float(self.mean)

    def ppf(self, u: np.ndarray) -> np.ndarray:
        """Inverse CDF of the (truncated) distribution at ``u`` in (0, 1)."""
        from scipy import stats

        u = np.asarray(u, float)
        if self.dist == "fixed":
            return np.full_like(u, self.value)
        if self.dist == "uniform":
            return self.lo + u * (self.hi - self.lo)
        if self.std == 0:
            return np.full_like(u, self.mean)
        if self.dist == "normal":
            d = stats.norm(self.mean, self.std)
        else:
            s2 = math.log(1.0 + (self.std / self.mean) ** 2)
            d = stats.lognorm(math.sqrt(s2), scale=self.mean / math.sqrt(1.0 + (self.std / self.mean) ** 2))
        a = d.cdf(self.lo) if self.lo is not None else 0.0
        b = d.cdf(self.hi) if self.hi is not None else 1.0
        return d.ppf(a + u * (b - a))

    def to_json(self) -> dict[str, Any]:
        return {k: v for k, v in dataclasses.asdict(self).items() if v is not None and v != ""}


@dataclass(frozen=True)
class Input:
    """An uncertain input of a sensor: default distribution (with its source), how many
    independent draws per build (``per_build``: the three FSS015 units), and a doc line."""

    name: str
    default: Distribution
    doc: str
    per_build: int = 1
    #: the values a build accepts, as a parameter field's metadata (``lo``, ``hi``,
    #: ``lo_open``, ``hi_open``, ``unit``); None: found by
    #: :func:`designlab.predict.uncertainty.input_range`
    allowed: dict[str, Any] | None = None


@dataclass(frozen=True)
class MonteCarloModel:
    """What the Monte Carlo needs of one sensor (its ``Sensor.uncertainty``): adding a sensor
    touches its own module only.

    inputs:    the uncertain inputs (default distributions with their sources)
    metrics:   the names ``build`` returns (the ``mc.<metric>.<stat>`` columns of a robust sweep)
    fem_stage: ``(part, settings_dict, protocol_dict, cache) -> context``: the design's FEM stage
               through the cache (computed once by the parent, read by every worker)
    build:     ``(context, values, seed) -> {metric: value}``: one virtual build, its inputs by
               name (per-build inputs as lists), its readout noise from ``seed``
    paper:     the paper's numbers the metrics compare with (shown beside the summary)
    """

    inputs: tuple[Input, ...]
    metrics: tuple[str, ...]
    fem_stage: Callable[..., Any]
    build: Callable[..., dict[str, Any]]
    paper: dict[str, Any] = dataclasses.field(default_factory=dict)
