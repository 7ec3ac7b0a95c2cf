"""Measured data in: a dataset card (TOML) -> a clean, resampled :class:`Dataset`.

The card says what each file holds::

    [[files]]                      # one or more; role = "train" | "validate" (optional)
    path = "run1.csv"              # CSV (header row, or columns = [..]) or Parquet
    columns = ["Ro", "Ri", "tR"]   # names when the CSV has no header row (may be set at top level)
    sign = { P = -1 }              # per-file sign override, by channel or column name
    [time]
    column = "t"                   # or one clock per channel: column = { F = "tF", P = "tP" }
    unit = "s"
    [inputs]                       # what was applied or known
    displacement = { column = "P", unit = "mm", sign = "auto" }
    [outputs]                      # what the sensor reported
    resistance = { column = "Ri", unit = "ohm" }
    [split]
    train = 0.6                    # fraction of each run's time used for training (no roles given)
    [repair]                       # defaults shown
    dropouts = true                # isolated runs of exact zeros -> interpolated
    spikes = true                  # isolated samples > spike_k MADs from a running median
    spike_k = 8.0
    spike_floor = 0.15             # ... and by more than this fraction of the 1-99 % range
    window = 7
    max_run = 3
    [preprocess]                   # seed 000: bias over the first second, 10 Hz low-pass, resample
    rate = 10.0                    # Hz, the common clock (default: median rate of the data)
    skip_s = 0.0                   # drop each run's first N s (e.g. a first-loading ramp; counted)
    bias_seconds = 1.0             # subtract the mean over the first N s of each run
    bias_channels = ["force"]      # default: every output
    lowpass_hz = 10.0              # 4th-order Butterworth, zero phase (sosfiltfilt)

Each channel's unit is converted to the canonical unit of its quantity (mm, N, ohm, V, s, C, g,
deg, MPa, 1, A); the quantity comes from ``quantity = ..`` or the channel's name, else from the
unit. Nothing is dropped silently: every repaired sample, flipped sign and trimmed edge is
counted in :attr:`Dataset.report`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from designlab.errors import DataError
from designlab.measured.card import (
    CANONICAL,
    Card,
    check_card,
    data_path,
    parse_card,
    quantity_of,
)
from designlab.params import load_toml

#: largest magnitude of a data value (no sensor reads 1e20 in any unit of UNITS): at 1e99,
#: the product of two sums of squares (a correlation) already overflows float64
MAX_ABS_VALUE = 1e20
#: smallest spread (max - min) of a column that varies: below it the products of squares a fit
#: forms (a variance, a correlation's product of two variances) underflow to 0 in float64 and
#: the column looks constant, or gives NaN, to every fit
MIN_SPREAD = 1e-60

MAX_FILE_BYTES = 2 * 1024 ** 3     # one data file
MIN_TIME_STEP_S = 1e-9             # smallest step of a time column (a 1 GHz clock)
MIN_SPLIT_SAMPLES = 10             # fewest samples a [split] fraction leaves to each part
MAX_SAMPLES = 20_000_000           # samples of one run on the common clock (rate x duration)
#: samples of all a card's runs together on the common clock: the loop's memory budget (the
#: fits are decimated to 50 000 samples, but the record is held whole; 2 000 000 samples of a
#: two-channel card peak at 885 MB: benchmarks/bench_loop_memory.py)
MAX_CARD_SAMPLES = 2_000_000


# --------------------------------------------------------------------------- reading


def read_table(path: Path, columns: list[str] | None = None, header: bool | None = None
               ) -> dict[str, np.ndarray]:
    """Columns of a CSV or Parquet file as float arrays (missing cells -> NaN)."""
    import pyarrow as pa
    import pyarrow.csv as pcsv

    if not path.is_file():
        raise DataError(f"{path}: file not found")
    size = path.stat().st_size
    if size > MAX_FILE_BYTES:
        raise DataError(f"{path}: {size} bytes; at most {MAX_FILE_BYTES} bytes per data file")
    if path.suffix.lower() in (".parquet", ".pq"):
        import pyarrow.parquet as pq
        try:
            table = pq.read_table(path)
        except (pa.ArrowException, OSError):  # the reason may quote the file: not shown
            raise DataError(f"{path}: not a readable Parquet file") from None
    else:
        if header is None:
            header = columns is None
        if not header and columns is None:
            raise DataError(f"{path}: no header row; name the columns with columns = [...]")
        read = pcsv.ReadOptions(column_names=list(columns) if not header else None,
                                autogenerate_column_names=False)
        conv = pcsv.ConvertOptions(strings_can_be_null=True,
                                   null_values=["", "nan", "NaN", "NA", "null"])
        try:
            table = pcsv.read_csv(path, read_options=read, convert_options=conv)
        except (pa.ArrowException, OSError, UnicodeDecodeError) as exc:
            # arrow's message quotes the offending row: keep only its shape, never the text
            import re

            m = re.search(r"Expected \d+ columns, got \d+", str(exc))
            why = m.group(0) if m else ("not UTF-8 text" if "UTF8" in str(exc).replace("-", "")
                                        else "not a CSV table")
            raise DataError(f"{path}: cannot parse as CSV ({why})") from None
        if header and columns is not None:
            if len(columns) != table.num_columns:
                raise DataError(f"{path}: columns = {columns} names {len(columns)} columns but "
                                f"the file has {table.num_columns}")
            table = table.rename_columns(list(columns))
    try:
        names = [str(n) for n in table.column_names]
    except UnicodeDecodeError:   # a header in another encoding (latin-1): arrow reads it lazily
        raise DataError(f"{path}: cannot parse as CSV (the header row is not UTF-8 text; save "
                        "the file as UTF-8)") from None
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(f"{path}: column name(s) {', '.join(map(repr, dup))} appear more than "
                        "once; name the columns with columns = [...]")
    out = {}
    for name in names:
        col = table.column(name)
        try:
            arr = col.cast(pa.float64()).to_numpy(zero_copy_only=False)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            arr = None  # non-numeric: only an error if a declared channel uses it
        out[str(name)] = np.asarray(arr, float) if arr is not None else col.to_pylist()
    return out


def _numeric(data: dict, col: str, path: Path, spread: bool = True) -> np.ndarray:
    """Column ``col`` as finite floats of at most :data:`MAX_ABS_VALUE`, varying by 0 or at
    least :data:`MIN_SPREAD` (``spread``; a time column's steps are checked instead)."""
    if col not in data:
        import re

        names = [str(n) for n in data]
        # list the header only when it looks like column names (never quote other text)
        plain = len(names) <= 50 and all(re.fullmatch(r"[A-Za-z_][\w .()/%\[\]-]{0,40}", n)
                                         for n in names)
        has = f"the file has {', '.join(names)}" if plain else \
            f"the file's first row holds no such name ({len(names)} column(s))"
        raise DataError(f"{path}: column '{col}' not found; {has}")
    arr = data[col]
    if not isinstance(arr, np.ndarray):
        raise DataError(f"{path}: column '{col}' is not numeric")
    bad = np.flatnonzero(~np.isfinite(arr))
    if bad.size:
        what = "NaN/missing" if np.isnan(arr[bad[0]]) else "infinite"
        raise DataError(f"{path}: column '{col}' has {bad.size} NaN/missing or infinite "
                        f"value(s), first ({what}) at data row {bad[0] + 1}")
    huge = np.flatnonzero(np.abs(arr) > MAX_ABS_VALUE)
    if huge.size:  # squares and sums of such values overflow: inf/NaN results, not an error
        raise DataError(f"{path}: column '{col}' has {huge.size} value(s) beyond "
                        f"+-{MAX_ABS_VALUE:g}, first at data row {huge[0] + 1}; allowed: "
                        f"|value| <= {MAX_ABS_VALUE:g} (a sensor reading in its card's unit)")
    width = float(np.ptp(arr)) if arr.size and spread else 0.0
    if 0 < width < MIN_SPREAD:
        raise DataError(f"{path}: column '{col}' varies by {width:.3g} only (largest |value| "
                        f"{float(np.max(np.abs(arr))):.3g}); allowed: a spread of 0 (constant) "
                        f"or >= {MIN_SPREAD:g}: a smaller one is below the precision a fit "
                        "needs (its squares underflow to 0; is the unit right?)")
    return arr


# --------------------------------------------------------------------------- repair


def _runs(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    d = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return np.flatnonzero(d == 1), np.flatnonzero(d == -1)


def find_dropouts(x: np.ndarray, max_run: int = 3, tol: float | None = None) -> np.ndarray:
    """Mask of isolated runs (<= ``max_run`` samples) of exact zeros inside a signal whose both
    neighbours are clearly non-zero (``|x| > tol``, default 2 % of the robust range)."""
    x = np.asarray(x, float)
    if tol is None:
        lo, hi = np.percentile(x, [1, 99])
        tol = 0.02 * max(hi - lo, 1e-300)
    mask = np.zeros(x.size, bool)
    st, en = _runs(x == 0.0)
    for s, e in zip(st, en):
        if e - s <= max_run and s > 0 and e < x.size and abs(x[s - 1]) > tol and abs(x[e]) > tol:
            mask[s:e] = True
    return mask


def find_spikes(x: np.ndarray, k: float = 8.0, window: int = 7, max_run: int = 3,
                exclude: np.ndarray | None = None, floor: float = 0.15) -> np.ndarray:
    """Mask of isolated samples deviating from a running median of ``window`` samples by more
    than ``k`` robust standard deviations (1.4826 MAD) and by more than ``floor`` times the
    robust (1-99 %) range; runs longer than ``max_run`` are kept as real features.

    The floor keeps sharp but real turns of a fast signal sampled slowly (whose median
    deviation is often exactly 0) from being taken for spikes."""
    from scipy import ndimage  # scipy.ndimage/signal cost ~0.5 s: imported where used

    x = np.asarray(x, float)
    if x.size < window:
        return np.zeros(x.size, bool)
    med = ndimage.median_filter(x, size=window, mode="nearest")
    dev = x - med
    ok = dev if exclude is None else dev[~exclude]
    lo, hi = np.percentile(x, [1, 99])
    scale = 1.4826 * np.median(np.abs(ok - np.median(ok)))
    flag = np.abs(dev) > max(k * scale, floor * (hi - lo), 1e-300)
    if exclude is not None:
        flag &= ~exclude
    st, en = _runs(flag)
    for s, e in zip(st, en):
        if e - s > max_run:
            flag[s:e] = False
    return flag


def interpolate_over(t: np.ndarray, x: np.ndarray, bad: np.ndarray) -> np.ndarray:
    """Replace samples under ``bad`` by linear interpolation in time from the good ones."""
    if not bad.any():
        return x
    good = ~bad
    y = x.copy()
    y[bad] = np.interp(t[bad], t[good], x[good])
    return y


# --------------------------------------------------------------------------- preprocessing


#: lowest low-pass cut-off over the sample rate (a Butterworth filter below 1e-10 of the rate is
#: singular; below 1e-6 it is already a mean of the run)
MIN_LOWPASS_FRACTION = 1e-6


def lowpass(x: np.ndarray, rate: float, cutoff: float, order: int = 4) -> np.ndarray:
    """Zero-phase Butterworth low-pass (``sosfiltfilt``) of ``x`` sampled at ``rate`` Hz."""
    from scipy import signal

    sos = signal.butter(order, cutoff, btype="low", fs=rate, output="sos")
    padlen = min(3 * (2 * len(sos) + 1), x.size - 1)
    return signal.sosfiltfilt(sos, x, padlen=max(padlen, 0))


# --------------------------------------------------------------------------- the dataset


@dataclass(frozen=True)
class Dataset:
    """Measured data on a uniform clock per run (segment).

    ``t`` (s) is each run's own time; ``inputs``/``outputs`` map channel names to arrays in
    canonical units (:attr:`units`); ``segment`` gives each sample's run index into
    :attr:`segments` (dicts with ``path`` and ``role``); ``role`` is each sample's
    ``"train"``/``"validate"``; :attr:`report` is the provenance (repairs, signs, units,
    resampling, filters).
    """

    t: np.ndarray
    inputs: Mapping[str, np.ndarray]
    outputs: Mapping[str, np.ndarray]
    segment: np.ndarray
    role: np.ndarray
    segments: tuple = ()
    units: Mapping[str, str] = field(default_factory=dict)
    quantities: Mapping[str, str] = field(default_factory=dict)
    kinds: Mapping[str, str] = field(default_factory=dict)
    report: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        n = self.t.size
        for name, arr in {**self.inputs, **self.outputs}.items():
            if arr.shape != (n,):
                raise DataError(f"channel '{name}' has {arr.shape} samples, expected ({n},)")
        if self.segment.shape != (n,) or self.role.shape != (n,):
            raise DataError("segment and role need one entry per sample")

    def __len__(self) -> int:
        return int(self.t.size)

    @property
    def dt(self) -> float:
        """Sample period (s): the median step within runs."""
        d = np.diff(self.t)[np.diff(self.segment) == 0]
        return float(np.median(d)) if d.size else 1.0

    def time_in_run(self) -> np.ndarray:
        """Time since the start of each sample's run (s), also in a subset of the run."""
        out = np.empty_like(self.t)
        for s in np.unique(self.segment):
            m = self.segment == s
            info = self.segments[s] if s < len(self.segments) else {}
            out[m] = self.t[m] - info.get("t_start", self.t[m][0])
        return out

    def select(self, mask: np.ndarray) -> "Dataset":
        """The samples under ``mask`` (a boolean array), keeping run ids."""
        mask = np.asarray(mask, bool)
        return replace(self, t=self.t[mask], inputs={k: v[mask] for k, v in self.inputs.items()},
                       outputs={k: v[mask] for k, v in self.outputs.items()},
                       segment=self.segment[mask], role=self.role[mask])

    def train(self) -> "Dataset":
        """The training samples."""
        return self.select(self.role == "train")

    def validate(self) -> "Dataset":
        """The validation samples."""
        return self.select(self.role == "validate")

    def split(self, fraction: float | None = None) -> tuple["Dataset", "Dataset"]:
        """(train, validate): by roles, or by ``fraction`` of each run's time when given."""
        if fraction is None:
            return self.train(), self.validate()
        if not 0 < fraction < 1:
            raise DataError(f"split fraction={fraction!r} is not allowed: 0 < fraction < 1")
        role = np.where(self.time_in_run() <= fraction * self._run_duration(), "train",
                        "validate")
        ds = replace(self, role=role)
        return ds.train(), ds.validate()

    def _run_duration(self) -> np.ndarray:
        dur = np.empty_like(self.t)
        tr = self.time_in_run()
        for s in np.unique(self.segment):
            m = self.segment == s
            dur[m] = tr[m][-1]
        return dur

    def channel(self, name: str) -> np.ndarray:
        """An input or output by name."""
        if name in self.inputs:
            return self.inputs[name]
        if name in self.outputs:
            return self.outputs[name]
        raise DataError(f"channel '{name}' not in the dataset; it has "
                        f"{', '.join([*self.inputs, *self.outputs])}")


def _resample(tt: np.ndarray, x: np.ndarray, grid: np.ndarray, rate_in: float,
              rate_out: float) -> np.ndarray:
    if rate_out < 0.8 * rate_in:  # anti-alias before decimating
        x = lowpass(x, rate_in, 0.4 * rate_out)
    return np.interp(grid, tt, x)


def load_card(path: str | Path, allow_outside: bool = False) -> Dataset:
    """Read a dataset card and every file it names into one :class:`Dataset`.

    The card is checked whole first (:func:`~designlab.measured.card.check_card`); its files
    must lie in its folder unless it says ``allow_outside_paths = true`` (or ``allow_outside``).

    Args:
        path: the card (TOML).
        allow_outside: read files outside the card's folder too.

    Returns:
        The runs on one common clock, in canonical units, with :attr:`Dataset.report`. Bad
        input is a one-line :class:`DataError`.
    """
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: dataset card not found")
    card = load_toml(path, "--data")
    check_card(card, str(path))
    spec = parse_card(card, path, allow_outside)
    raw = [_read_file(path, spec, i, f) for i, f in enumerate(spec.files)]
    rate = float(spec.preprocess.get("rate", float(np.median([r["rate"] for r in raw]))))
    if not rate > 0:
        raise DataError(f"{path}: [preprocess] rate={rate!r} is not allowed: > 0 Hz")
    roles_given = any(r["role"] for r in raw)
    frac = spec.split.get("train", None if roles_given else 0.6)
    if frac is not None and not 0 < float(frac) < 1:
        raise DataError(f"{path}: [split] train={frac!r} is not allowed: 0 < train < 1")
    runs = _resample_runs(raw, spec, rate, roles_given, frac)
    if not roles_given:   # a fraction near 0 or 1 leaves a part too few samples to judge on
        held = {r: sum(int(np.sum(run["role"] == r)) for run in runs)
                for r in ("train", "validate")}
        if min(held.values()) < MIN_SPLIT_SAMPLES:
            raise DataError(f"{path}: [split] train={frac!r} is not allowed: a fraction leaving "
                            f"at least {MIN_SPLIT_SAMPLES} samples to training and to validation "
                            f"(it leaves {held['train']} and {held['validate']})")
    return _assemble(path, spec, runs, rate, roles_given, frac)


def _read_file(path: Path, spec: Card, i: int, f: Mapping) -> dict:
    """One [[files]] entry read, converted and repaired on its own clocks, with its role."""
    if "path" not in f:
        raise DataError(f"{path}: [[files]] entry {i + 1} has no path")
    fpath = data_path(path, f["path"], spec.allow_outside)
    role = f.get("role")
    if role not in (None, "train", "validate"):
        raise DataError(f"{path}: file {f['path']} role={role!r} is not allowed: "
                        "\"train\" or \"validate\"")
    data = read_table(fpath, f.get("columns", spec.columns), f.get("header"))
    out = _prepare_file(fpath, data, spec.channels, spec.t_scale, spec.repair, f.get("sign", {}))
    out["role"] = role
    return out


def _resample_runs(raw: list[dict], spec: Card, rate: float, roles_given: bool,
                   frac: float | None) -> list[dict]:
    """Every run on the common clock (``rate`` Hz), within the per-run and per-card budgets."""
    runs, total = [], 0
    for k, r in enumerate(raw):
        t0, t1 = _skip_start(r, float(spec.preprocess.get("skip_s", 0.0)))
        n_f = math.floor((t1 - t0) * rate + 1e-9) + 1
        if n_f > MAX_SAMPLES:
            raise DataError(f"{r['path']}: {n_f:.3g} samples at {rate:g} Hz over "
                            f"{t1 - t0:.3g} s; at most {MAX_SAMPLES} per run (lower "
                            "[preprocess] rate)")
        n = int(n_f)
        total += n
        if total > MAX_CARD_SAMPLES:
            raise DataError(f"{r['path']}: the card's runs hold {total} samples at {rate:g} "
                            f"Hz so far; at most {MAX_CARD_SAMPLES} in all (the loop's memory "
                            "budget: lower [preprocess] rate or split the card)")
        if n < 4:
            raise DataError(f"{r['path']}: the channels' clocks overlap for only "
                            f"{max(t1 - t0, 0):.3g} s; nothing to resample")
        runs.append(_run_on_clock(k, r, t0, n, rate, spec, roles_given, frac))
    return runs


def _skip_start(r: dict, skip: float) -> tuple[float, float]:
    """The run's overlap of all clocks, its first ``skip`` s dropped (counted per channel)."""
    t0, t1 = r["t_start"], r["t_end"]
    if skip:
        for name, (tt, _) in r["series"].items():
            r["report"]["trimmed"][name]["skipped_start"] = int(np.sum(
                (tt >= t0) & (tt < t0 + skip)))
        t0 = t0 + skip
    return t0, t1


def _run_on_clock(k: int, r: dict, t0: float, n: int, rate: float, spec: Card,
                  roles_given: bool, frac: float | None) -> dict:
    """Run ``k`` resampled to ``n`` samples from ``t0``, filtered, with each sample's role."""
    grid = t0 + np.arange(n) / rate
    values = {}
    for name, (tt, x) in r["series"].items():
        values[name] = _resample(tt, x, grid, r["rate"], rate)
    filt = _preprocess(values, spec.channels, grid, rate, spec.preprocess, r)
    role = r["role"] or ("train" if roles_given else None)
    if role is None:
        rr = np.where(grid - grid[0] <= float(frac) * (grid[-1] - grid[0]), "train",
                      "validate")
    else:
        rr = np.full(n, role)
    r["report"]["resampled"] = {"rate_hz": rate, "samples": n, "t_start": float(t0),
                                "t_end": float(grid[-1])}
    return {"t": grid, "segment": np.full(n, k), "role": rr,
            "values": {name: filt[name] for name in spec.channels},
            "info": {"path": str(r["path"]), "role": role or f"split {frac}",
                     "t_start": float(grid[0])},
            "report": r["report"]}


def _assemble(path: Path, spec: Card, runs: list[dict], rate: float, roles_given: bool,
              frac: float | None) -> Dataset:
    """The runs concatenated into one :class:`Dataset` with its provenance report."""
    channels = spec.channels
    cat = {n: np.concatenate([run["values"][n] for run in runs]) for n in channels}
    return Dataset(
        t=np.concatenate([run["t"] for run in runs]),
        segment=np.concatenate([run["segment"] for run in runs]),
        role=np.concatenate([run["role"] for run in runs]),
        inputs={n: cat[n] for n, (g, _) in channels.items() if g == "inputs"},
        outputs={n: cat[n] for n, (g, _) in channels.items() if g == "outputs"},
        segments=tuple(run["info"] for run in runs),
        units={n: c.canonical_unit for n, (_, c) in channels.items()},
        quantities={n: c.quantity for n, (_, c) in channels.items()},
        kinds={n: c.kind for n, (_, c) in channels.items()},
        report=_card_report(path, spec, [run["report"] for run in runs], rate, roles_given,
                            frac))


def _card_report(path: Path, spec: Card, file_reports: list[dict], rate: float,
                 roles_given: bool, frac: float | None) -> dict:
    """:attr:`Dataset.report` of a card: its files' reports, clock, split, filters, repairs."""
    return {
        "card": str(path),
        "files": file_reports,
        "rate_hz": rate,
        "split": ("roles" if roles_given else {"train_fraction": float(frac)}),
        "preprocess": {k: v for k, v in spec.preprocess.items()},
        "repair": spec.repair,
        "repaired_total": {n: int(sum(fr["repaired"].get(n, {}).get("total", 0)
                                      for fr in file_reports)) for n in spec.channels},
    }


def _prepare_file(fpath: Path, data: dict, channels: dict, t_scale: float, rep: dict,
                  sign_over: Mapping) -> dict:
    """Check, convert, sign-correct and repair one file's channels on their own clocks."""
    series, report = {}, {"path": str(fpath), "rows": None, "repaired": {}, "signs": {},
                           "units": {}, "trimmed": {}}
    clocks = {}
    for name, (_, ch) in channels.items():
        tcol = ch.time_column
        if tcol not in clocks:
            tt = _numeric(data, tcol, fpath, spread=False) * t_scale
            d = np.diff(tt)
            bad = np.flatnonzero(d <= 0)
            if bad.size:
                raise DataError(f"{fpath}: time column '{tcol}' is not strictly increasing "
                                f"({bad.size} step(s), first at data row {bad[0] + 2})")
            if tt.size < 4:
                raise DataError(f"{fpath}: time column '{tcol}' has only {tt.size} samples")
            if d.min() < MIN_TIME_STEP_S:   # 1 / step overflows: no sample rate
                raise DataError(f"{fpath}: time column '{tcol}' has a step of {d.min():.3g} s "
                                f"at data row {int(np.argmin(d)) + 2}; allowed: steps >= "
                                f"{MIN_TIME_STEP_S:g} s (is the time unit right?)")
            clocks[tcol] = tt
        tt = clocks[tcol]
        x = _numeric(data, ch.column, fpath)
        report["rows"] = int(x.size)
        x = x * ch.scale + ch.offset
        report["units"][name] = {"column": ch.column, "from": ch.unit, "to": ch.canonical_unit}
        # repairs first (a dropout to 0 must not flip the median), counted per column
        fixed = {"dropouts": 0, "spikes": 0}
        bad = np.zeros(x.size, bool)
        if rep.get("dropouts", True):
            drop = find_dropouts(x, int(rep.get("max_run", 3)))
            fixed["dropouts"] = int(drop.sum())
            bad |= drop
        if rep.get("spikes", True):
            sp = find_spikes(x, float(rep.get("spike_k", 8.0)), int(rep.get("window", 7)),
                             int(rep.get("max_run", 3)), exclude=bad,
                             floor=float(rep.get("spike_floor", 0.15)))
            fixed["spikes"] = int(sp.sum())
            bad |= sp
        x = interpolate_over(tt, x, bad)
        fixed["total"] = int(bad.sum())
        fixed["fraction"] = float(bad.mean())
        report["repaired"][name] = fixed
        sign = sign_over.get(name, sign_over.get(ch.column, ch.sign))
        if sign == "auto":
            s = -1.0 if np.median(x) < 0 else 1.0
            mode = "auto"
        elif sign in (1, -1):
            s, mode = float(sign), "declared"
        else:
            raise DataError(f"{fpath}: sign={sign!r} for '{name}' is not allowed: 1, -1 or "
                            "\"auto\"")
        report["signs"][name] = {"sign": int(s), "mode": mode}
        series[name] = (tt, s * x)
    t_start = max(tt[0] for tt, _ in series.values())
    t_end = min(tt[-1] for tt, _ in series.values())
    for name, (tt, _) in series.items():
        report["trimmed"][name] = {"before": int(np.sum(tt < t_start)),
                                   "after": int(np.sum(tt > t_end))}
    steps = np.concatenate([np.diff(tt) for tt in clocks.values()])
    return {"path": fpath, "series": series, "t_start": float(t_start), "t_end": float(t_end),
            "rate": float(1.0 / np.median(steps)), "report": report}


def _preprocess(values: dict, channels: dict, grid: np.ndarray, rate: float, pre: Mapping,
                r: dict) -> dict:
    """Low-pass and bias removal of one run on the common clock, recorded in the report."""
    out = dict(values)
    notes = {}
    cutoff = pre.get("lowpass_hz")
    if cutoff is not None:
        if cutoff < MIN_LOWPASS_FRACTION * rate:   # the filter's matrices turn singular
            raise DataError(f"{r['path']}: preprocess.lowpass_hz={cutoff!r} is not allowed: >= "
                            f"{MIN_LOWPASS_FRACTION:g} x the sample rate ({rate:.6g} Hz), or "
                            "no lowpass_hz")
        if cutoff >= rate / 2:
            notes["lowpass"] = (f"skipped: {cutoff} Hz is not below the Nyquist frequency "
                                f"{rate / 2:g} Hz")
        else:
            order = int(pre.get("filter_order", 4))
            for name in out:
                out[name] = lowpass(out[name], rate, float(cutoff), order)
            notes["lowpass"] = f"butterworth order {order}, {cutoff} Hz, zero phase"
    secs = pre.get("bias_seconds")
    if secs is not None:
        names = pre.get("bias_channels",
                        [n for n, (g, _) in channels.items() if g == "outputs"])
        m = grid - grid[0] <= float(secs)
        bias = {}
        for name in names:
            if name not in out:
                raise DataError(f"[preprocess] bias_channels names '{name}', not a channel; "
                                f"allowed: {', '.join(out)}")
            b = float(np.mean(out[name][m]))
            out[name] = out[name] - b
            bias[name] = b
        notes["bias"] = {"seconds": float(secs), "subtracted": bias}
    r["report"]["preprocess"] = notes
    return out


def from_arrays(t: np.ndarray, inputs: Mapping[str, np.ndarray],
                outputs: Mapping[str, np.ndarray], *, segment: np.ndarray | None = None,
                role: np.ndarray | None = None, units: Mapping[str, str] | None = None,
                quantities: Mapping[str, str] | None = None,
                kinds: Mapping[str, str] | None = None) -> Dataset:
    """A :class:`Dataset` from arrays already in canonical units (synthetic data, tests).
    Quantities and kinds default from the channel names."""
    t = np.asarray(t, float)
    seg = np.zeros(t.size, int) if segment is None else np.asarray(segment, int)
    rl = np.full(t.size, "train") if role is None else np.asarray(role)
    q, k = dict(quantities or {}), dict(kinds or {})
    for name in [*inputs, *outputs]:
        if name not in q or name not in k:
            qq, kk = quantity_of(name, {"quantity": q.get(name), "kind": k.get(name),
                                         "unit": (units or {}).get(name)}, "arrays")
            q.setdefault(name, qq)
            k.setdefault(name, kk)
    u = {n: (units or {}).get(n, CANONICAL[q[n]]) for n in q}
    segs = tuple({"path": f"segment {s}", "role": str(rl[seg == s][0]),
                  "t_start": float(t[seg == s][0])} for s in range(int(seg.max()) + 1))
    return Dataset(t=t, inputs={n: np.asarray(v, float) for n, v in inputs.items()},
                   outputs={n: np.asarray(v, float) for n, v in outputs.items()},
                   segment=seg, role=rl, segments=segs, units=u, quantities=q, kinds=k,
                   report={"source": "arrays"})
