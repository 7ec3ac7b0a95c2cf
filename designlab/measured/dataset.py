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
from designlab.params import load_toml

#: largest magnitude of a data value (no sensor reads 1e20 in any unit of UNITS): at 1e99,
#: the product of two sums of squares (a correlation) already overflows float64
MAX_ABS_VALUE = 1e20

# canonical unit first; factor to canonical (temperature: (scale, offset))
UNITS: dict[str, dict[str, float | tuple[float, float]]] = {
    "length": {"mm": 1.0, "m": 1e3, "cm": 10.0, "um": 1e-3, "in": 25.4},
    "force": {"N": 1.0, "kN": 1e3, "mN": 1e-3},
    "resistance": {"ohm": 1.0, "kohm": 1e3, "Mohm": 1e6, "mohm": 1e-3},
    "voltage": {"V": 1.0, "mV": 1e-3, "uV": 1e-6},
    "current": {"A": 1.0, "mA": 1e-3, "uA": 1e-6},
    "time": {"s": 1.0, "ms": 1e-3, "us": 1e-6, "min": 60.0},
    "temperature": {"C": (1.0, 0.0), "K": (1.0, -273.15)},
    "mass": {"g": 1.0, "kg": 1e3, "mg": 1e-3},
    "angle": {"deg": 1.0, "rad": 180.0 / math.pi},
    "pressure": {"MPa": 1.0, "kPa": 1e-3, "Pa": 1e-6},
    "strain": {"1": 1.0, "%": 1e-2},
    "torque": {"Nmm": 1.0, "Nm": 1e3},
}
CANONICAL = {q: next(iter(u)) for q, u in UNITS.items()}
ELECTRICAL = ("resistance", "voltage", "current")

# channel-name stem -> (quantity, kind); kind says what an input does physically
NAME_QUANTITY: dict[str, tuple[str, str]] = {
    "displacement": ("length", "drive"), "elongation": ("length", "drive"),
    "extension": ("length", "drive"), "deflection": ("length", "drive"),
    "position": ("length", "drive"), "indentation": ("length", "drive"),
    "location": ("length", "location"), "arm": ("length", "location"),
    "force": ("force", "drive"), "load": ("force", "drive"),
    "resistance": ("resistance", "drive"), "voltage": ("voltage", "drive"),
    "current": ("current", "drive"), "temperature": ("temperature", "temperature"),
    "weight": ("mass", "drive"), "mass": ("mass", "drive"), "angle": ("angle", "drive"),
    "pressure": ("pressure", "drive"), "strain": ("strain", "drive"),
    "torque": ("torque", "drive"), "time": ("time", "drive"),
}
KINDS = ("drive", "location", "temperature")


@dataclass(frozen=True)
class Channel:
    """One declared channel of the card (an input or an output)."""

    name: str
    column: str
    unit: str
    quantity: str
    kind: str = "drive"
    sign: float | str = 1.0
    time_column: str | None = None
    scale: float = 1.0
    offset: float = 0.0

    @property
    def canonical_unit(self) -> str:
        return CANONICAL[self.quantity]


def _quantity_of(name: str, spec: Mapping[str, Any], where: str) -> tuple[str, str]:
    unit = spec.get("unit")
    q = spec.get("quantity")
    kind = spec.get("kind")
    stem = name.lower().split("_")[0].rstrip("0123456789")
    by_name = NAME_QUANTITY.get(stem)
    if q is None and by_name is not None:
        q = by_name[0]
    if q is None:  # unknown name: the unit decides
        owners = [qq for qq, table in UNITS.items() if unit in table]
        if len(owners) != 1:
            raise DataError(f"{where}: cannot tell the quantity of channel '{name}' from unit "
                            f"{unit!r}; set quantity = one of {', '.join(UNITS)}")
        q = owners[0]
    if q not in UNITS:
        raise DataError(f"{where}: channel '{name}' quantity={q!r} is not allowed: one of "
                        f"{', '.join(UNITS)}")
    if kind is None:
        kind = by_name[1] if by_name is not None and by_name[0] == q else (
            "temperature" if q == "temperature" else "drive")
    if kind not in KINDS:
        raise DataError(f"{where}: channel '{name}' kind={kind!r} is not allowed: one of "
                        f"{', '.join(KINDS)}")
    return q, kind


def make_channel(name: str, spec: Any, where: str, time_spec: Any) -> Channel:
    """A :class:`Channel` from its card entry; bad units raise a one-line DataError."""
    if isinstance(spec, str):
        spec = {"column": spec}
    if not isinstance(spec, Mapping) or "column" not in spec:
        raise DataError(f"{where}: channel '{name}' needs a column, e.g. "
                        f"{name} = {{ column = \"C\", unit = \"...\" }}")
    q, kind = _quantity_of(name, spec, where)
    unit = spec.get("unit", CANONICAL[q])
    table = UNITS[q]
    if unit not in table:
        raise DataError(f"{where}: column '{spec['column']}' ({name}) has unit {unit!r}, "
                        f"not a {q} unit; allowed: {', '.join(table)}")
    factor = table[unit]
    scale, offset = factor if isinstance(factor, tuple) else (factor, 0.0)
    sign = spec.get("sign", 1)
    if not (sign == "auto" or sign in (1, -1)):
        raise DataError(f"{where}: channel '{name}' sign={sign!r} is not allowed: 1, -1 or \"auto\"")
    tcol = None
    if isinstance(time_spec, str):
        tcol = time_spec
    elif isinstance(time_spec, Mapping):
        tcol = time_spec.get(spec["column"], time_spec.get(name))
        if tcol is None:
            raise DataError(f"{where}: [time] column gives no clock for column "
                            f"'{spec['column']}' ({name}); add {spec['column']} = \"t...\"")
    return Channel(name=name, column=str(spec["column"]), unit=unit, quantity=q, kind=kind,
                   sign=sign if sign == "auto" else float(sign), time_column=tcol,
                   scale=float(scale), offset=float(offset))


MAX_FILE_BYTES = 2 * 1024 ** 3     # one data file
MAX_SAMPLES = 20_000_000           # samples of one run on the common clock (rate x duration)
#: samples of all a card's runs together on the common clock: the loop's memory budget (the
#: fits are decimated to 50 000 samples, but the record is held whole; 2 000 000 samples of a
#: two-channel card peak at 885 MB: benchmarks/bench_loop_memory.py)
MAX_CARD_SAMPLES = 2_000_000
MAX_RATE_HZ = 100_000.0

_CARD_KEYS = ("files", "columns", "time", "inputs", "outputs", "split", "repair", "preprocess",
              "allow_outside_paths")
_FILE_KEYS = ("path", "role", "columns", "header", "sign")
_CHANNEL_KEYS = ("column", "unit", "quantity", "kind", "sign")
# key -> (type, lo, hi, lo_open): the numbers a card may hold, and where
_REPAIR = {"dropouts": (bool,), "spikes": (bool,), "spike_k": (float, 0.0, 1e6, True),
           "spike_floor": (float, 0.0, 1.0, False), "window": (int, 3, 100_001, False),
           "max_run": (int, 1, 100_000, False)}
_PREPROCESS = {"rate": (float, 0.0, MAX_RATE_HZ, True), "skip_s": (float, 0.0, 1e9, False),
               "bias_seconds": (float, 0.0, 1e9, True), "bias_channels": (list,),
               "lowpass_hz": (float, 0.0, MAX_RATE_HZ, True), "filter_order": (int, 1, 10, False)}
_SPLIT = {"train": (float, 0.0, 1.0, True)}


def _card_error(where: str, name: str, value: Any, allowed: str) -> DataError:
    from designlab.params import _short

    return DataError(f"{where}: {name}={_short(value)!r} is not allowed: {allowed}")


def _check_keys(where: str, table: Any, known: tuple, section: str) -> None:
    from designlab.params import did_you_mean

    if not isinstance(table, Mapping):
        raise _card_error(where, section, table, "a table")
    for k in table:
        if k not in known:
            raise DataError(f"{where}: unknown key {section + '.' if section else ''}{k} "
                            f"(allowed: {', '.join(known)}){did_you_mean(k, known)}")


def _check_numbers(where: str, section: str, table: Mapping, spec: dict) -> None:
    _check_keys(where, table, tuple(spec), section)
    for k, v in table.items():
        kind, *rng = spec[k]
        name = f"{section}.{k}"
        if kind is bool:
            if not isinstance(v, bool):
                raise _card_error(where, name, v, "true or false")
        elif kind is list:
            if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
                raise _card_error(where, name, v, "a list of channel names")
        else:
            lo, hi, lo_open = rng
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            if kind is int:
                ok = ok and isinstance(v, int)
            ok = ok and (v > lo if lo_open else v >= lo) and v <= hi
            if not ok:
                what = "an integer" if kind is int else "a number"
                raise _card_error(where, name, v, f"{what}, {lo:g} {'<' if lo_open else '<='} "
                                  f"value <= {hi:g}")


def check_card(card: Mapping[str, Any], where: str) -> None:
    """Every key and value of a dataset card before any file is read: unknown keys (with a
    did-you-mean: ``unti`` is never read as millimetres), types, ranges, finite numbers."""
    _check_keys(where, card, _CARD_KEYS, "")
    if not isinstance(card.get("allow_outside_paths", False), bool):
        raise _card_error(where, "allow_outside_paths", card["allow_outside_paths"],
                          "true or false")
    files = card.get("files")
    if not isinstance(files, list) or not files:
        raise DataError(f"{where}: needs at least one [[files]] entry with a path")
    for i, f in enumerate(files):
        sec = f"files[{i + 1}]"
        _check_keys(where, f, _FILE_KEYS, sec)
        if not isinstance(f.get("path"), str) or not f["path"]:
            raise _card_error(where, f"{sec}.path", f.get("path"), "a file name (text)")
        if "header" in f and not isinstance(f["header"], bool):
            raise _card_error(where, f"{sec}.header", f["header"], "true or false")
        if "sign" in f and not isinstance(f["sign"], Mapping):
            raise _card_error(where, f"{sec}.sign", f["sign"], "a table channel = 1 | -1")
    for sec, cols in [("columns", card.get("columns"))] + [
            (f"files[{i + 1}].columns", f.get("columns")) for i, f in enumerate(files)]:
        if cols is not None:
            if not isinstance(cols, list) or not cols or not all(isinstance(c, str) for c in cols):
                raise _card_error(where, sec, cols, "a list of column names")
            if len(set(cols)) != len(cols):
                raise _card_error(where, sec, cols, "distinct column names")
    time = card.get("time", {})
    _check_keys(where, time, ("column", "unit"), "time")
    col = time.get("column")
    if col is not None and not (isinstance(col, str) or (
            isinstance(col, Mapping) and all(isinstance(v, str) for v in col.values()))):
        raise _card_error(where, "time.column", col, 'a column name, or {CHANNEL = "COLUMN"}')
    if "unit" in time and not isinstance(time["unit"], str):
        raise _card_error(where, "time.unit", time["unit"], ", ".join(UNITS["time"]))
    for group in ("inputs", "outputs"):
        chans = card.get(group, {})
        if not isinstance(chans, Mapping):
            raise _card_error(where, group, chans, "a table of channels")
        for name, spec in chans.items():
            if isinstance(spec, str):
                continue
            _check_keys(where, spec, _CHANNEL_KEYS, f"{group}.{name}")
            for k in ("column", "unit", "quantity", "kind"):
                if k in spec and not isinstance(spec[k], str):
                    raise _card_error(where, f"{group}.{name}.{k}", spec[k], "text")
    _check_numbers(where, "repair", card.get("repair", {}), _REPAIR)
    _check_numbers(where, "preprocess", card.get("preprocess", {}), _PREPROCESS)
    _check_numbers(where, "split", card.get("split", {}), _SPLIT)


def data_path(card_path: Path, name: str, allow_outside: bool) -> Path:
    """A data file named in a card, confined to the card's folder (symbolic links resolved)
    unless outside paths are allowed (``allow_outside_paths = true`` or the caller's flag)."""
    base = card_path.parent.resolve()
    p = (base / name).resolve()
    if not allow_outside and not p.is_relative_to(base):
        raise DataError(f"{card_path}: file {name!r} is outside the card's folder {base}; "
                        "set allow_outside_paths = true in the card to read it")
    return p


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
    names = [str(n) for n in table.column_names]
    dup = sorted({n for n in names if names.count(n) > 1})
    if dup:
        raise DataError(f"{path}: column name(s) {', '.join(map(repr, dup))} appear more than "
                        "once; name the columns with columns = [...]")
    out = {}
    for name in table.column_names:
        col = table.column(name)
        try:
            arr = col.cast(pa.float64()).to_numpy(zero_copy_only=False)
        except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
            arr = None  # non-numeric: only an error if a declared channel uses it
        out[str(name)] = np.asarray(arr, float) if arr is not None else col.to_pylist()
    return out


def _numeric(data: dict, col: str, path: Path) -> np.ndarray:
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
    """Read a dataset card and every file it names into one :class:`Dataset`. The card is
    checked whole first (:func:`check_card`); its files must lie in its folder unless it says
    ``allow_outside_paths = true`` (or ``allow_outside``)."""
    path = Path(path)
    if not path.is_file():
        raise DataError(f"{path}: dataset card not found")
    card = load_toml(path, "--data")
    check_card(card, str(path))
    allow_outside = allow_outside or bool(card.get("allow_outside_paths", False))
    files = card.get("files")
    if not files or not isinstance(files, list):
        raise DataError(f"{path}: needs at least one [[files]] entry with a path")
    time_sec = card.get("time", {})
    if "column" not in time_sec:
        raise DataError(f"{path}: [time] needs column = \"t\" (or one per channel)")
    tspec = time_sec["column"]
    t_unit = time_sec.get("unit", "s")
    if t_unit not in UNITS["time"]:
        raise DataError(f"{path}: [time] unit {t_unit!r} is not a time unit; allowed: "
                        f"{', '.join(UNITS['time'])}")
    t_scale = float(UNITS["time"][t_unit])
    where = str(path)
    channels: dict[str, tuple[str, Channel]] = {}
    for group in ("inputs", "outputs"):
        for name, spec in (card.get(group) or {}).items():
            if name in channels:
                raise DataError(f"{where}: channel '{name}' is declared twice")
            if not name or name in (".", "..") or any(c in name for c in "/\\") or any(
                    ord(c) < 32 or ord(c) == 127 for c in name):
                # the name becomes part of output file names (plots): never a path
                raise DataError(f"{where}: channel name {name!r} is not allowed: a name "
                                "without '/', '\\' or control characters (it names output "
                                "files)")
            channels[name] = (group, make_channel(name, spec, where, tspec))
    if not any(g == "outputs" for g, _ in channels.values()):
        raise DataError(f"{where}: [outputs] declares no channel")
    rep = {**{"dropouts": True, "spikes": True, "spike_k": 8.0, "spike_floor": 0.15,
              "window": 7, "max_run": 3},
           **card.get("repair", {})}
    pre = card.get("preprocess", {})
    split = card.get("split", {})
    top_columns = card.get("columns")

    raw = []
    for i, f in enumerate(files):
        if "path" not in f:
            raise DataError(f"{where}: [[files]] entry {i + 1} has no path")
        fpath = data_path(path, f["path"], allow_outside)
        role = f.get("role")
        if role not in (None, "train", "validate"):
            raise DataError(f"{where}: file {f['path']} role={role!r} is not allowed: "
                            "\"train\" or \"validate\"")
        data = read_table(fpath, f.get("columns", top_columns), f.get("header"))
        raw.append(_prepare_file(fpath, data, channels, t_scale, rep, f.get("sign", {})))
        raw[-1]["role"] = role

    rates = [r["rate"] for r in raw]
    rate = float(pre.get("rate", float(np.median(rates))))
    if not rate > 0:
        raise DataError(f"{where}: [preprocess] rate={rate!r} is not allowed: > 0 Hz")
    roles_given = any(r["role"] for r in raw)
    frac = split.get("train", None if roles_given else 0.6)
    if frac is not None and not 0 < float(frac) < 1:
        raise DataError(f"{where}: [split] train={frac!r} is not allowed: 0 < train < 1")

    ts, segs, roles, chans = [], [], [], {n: [] for n in channels}
    seg_info, file_reports = [], []
    total = 0
    for k, r in enumerate(raw):
        t0, t1 = r["t_start"], r["t_end"]
        skip = float(pre.get("skip_s", 0.0))
        if skip:
            for name, (tt, _) in r["series"].items():
                r["report"]["trimmed"][name]["skipped_start"] = int(np.sum(
                    (tt >= t0) & (tt < t0 + skip)))
            t0 = t0 + skip
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
        grid = t0 + np.arange(n) / rate
        values = {}
        for name, (tt, x) in r["series"].items():
            values[name] = _resample(tt, x, grid, r["rate"], rate)
        filt = _preprocess(values, channels, grid, rate, pre, r)
        role = r["role"] or ("train" if roles_given else None)
        if role is None:
            rr = np.where(grid - grid[0] <= float(frac) * (grid[-1] - grid[0]), "train",
                          "validate")
        else:
            rr = np.full(n, role)
        ts.append(grid)
        segs.append(np.full(n, k))
        roles.append(rr)
        for name in channels:
            chans[name].append(filt[name])
        seg_info.append({"path": str(r["path"]), "role": role or f"split {frac}",
                         "t_start": float(grid[0])})
        r["report"]["resampled"] = {"rate_hz": rate, "samples": n, "t_start": float(t0),
                                    "t_end": float(grid[-1])}
        file_reports.append(r["report"])

    cat = {n: np.concatenate(v) for n, v in chans.items()}
    report = {
        "card": str(path),
        "files": file_reports,
        "rate_hz": rate,
        "split": ("roles" if roles_given else {"train_fraction": float(frac)}),
        "preprocess": {k: v for k, v in pre.items()},
        "repair": rep,
        "repaired_total": {n: int(sum(fr["repaired"].get(n, {}).get("total", 0)
                                      for fr in file_reports)) for n in channels},
    }
    ds = Dataset(
        t=np.concatenate(ts), segment=np.concatenate(segs), role=np.concatenate(roles),
        inputs={n: cat[n] for n, (g, _) in channels.items() if g == "inputs"},
        outputs={n: cat[n] for n, (g, _) in channels.items() if g == "outputs"},
        segments=tuple(seg_info),
        units={n: c.canonical_unit for n, (_, c) in channels.items()},
        quantities={n: c.quantity for n, (_, c) in channels.items()},
        kinds={n: c.kind for n, (_, c) in channels.items()},
        report=report)
    return ds


def _prepare_file(fpath: Path, data: dict, channels: dict, t_scale: float, rep: dict,
                  sign_over: Mapping) -> dict:
    """Check, convert, sign-correct and repair one file's channels on their own clocks."""
    series, report = {}, {"path": str(fpath), "rows": None, "repaired": {}, "signs": {},
                           "units": {}, "trimmed": {}}
    clocks = {}
    for name, (_, ch) in channels.items():
        tcol = ch.time_column
        if tcol not in clocks:
            tt = _numeric(data, tcol, fpath) * t_scale
            d = np.diff(tt)
            bad = np.flatnonzero(d <= 0)
            if bad.size:
                raise DataError(f"{fpath}: time column '{tcol}' is not strictly increasing "
                                f"({bad.size} step(s), first at data row {bad[0] + 2})")
            if tt.size < 4:
                raise DataError(f"{fpath}: time column '{tcol}' has only {tt.size} samples")
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
            qq, kk = _quantity_of(name, {"quantity": q.get(name), "kind": k.get(name),
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
