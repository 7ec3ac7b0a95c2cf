"""A population of fingers for the strap's sizes: drawn from an anthropometric table (by sex or
all adults, keeping the table's correlations) or read from a user's CSV of per-person sizes.
The table gives the index finger's breadth at the distal joint but no fingertip depth: depth is
a stated assumption (a ratio of breadth with its own scatter), named in every output.
"""

from __future__ import annotations

import csv
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from designlab.errors import DataError, ParameterError
from designlab.sensors.strap.fit import (DEPTH_RANGE, SECTION_PERIMETER_RATIO, WIDTH_RANGE,
                                         ellipse_perimeter)

#: the anthropometric table shipped with the package (designlab/data/)
TABLE_JSON = "index_finger_sizekorea8.json"
#: the table's measure used as the finger's width under the strap
BREADTH = "index_distal_phalanx_breadth_mm"
GROUPS = ("all", "men", "women")
#: the table's percentiles a fit check compares
PERCENTILES = (1, 5, 10, 25, 50, 75, 90, 95, 99)
#: drawn fingers per population: at least this many, at most
FINGERS_RANGE = (50, 200_000)
#: a user's CSV: the columns it must have (mm) and the ones it may have
CSV_REQUIRED = ("width", "depth")
CSV_OPTIONAL = ("length", "perimeter")


@dataclass(frozen=True)
class DepthAssumption:
    """Fingertip depth (nail to pulp) = ratio x breadth, the ratio drawn per person from a
    normal (``mean``, ``sd``) cut to [``lo``, ``hi``]. NOT a cited value: no readable source
    gives fingertip depth for this population (the table's README). The range covers a round
    section (1.0), the strap model's default finger 16 x 14 mm (0.875) and the ratio 0.75 of
    a secondary transcription of Nag, Nag & Desai 2003 (index interphalangeal depth 7.8 mm /
    breadth 10.4 mm, not checked against the paper: docs/strap.md)."""

    mean: float = 0.85
    sd: float = 0.05
    lo: float = 0.70
    hi: float = 1.00

    def __post_init__(self):
        if not 0.55 <= self.lo < self.hi <= 1.25:
            raise ParameterError("depth ratio range", (self.lo, self.hi),
                                 "0.55 <= lo < hi <= 1.25 (a fingertip-like section)")
        if not self.lo <= self.mean <= self.hi:
            raise ParameterError("depth ratio mean", self.mean, f"{self.lo:g}-{self.hi:g}")
        if not 0 <= self.sd <= 0.2:
            raise ParameterError("depth ratio sd", self.sd, "0 <= value <= 0.2")

    def describe(self) -> str:
        return (f"ASSUMED fingertip depth = ratio x breadth, ratio normal(mean {self.mean:g}, "
                f"sd {self.sd:g}) cut to {self.lo:g}-{self.hi:g} per person; no cited "
                "source for this population (the range covers a round section, the strap's "
                "default 16 x 14 mm finger and a secondary transcription's 0.75)")


#: the distal phalanx's length under the strap: not in the table; it enters only the check
#: that the strap fits on the phalanx, not the strain or the sensitivity
ASSUMED_LENGTH_MM = 25.0


@dataclass(frozen=True)
class Population:
    """Per-person finger sizes at the strap (mm) and where they come from."""

    width: np.ndarray
    depth: np.ndarray
    length: np.ndarray
    perimeter: np.ndarray
    source: str
    group: str
    assumptions: tuple[str, ...] = ()
    sex: np.ndarray | None = field(default=None, repr=False)

    @property
    def size(self) -> int:
        return int(len(self.width))

    def describe(self) -> dict[str, Any]:
        """What the population is (for every output that uses it)."""
        pct = {f"p{p}": float(np.percentile(self.width, p)) for p in (5, 50, 95)}
        return {"source": self.source, "group": self.group, "fingers": self.size,
                "width_mm": pct, "perimeter_mm": {
                    f"p{p}": float(np.percentile(self.perimeter, p)) for p in (5, 50, 95)},
                "assumptions": list(self.assumptions)}


def load_table(path: str | Path | None = None) -> dict[str, Any]:
    """The anthropometric table (default: the one shipped in ``designlab/data/``)."""
    from importlib import resources

    if path is None:
        return json.loads((resources.files("designlab") / "data" / TABLE_JSON).read_text())
    return json.loads(Path(path).read_text(encoding="utf-8"))


def sheppard_sd(sd: float, step: float = 1.0) -> float:
    """The sd of the continuous size behind readings rounded to ``step`` (Sheppard's
    correction: the rounding adds step^2 / 12 to the variance)."""
    return math.sqrt(max(sd ** 2 - step ** 2 / 12, 1e-12))


def _draw_group(gd: dict[str, Any], n: int, rng: np.random.Generator) -> np.ndarray:
    """``n`` draws of the table's measures for one sex: a Gaussian copula with the table's
    correlation matrix and normal marginals (the table's mean, sd corrected for the whole-mm
    readings). Columns in the table's correlation order."""
    order = gd["correlation"]["order"]
    C = np.asarray(gd["correlation"]["matrix"], float)
    z = rng.standard_normal((n, len(order))) @ np.linalg.cholesky(C).T
    mu = np.array([gd[m]["mean"] for m in order])
    sd = np.array([sheppard_sd(gd[m]["sd"]) for m in order])
    return mu + sd * z


def draw_measures(group: str = "all", n: int = 1000, seed: int = 0,
                  table: dict[str, Any] | None = None) -> tuple[np.ndarray, np.ndarray, list]:
    """The table's measures for ``n`` adults of ``group``: (values n x 4, sex per row, measure
    names). ``all``: men and women in the survey's proportions, each from its own copula (the
    table's all-adults row is that mixture)."""
    if group not in GROUPS:
        raise ParameterError("--population", group, "|".join(GROUPS))
    lo, hi = FINGERS_RANGE
    if not (isinstance(n, (int, np.integer)) and lo <= n <= hi):
        raise ParameterError("--fingers", n, f"a whole number {lo}-{hi}")
    if not (isinstance(seed, (int, np.integer)) and 0 <= seed < 2 ** 63):
        raise ParameterError("--seed", seed, "a whole number >= 0")
    table = table or load_table()
    groups = table["groups"]
    rng = np.random.default_rng(seed)
    sexes = ("men", "women") if group == "all" else (group,)
    weights = np.array([groups[s]["n"] for s in sexes], float)
    counts = rng.multinomial(n, weights / weights.sum())
    vals = [_draw_group(groups[s], int(k), rng) for s, k in zip(sexes, counts)]
    sex = np.concatenate([[s] * int(k) for s, k in zip(sexes, counts)])
    return np.vstack(vals), sex, list(groups[sexes[0]]["correlation"]["order"])


def _depth_ratio(depth: DepthAssumption, n: int, rng: np.random.Generator) -> np.ndarray:
    """Per-person depth ratios: normal draws redrawn until inside [lo, hi] (a cut normal)."""
    r = depth.mean + depth.sd * rng.standard_normal(n)
    for _ in range(100):
        bad = (r < depth.lo) | (r > depth.hi)
        if not bad.any():
            break
        r[bad] = depth.mean + depth.sd * rng.standard_normal(int(bad.sum()))
    return np.clip(r, depth.lo, depth.hi)


def _check_sizes(width: np.ndarray, depth: np.ndarray, what: str) -> None:
    """Every finger inside the wrap model's range (fit.Finger's)."""
    for name, v, (lo, hi) in (("width", width, WIDTH_RANGE), ("depth", depth, DEPTH_RANGE)):
        bad = (v < lo) | (v > hi) | ~np.isfinite(v)
        if bad.any():
            raise ParameterError(f"{what} {name}", round(float(v[bad][0]), 3),
                                 f"{lo:g} <= value <= {hi:g} mm (the wrap model's range)")


def draw(group: str = "all", n: int = 1000, seed: int = 0,
         depth: DepthAssumption | None = None, table: dict[str, Any] | None = None) -> Population:
    """``n`` fingers of ``group`` (all | men | women) from the table, seeded: the breadth at
    the distal joint as the width under the strap (the strap sits on the distal phalanx next
    to that joint: an assumption), the depth from :class:`DepthAssumption`, the length
    :data:`ASSUMED_LENGTH_MM`, the perimeter the ellipse of width and depth. Fingers outside
    the wrap model's width range are clipped to it (a handful of the table's tails)."""
    depth = depth or DepthAssumption()
    table = table or load_table()
    vals, sex, order = draw_measures(group, n, seed, table)
    width = np.clip(vals[:, order.index(BREADTH)], *WIDTH_RANGE)
    ratio = _depth_ratio(depth, n, np.random.default_rng([seed, 1]))
    d = np.clip(ratio * width, *DEPTH_RANGE)
    per = np.array([ellipse_perimeter(a / 2, b / 2) for a, b in zip(width, d)])
    return Population(width, d, np.full(n, ASSUMED_LENGTH_MM), per,
                      source=table["source"], group=group, sex=sex,
                      assumptions=(
                          "width under the strap = the table's index finger breadth at the "
                          "distal joint (ASSUMED: the strap sits on the distal phalanx next "
                          "to it)",
                          depth.describe(),
                          f"ASSUMED distal phalanx length {ASSUMED_LENGTH_MM:g} mm (enters "
                          "only the strap-fits-the-phalanx check)",
                          "perimeter = ellipse of width and depth (Ramanujan)",
                          "marginals: normal with the table's mean and Sheppard-corrected sd; "
                          "joint: Gaussian copula with the table's correlation matrix"))


def from_csv(path: str | Path) -> Population:
    """A user's measured fingers: a CSV with columns ``width`` and ``depth`` (mm), optionally
    ``length`` and ``perimeter`` (a measured girth at the strap; else the ellipse). It
    replaces the table and the depth assumption."""
    path = Path(path)
    try:
        with path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
    except (OSError, UnicodeDecodeError, csv.Error) as exc:
        raise DataError(f"--fingers-csv={str(path)!r}: not a readable CSV ({exc})") from None
    cols = set(rows[0]) if rows else set()
    missing = [c for c in CSV_REQUIRED if c not in cols]
    if missing:
        raise DataError(f"--fingers-csv={str(path)!r}: missing column(s) "
                        f"{', '.join(missing)}; needed: {', '.join(CSV_REQUIRED)} (mm), "
                        f"optional: {', '.join(CSV_OPTIONAL)}")
    if len(rows) < 5:
        raise DataError(f"--fingers-csv={str(path)!r}: {len(rows)} rows; at least 5 fingers")

    def col(name, default=None):
        try:
            return np.array([float(r[name]) if r.get(name) not in (None, "") else default
                             for r in rows], float)
        except ValueError:
            raise DataError(f"--fingers-csv={str(path)!r}: column {name} holds a value that "
                            "is not a number") from None

    w, d = col("width"), col("depth")
    _check_sizes(w, d, "--fingers-csv")
    ln = col("length", ASSUMED_LENGTH_MM) if "length" in cols else np.full(len(w),
                                                                            ASSUMED_LENGTH_MM)
    ell = np.array([ellipse_perimeter(a / 2, b / 2) for a, b in zip(w, d)])
    per = col("perimeter", np.nan) if "perimeter" in cols else ell
    per = np.where(np.isfinite(per), per, ell)
    lo, hi = SECTION_PERIMETER_RATIO
    bad = (per < lo * ell) | (per > hi * ell)
    if bad.any():
        k = int(np.flatnonzero(bad)[0])
        raise DataError(f"--fingers-csv={str(path)!r}: perimeter={per[k]:g} on row {k + 1} is "
                        f"not allowed: {lo * ell[k]:.4g}-{hi * ell[k]:.4g} mm ({lo:g}-{hi:g} x "
                        "the ellipse of its width and depth: a fingertip-like section)")
    assumptions = ["measured per person (the user's CSV)"]
    if "perimeter" not in cols:
        assumptions.append("perimeter = ellipse of width and depth (Ramanujan)")
    if "length" not in cols:
        assumptions.append(f"ASSUMED distal phalanx length {ASSUMED_LENGTH_MM:g} mm")
    return Population(w, d, ln, per, source=f"user CSV {path.name}", group="csv",
                      assumptions=tuple(assumptions))


def fit_check(group: str = "all", n: int = 20000, seed: int = 0,
              table: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """How the drawn measures reproduce the table: per measure and percentile, the share of
    draws (rounded to whole mm, as the survey read them) below and at the table's value (the
    table's percentile lies between them when the model fits); and the correlations."""
    table = table or load_table()
    vals, _, order = draw_measures(group, n, seed, table)
    gd = table["groups"][group]
    rows = []
    rounded = np.round(vals)
    for j, m in enumerate(order):
        for p in PERCENTILES:
            v = gd[m][f"p{p}"]
            rows.append({"measure": m, "percentile": p, "table_mm": v,
                         "share_below": float(np.mean(rounded[:, j] < round(v))),
                         "share_at_or_below": float(np.mean(rounded[:, j] <= round(v)))})
    C = np.corrcoef(vals, rowvar=False)
    T = np.asarray(gd["correlation"]["matrix"], float)
    for i in range(len(order)):
        for j in range(i + 1, len(order)):
            rows.append({"measure": f"{order[i]} x {order[j]}", "correlation_table": T[i, j],
                         "correlation_drawn": float(C[i, j])})
    return rows
