"""Dataset cards: every messy aspect of real logs on small synthetic files, then the real ones."""

from __future__ import annotations

import numpy as np
import pytest

from designlab.measured.dataset import (find_dropouts, find_spikes, from_arrays, load_card,
                                           lowpass)
from designlab.errors import DataError

STRETCH = ["Ro", "Ri", "tR", "P", "tP", "F", "tF"]


def write_csv(path, cols: dict, header: bool = True) -> None:
    names = list(cols)
    n = len(next(iter(cols.values())))
    lines = [",".join(names)] if header else []
    for i in range(n):
        lines.append(",".join("" if (isinstance(cols[c][i], float) and np.isnan(cols[c][i]))
                              else repr(float(cols[c][i])) for c in names))
    path.write_text("\n".join(lines) + "\n")


def card(tmp_path, body: str, name: str = "card.toml"):
    p = tmp_path / name
    p.write_text(body)
    return p


def signals(n=400, dt=0.1, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(n) * dt
    P = 5 + 4 * np.sin(2 * np.pi * t / 9.0)              # mm, always > 1
    F = 0.3 * P + rng.normal(0, 0.005, n)                # N
    return t, P, F


BASIC = """
[[files]]
path = "run.csv"
[time]
column = "t"
[inputs]
displacement = {{ column = "P", unit = "{punit}" }}
[outputs]
force = {{ column = "F", unit = "N" }}
[split]
train = 0.6
"""


def test_basic_card_units_and_split(tmp_path):
    t, P, F = signals()
    write_csv(tmp_path / "run.csv", {"t": t, "P": P / 1000.0, "F": F})   # P in metres
    ds = load_card(card(tmp_path, BASIC.format(punit="m")))
    np.testing.assert_allclose(ds.inputs["displacement"], P, rtol=1e-9, atol=1e-9)
    assert ds.units == {"displacement": "mm", "force": "N"}
    assert ds.report["files"][0]["units"]["displacement"] == {"column": "P", "from": "m",
                                                              "to": "mm"}
    tr, va = ds.train(), ds.validate()
    assert len(tr) + len(va) == len(ds)
    assert tr.t.max() < va.t.min()
    assert len(tr) / len(ds) == pytest.approx(0.6, abs=0.01)
    # split by a fraction on request
    a, b = ds.split(0.5)
    assert len(a) / len(ds) == pytest.approx(0.5, abs=0.01)


def test_dropouts_and_spikes_are_repaired_and_counted(tmp_path):
    t, P, F = signals()
    Pd, Fd = P.copy(), F.copy()
    drop = [50, 51, 120, 300]           # encoder drops to exactly 0 (one run of 2)
    Pd[drop] = 0.0
    Fd[[77, 250]] += 2.0                 # two isolated spikes
    write_csv(tmp_path / "run.csv", {"t": t, "P": Pd, "F": Fd})
    ds = load_card(card(tmp_path, BASIC.format(punit="mm")))
    rep = ds.report["files"][0]["repaired"]
    assert rep["displacement"]["dropouts"] == 4 and rep["displacement"]["spikes"] == 0
    assert rep["force"]["spikes"] == 2 and rep["force"]["dropouts"] == 0
    assert ds.report["repaired_total"] == {"displacement": 4, "force": 2}
    np.testing.assert_allclose(ds.inputs["displacement"], P, atol=0.05)
    assert np.max(np.abs(ds.outputs["force"] - F)) < 0.05
    # a real zero crossing / long zero hold is not a dropout
    x = np.r_[np.linspace(1, 0, 10), np.zeros(20), np.linspace(0, 1, 10)]
    assert not find_dropouts(x).any()
    # sharp but real turns of a fast signal are not spikes
    tri = np.abs(((np.arange(300) * 0.37) % 10) - 5)
    assert not find_spikes(tri).any()


def test_repair_can_be_switched_off(tmp_path):
    t, P, F = signals()
    P[100] = 0.0
    write_csv(tmp_path / "run.csv", {"t": t, "P": P, "F": F})
    body = BASIC.format(punit="mm") + "[repair]\ndropouts = false\nspikes = false\n"
    ds = load_card(card(tmp_path, body))
    assert ds.report["repaired_total"]["displacement"] == 0
    assert np.min(ds.inputs["displacement"]) == pytest.approx(0.0, abs=1e-9)


def test_sign_flip_between_files_auto_and_declared(tmp_path):
    t, P, F = signals()
    write_csv(tmp_path / "a.csv", {"t": t, "P": P, "F": F})
    write_csv(tmp_path / "b.csv", {"t": t, "P": -P, "F": -F})      # flipped conventions
    body = """
[[files]]
path = "a.csv"
role = "train"
[[files]]
path = "b.csv"
role = "validate"
sign = { F = -1 }
[time]
column = "t"
[inputs]
displacement = { column = "P", unit = "mm", sign = "auto" }
[outputs]
force = { column = "F", unit = "N" }
"""
    ds = load_card(card(tmp_path, body))
    va = ds.validate()
    np.testing.assert_allclose(va.inputs["displacement"], P, atol=1e-9)
    np.testing.assert_allclose(va.outputs["force"], F, atol=1e-9)
    signs = [f["signs"] for f in ds.report["files"]]
    assert signs[0]["displacement"] == {"sign": 1, "mode": "auto"}
    assert signs[1]["displacement"] == {"sign": -1, "mode": "auto"}
    assert signs[1]["force"] == {"sign": -1, "mode": "declared"}
    assert [s["role"] for s in ds.segments] == ["train", "validate"]


def test_separate_clocks_are_resampled_onto_one(tmp_path):
    n = 500
    rng = np.random.default_rng(3)
    tP = np.cumsum(rng.uniform(0.07, 0.1, n))
    tF = tP + 0.031 + rng.uniform(0, 0.01, n)           # another instrument's clock
    f = lambda tt: 3 + 2 * np.sin(2 * np.pi * tt / 11.0)  # noqa: E731
    write_csv(tmp_path / "r.csv", {"P": f(tP), "tP": tP, "F": 0.3 * f(tF), "tF": tF},
              header=False)
    body = """
columns = ["P", "tP", "F", "tF"]
[[files]]
path = "r.csv"
[time]
column = { P = "tP", F = "tF" }
[inputs]
displacement = { column = "P", unit = "mm" }
[outputs]
force = { column = "F", unit = "N" }
[preprocess]
rate = 10.0
"""
    ds = load_card(card(tmp_path, body))
    assert ds.dt == pytest.approx(0.1)
    assert ds.t[0] >= max(tP[0], tF[0]) - 1e-12 and ds.t[-1] <= min(tP[-1], tF[-1]) + 1e-12
    # on the common clock the two channels agree with the truth at the same instants
    np.testing.assert_allclose(ds.inputs["displacement"], f(ds.t), atol=0.02)
    np.testing.assert_allclose(ds.outputs["force"], 0.3 * f(ds.t), atol=0.01)
    tr = ds.report["files"][0]["trimmed"]
    assert tr["displacement"]["before"] >= 1     # P starts before F's clock: counted, not lost


def test_preprocess_bias_lowpass_recorded(tmp_path):
    t = np.arange(2000) * 0.01                             # 100 Hz
    P = np.where(t > 2, 3.0, 0.0) + 0.0
    F = 0.5 + 0.3 * P + 0.2 * np.sin(2 * np.pi * 40 * t)   # bias 0.5 N and 40 Hz hum
    write_csv(tmp_path / "run.csv", {"t": t, "P": P + 1e-3, "F": F})
    body = BASIC.format(punit="mm") + """
[preprocess]
bias_seconds = 1.0
lowpass_hz = 10.0
rate = 50.0
"""
    ds = load_card(card(tmp_path, body))
    pre = ds.report["files"][0]["preprocess"]
    assert pre["bias"]["subtracted"]["force"] == pytest.approx(0.5, abs=0.01)
    assert "10.0 Hz" in pre["lowpass"]
    hold = (ds.t > 5) & (ds.t < 15)
    assert np.std(ds.outputs["force"][hold]) < 0.01       # hum removed
    assert np.mean(ds.outputs["force"][hold]) == pytest.approx(0.9, abs=0.01)
    # a cut-off above Nyquist is skipped and said so
    body2 = body.replace("rate = 50.0", "rate = 15.0")
    ds2 = load_card(card(tmp_path, body2, "c2.toml"))
    assert ds2.report["files"][0]["preprocess"]["lowpass"].startswith("skipped")
    assert np.std(lowpass(np.sin(np.arange(500) * 2.5), 100.0, 5.0)) < 0.05


@pytest.mark.parametrize("mutate, message", [
    ("nan", "column 'F' has 1 NaN"),
    ("inf", "column 'F' has 1 NaN/missing or infinite value(s), first (infinite) at data row 18"),
    ("huge", "column 'F' has 1 value(s) beyond +-1e+20, first at data row 18"),
    ("slash", "channel name 'a/b' is not allowed"),
    ("time", "time column 't' is not strictly increasing"),
    ("column", "column 'Q' not found"),
    ("unit", "column 'P' (displacement) has unit 'kg', not a length unit; allowed: mm, m"),
    ("role", "role='test' is not allowed"),
    ("sign", "sign=2 is not allowed"),
    ("missing", "file not found"),
])
def test_bad_data_gives_one_line_error(tmp_path, mutate, message):
    t, P, F = signals(50)
    if mutate == "nan":
        F[17] = np.nan
    if mutate == "inf":
        F[17] = np.inf
    if mutate == "huge":
        F[17] = 1e300
    if mutate == "time":
        t[30] = t[28]
    write_csv(tmp_path / "run.csv", {"t": t, "P": P, "F": F})
    body = BASIC.format(punit="kg" if mutate == "unit" else "mm")
    if mutate == "column":
        body = body.replace('column = "F"', 'column = "Q"')
    if mutate == "role":
        body = body.replace('path = "run.csv"', 'path = "run.csv"\nrole = "test"')
    if mutate == "sign":
        body = body.replace('unit = "N" }', 'unit = "N", sign = 2 }')
    if mutate == "missing":
        body = body.replace("run.csv", "nope.csv")
    if mutate == "slash":  # a channel name ends up in plot file names: never a path
        body = body.replace("force =", '"a/b" =')
    with pytest.raises(DataError) as exc:
        load_card(card(tmp_path, body))
    text = str(exc.value)
    assert message in text and "\n" not in text


CARD_FAULTS = [  # (what the card says, the words of the one-line error)
    ('unti = "m"', "unknown key unti"),
    ('[inputs.displacement]\ncolumn = "P"\nunti = "m"', "unknown key inputs.displacement.unti"),
    ("[preprocess]\nrat = 5.0", "unknown key preprocess.rat (allowed: rate"),
    ('files = [1]', "files[1]"),
    ('[time]\ncolumn = "t"\nunit = 3', "time.unit=3"),
    ('[preprocess]\nrate = "abc"', "preprocess.rate='abc' is not allowed"),
    ("[repair]\nwindow = 0", "repair.window=0 is not allowed: an integer, 3 <= value"),
    ("[preprocess]\nlowpass_hz = -1", "preprocess.lowpass_hz=-1 is not allowed"),
    ("[preprocess]\nbias_seconds = -1", "preprocess.bias_seconds=-1 is not allowed"),
    ("[preprocess]\nrate = 1e6", "preprocess.rate=1000000.0 is not allowed"),
    ("[preprocess]\nrate = inf", "is not allowed: a finite number"),
    ("[split]\ntrain = 1.5", "split.train=1.5"),
    ("allow_outside_paths = 1", "allow_outside_paths=1"),
]


@pytest.mark.parametrize("extra, message", CARD_FAULTS)
def test_every_card_key_and_value_is_checked(tmp_path, extra, message):
    """Typos and wrong types are errors naming the key (never ignored: ``unti = "m"`` would
    read metres as millimetres)."""
    t, P, F = signals(50)
    write_csv(tmp_path / "run.csv", {"t": t, "P": P, "F": F})
    body = BASIC.format(punit="mm")
    if extra.startswith("files"):
        body = extra + "\n" + body.replace('[[files]]\npath = "run.csv"\n', "")
    elif extra.startswith("[inputs.displacement]"):
        body = body.replace('displacement = { column = "P", unit = "mm" }\n', "") + extra
    elif extra.startswith("[time]"):
        body = body.replace('[time]\ncolumn = "t"\n', "") + extra
    elif extra.startswith("[split]"):
        body = body.replace("[split]\ntrain = 0.6\n", "") + extra
    elif extra.startswith("["):
        body = body + extra
    else:
        body = extra + "\n" + body
    with pytest.raises(Exception) as exc:
        load_card(card(tmp_path, body))
    from designlab.errors import DesignlabError

    assert isinstance(exc.value, DesignlabError)
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_card_paths_stay_in_the_card_folder_and_errors_never_quote_files(tmp_path):
    secret = tmp_path / "secret.txt"
    secret.write_text("hunter2:*:19000:0:99999:7:::\nsecondline:x\n")
    folder = tmp_path / "cards"
    folder.mkdir()
    for name in (str(secret), "../secret.txt"):
        body = BASIC.format(punit="mm").replace("run.csv", name)
        with pytest.raises(DataError, match="outside the card's folder") as exc:
            load_card(card(folder, body))
        assert "hunter2" not in str(exc.value)
    (folder / "link.csv").symlink_to(secret)
    with pytest.raises(DataError, match="outside the card's folder"):
        load_card(card(folder, BASIC.format(punit="mm").replace("run.csv", "link.csv")))
    # allowed explicitly: the file is read, and its parse error does not quote it
    body = "allow_outside_paths = true\n" + BASIC.format(punit="mm").replace("run.csv",
                                                                              str(secret))
    with pytest.raises(DataError) as exc:
        load_card(card(folder, body))
    assert "hunter2" not in str(exc.value) and "secondline" not in str(exc.value)


def test_repeated_columns_and_binary_parquet_are_one_line_errors(tmp_path):
    (tmp_path / "run.csv").write_text("t,P,P,F\n0,1,1,1\n1,2,2,2\n2,3,3,3\n3,4,4,4\n4,5,5,5\n")
    with pytest.raises(DataError, match="'P' appear more than once"):
        load_card(card(tmp_path, BASIC.format(punit="mm")))
    (tmp_path / "run.parquet").write_bytes(b"\x00\x01garbage" * 100)
    with pytest.raises(DataError, match="not a readable Parquet file"):
        load_card(card(tmp_path, BASIC.format(punit="mm").replace("run.csv", "run.parquet")))


def test_headerless_csv_needs_columns_and_parquet_reads(tmp_path):
    import pyarrow as pa
    import pyarrow.parquet as pq

    t, P, F = signals(100)
    write_csv(tmp_path / "run.csv", {"t": t, "P": P, "F": F}, header=False)
    with pytest.raises(DataError, match="could not|not found|no header|columns"):
        load_card(card(tmp_path, BASIC.format(punit="mm")))
    pq.write_table(pa.table({"t": t, "P": P, "F": F}), tmp_path / "run.parquet")
    ds = load_card(card(tmp_path, BASIC.format(punit="mm").replace("run.csv", "run.parquet")))
    np.testing.assert_allclose(ds.outputs["force"], F, atol=1e-12)


def test_from_arrays_and_select():
    t = np.arange(100) * 0.1
    ds = from_arrays(t, {"displacement": t}, {"force": 2 * t},
                     role=np.where(t < 6, "train", "validate"))
    assert ds.quantities == {"displacement": "length", "force": "force"}
    v = ds.validate()
    assert v.time_in_run()[0] == pytest.approx(t[t >= 6][0])   # time since the run began
    with pytest.raises(DataError):
        ds.channel("nope")


# --------------------------------------------------------------------------- the real logs


def test_real_stretch_files(shared, tmp_path):
    data = shared / "data" / "stretch"
    files = "".join(f'[[files]]\npath = "{p}"\nrole = "train"\n'
                    for p in sorted(data.glob("*.csv")))
    body = f"""columns = {STRETCH!r}
{files}
[time]
column = {{ Ri = "tR", P = "tP", F = "tF" }}
[inputs]
displacement = {{ column = "P", unit = "mm", sign = "auto" }}
[outputs]
force = {{ column = "F", unit = "N" }}
resistance = {{ column = "Ri", unit = "ohm", sign = "auto" }}
""".replace("'", '"')
    with pytest.raises(DataError, match="outside the card's folder"):
        load_card(card(tmp_path, body))
    ds = load_card(card(tmp_path, "allow_outside_paths = true\n" + body))
    reps = {f["path"].rsplit("/", 1)[-1]: f for f in ds.report["files"]}
    # single-sample encoder dropouts: ~3 % of the multisine samples, all repaired and counted
    ms = reps["multisine_600s_1.csv"]
    assert ms["repaired"]["displacement"]["dropouts"] == 172
    assert 0.02 < ms["repaired"]["displacement"]["dropouts"] / ms["rows"] < 0.04
    assert reps["multisine_300s_2.csv"]["repaired"]["displacement"]["dropouts"] == 77
    # sign conventions: P negative in the sawtooth/v8/v19 files, Ri negative in v19
    v19 = reps["2_7-5_E4pin_20mm_v19_0.3Strain.csv"]
    assert v19["signs"]["displacement"]["sign"] == -1 and v19["signs"]["resistance"]["sign"] == -1
    assert reps["multisine_600s_1.csv"]["signs"]["displacement"]["sign"] == 1
    assert np.median(ds.inputs["displacement"]) > 0 and np.min(ds.outputs["resistance"]) > 0
    # after repair no interior dropout is left in the multisine runs
    for s, info in enumerate(ds.segments):
        if "multisine" in info["path"]:
            x = ds.inputs["displacement"][ds.segment == s]
            assert not find_dropouts(x).any()
            assert ds.dt == pytest.approx(1 / ds.report["rate_hz"])


def test_a_card_holds_at_most_the_memory_budgets_samples(tmp_path, monkeypatch):
    """All runs together on the common clock are capped (the loop's memory budget): the run that
    crosses it is named with the count and the allowed total, one line; at the cap it loads."""
    from designlab.errors import DesignlabError
    from designlab.measured import dataset

    assert dataset.MAX_CARD_SAMPLES == 2_000_000
    t, P, F = signals(50)                      # 50 samples at 10 Hz per run
    for k in (1, 2):
        write_csv(tmp_path / f"run{k}.csv", {"t": t, "P": P, "F": F})
    body = BASIC.format(punit="mm").replace(
        '[[files]]\npath = "run.csv"\n', '[[files]]\npath = "run1.csv"\n[[files]]\npath = "run2.csv"\n')
    monkeypatch.setattr(dataset, "MAX_CARD_SAMPLES", 100)
    assert len(load_card(card(tmp_path, body))) == 100
    monkeypatch.setattr(dataset, "MAX_CARD_SAMPLES", 99)
    with pytest.raises(DesignlabError) as exc:
        load_card(card(tmp_path, body))
    msg = str(exc.value)
    assert "run2.csv" in msg and "100 samples" in msg and "at most 99 in all" in msg
    assert "\n" not in msg


@pytest.mark.parametrize("change, message", [
    ("tiny-steps", "time column 't' has a step of 1e-310 s at data row 396; allowed: steps >= 1e-09 s"),
    ("lowpass", "preprocess.lowpass_hz=1e-13 is not allowed: >= 1e-06 x the sample rate (10 Hz)"),
    ("split", "[split] train=0.9999999999999999 is not allowed: a fraction leaving at least 10 "
              "samples to training and to validation (it leaves 399 and 1)"),
    ("latin-1", "cannot parse as CSV (the header row is not UTF-8 text"),
    ("tiny-values", "run.csv: column 'F' varies by 2e-300 only (largest |value| 1e-300); allowed: "
                    "a spread of 0 (constant) or >= 1e-60: a smaller one is below the precision "
                    "a fit needs"),
])
def test_values_that_break_the_numbers_are_named(tmp_path, change, message):
    """Steps of 1e-310 s (1 / step overflows), a cut-off that makes the filter singular, a split
    leaving one validation sample, a latin-1 header and readings that vary near 1e-300 (no fit
    can scale them; their squares underflow to 0): one line naming the file, not an
    internal error."""
    t, P, F = signals(400)
    if change == "tiny-steps":
        t = t * 1e-309
    if change == "tiny-values":
        F = np.sin(t) * 1e-300
    write_csv(tmp_path / "run.csv", {"t": t, "P": P, "F": F})
    body = BASIC.format(punit="mm")
    if change == "lowpass":
        body += "[preprocess]\nlowpass_hz = 1e-13\n"
    if change == "split":
        body = body.replace("train = 0.6", "train = 0.9999999999999999")
    if change == "latin-1":
        raw = (tmp_path / "run.csv").read_bytes()
        (tmp_path / "run.csv").write_bytes(b"t,P,F\xe9" + raw[raw.index(b"\n"):])
        body = body.replace('column = "F"', 'column = "F\xe9"')
    with pytest.raises(DataError) as exc:
        load_card(card(tmp_path, body))
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_a_card_with_too_many_channels_or_one_column_twice_is_refused(tmp_path):
    """3000 channels (or inputs all reading one column) ran past 5 minutes or fitted one
    signal several times: refused before any file is read."""
    many = "\n".join(f'c{i} = {{ column = "P", unit = "mm" }}' for i in range(70))
    body = BASIC.format(punit="mm").replace("[inputs]\n", "[inputs]\n" + many + "\n", 1)
    with pytest.raises(DataError, match="72 channels are declared; at most 64"):
        load_card(card(tmp_path, body))
    body = BASIC.format(punit="mm").replace(
        "[inputs]\n", '[inputs]\nagain = { column = "P", unit = "mm" }\n', 1)
    with pytest.raises(DataError, match="channels 'again' and 'displacement' both read "
                                        "column 'P'"):
        load_card(card(tmp_path, body, "c2.toml"))
