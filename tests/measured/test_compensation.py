"""Compensation of seed 000: linear fit, common evaluation (NCC/RMSE/Wilcoxon), real data, CLI."""

import dataclasses
import json

from pathlib import Path

import numpy as np
import pytest

from designlab.measured import compensation as comp
from designlab.measured import linear_fit
from designlab.measured import mpl
from designlab.cli import main
from designlab.errors import DataError, ParameterError


def test_linear_fit_exact_on_sum_and_difference_channels():
    rng = np.random.default_rng(0)
    ch = rng.normal(size=(500, 2))
    fn = 3.0 * (ch[:, 0] + ch[:, 1]) + 0.5
    fx = -1.5 * (ch[:, 0] - ch[:, 1]) + 0.1
    fit = linear_fit.fit_linear(ch, np.column_stack([fn, fx]))      # auto: sum/diff (seed 000)
    assert fit.channels == ((1.0, 1.0), (1.0, -1.0))
    np.testing.assert_allclose(fit.A, [[3.0, 3.0], [-1.5, 1.5]], atol=1e-12)
    np.testing.assert_allclose(fit.b, [0.5, 0.1], atol=1e-12)
    np.testing.assert_allclose(fit.predict(ch), np.column_stack([fn, fx]), atol=1e-12)


def test_linear_fit_any_number_of_channels():
    rng = np.random.default_rng(1)
    u = rng.normal(size=(300, 3))
    A = np.array([[1.0, -2.0, 0.5], [0.3, 0.0, 4.0]])
    y = u @ A.T + [1.0, -2.0]
    fit = linear_fit.fit_linear(u, y)                               # 3 -> 2: full fit
    assert fit.channels is None
    np.testing.assert_allclose(fit.A, A, atol=1e-12)
    one = linear_fit.fit_linear(u[:, 0], 2 * u[:, 0] - 1)           # 1 -> 1
    np.testing.assert_allclose(one.predict(u[:, 0])[:, 0], 2 * u[:, 0] - 1, atol=1e-12)
    with pytest.raises(ParameterError, match="mix"):
        linear_fit.fit_linear(u, y, mix="sum-diff")
    with pytest.raises(ParameterError, match="2x3"):
        linear_fit.fit_linear(u, y, mix=np.eye(3))
    with pytest.raises(DataError, match="lengths differ"):
        linear_fit.fit_linear(u, y[:-1])
    with pytest.raises(DataError, match="NaN"):
        linear_fit.fit_linear(np.where(u > 2.5, np.nan, u), y)


def gauges(T, dt, seed):
    """Two hysteretic gauges (Ch1 <- F_n + F_x, Ch2 <- F_n - F_x) and the forces."""
    rng = np.random.default_rng(seed)
    t = np.arange(T) * dt
    fn = 2 + np.sin(rng.uniform(0.2, 0.4) * t) + 0.5 * np.sin(rng.uniform(0.9, 1.4) * t + 1)
    fx = 0.3 * np.sin(rng.uniform(0.4, 0.6) * t + 2)
    g = mpl.MPLParams(w0=1.0, w=(-0.5,), V_b=0.0, P_T=(0.1,), P_S=(0.05,), g=(0.0, 1.0, 0.05))
    return np.column_stack([g.simulate(fn + fx, dt), g.simulate(fn - fx, dt)]), \
        np.column_stack([fn, fx])


def records(n=3, T=2500, dt=0.05):
    out = []
    for i in range(n):
        u, y = gauges(T, dt, i)
        out.append(comp.Record(f"task{i + 1}", u, y, dt, ("Ch1", "Ch2"), ("Fn", "Fx")))
    return out


def test_compare_metrics_and_wilcoxon_on_synthetic_tasks():
    recs = records()
    opts = comp.CompensationOptions(mpl_cells=1, mpl_order=3, narx_max_iter=100)
    res = comp.compare(recs[:1], recs[1:], ("linear", "mpl"), opts)
    assert len(res.rows) == 2 * 3 * 2                                # models x tasks x outputs
    row = {(r["model"], r["task"], r["output"]): r for r in res.rows}
    assert row[("linear", "task1", "Fn")]["role"] == "train"
    assert row[("mpl", "task3", "Fx")]["role"] == "validate"
    for task in ("task2", "task3"):
        assert row[("mpl", task, "Fn")]["rmse"] < 0.3 * row[("linear", task, "Fn")]["rmse"]
        assert row[("mpl", task, "Fn")]["ncc"] > row[("linear", task, "Fn")]["ncc"]
        assert len(row[("mpl", task, "Fn")]["segment_rmse"]) == 10
    # the mPL is better on every one of the 10 segments: smallest two-sided p of n = 10
    w = [b for b in res.between_models if b["task"] == "task2" and b["output"] == "Fn"][0]
    assert (w["a"], w["b"]) == ("linear", "mpl")
    assert w["rmse"]["p_value"] == pytest.approx(2 / 2 ** 10)
    assert len(res.between_tasks) == 2 * 2 * 3                       # models x outputs x pairs
    # per-segment metrics are the metrics of the segment
    r = row[("linear", "task2", "Fx")]
    y, yh = recs[1].y[:250, 1], res.predictions[("linear", "task2")][:250, 1]
    assert r["segment_rmse"][0] == pytest.approx(np.sqrt(np.mean((y - yh) ** 2)))


def test_records_check_their_input():
    with pytest.raises(DataError, match="lengths differ"):
        comp.Record("a", np.ones((10, 2)), np.ones((9, 2)), 0.1)
    with pytest.raises(ParameterError, match="dt"):
        comp.Record("a", np.ones((10, 2)), np.ones((10, 2)), 0.0)
    a, b = records(2, T=400)
    b2 = comp.Record("b", b.u, b.y, 0.07)
    with pytest.raises(DataError, match="sample periods"):
        comp.fit_compensator("linear", [a, b2])
    with pytest.raises(ParameterError, match="model"):
        comp.fit_compensator("kalman", [a])




@pytest.fixture
def stretch_card(shared):
    """The example card (paths relative to it reach ../shared/data/stretch)."""
    return Path(__file__).resolve().parents[2] / "examples" / "cards" / "stretch_compensation.toml"


@pytest.mark.slow
def test_real_stretch_data_mpl_and_narx_beat_linear(stretch_card):
    """Force (N) from the 4-wire resistance of a carbon-black silicone strip: train on one
    multisine run, validate on another multisine run and a random sawtooth."""
    train, val = comp.records_from_card(stretch_card, ["resistance"], ["force"])
    assert [r.name for r in train] == ["multisine_600s_1"]
    assert [r.name for r in val] == ["multisine_300s_2", "2_7-5_4Epin_rand_sawtooth"]
    res = comp.compare(train, val, options=comp.CompensationOptions(narx_max_iter=200))
    row = {(r["model"], r["task"]): r for r in res.rows}
    for r in val:
        lin = row[("linear", r.name)]
        for m in ("mpl", "narx"):
            assert row[(m, r.name)]["rmse"] < 0.9 * lin["rmse"]
            assert row[(m, r.name)]["ncc"] > lin["ncc"]
        assert 0.3 < lin["rmse"] < 0.7          # N: the uncompensated error is large


def write_csv(path, u, y, dt, names=("Ch1", "Ch2", "Fn", "Fx")):
    t = np.arange(u.shape[0]) * dt
    data = np.column_stack([t, u, y])
    np.savetxt(path, data, delimiter=",", header=",".join(("t",) + names), comments="")


@pytest.mark.slow
def test_cli_writes_json_and_png(tmp_path):
    recs = records(2, T=1200)
    write_csv(tmp_path / "task1.csv", recs[0].u, recs[0].y, recs[0].dt)
    write_csv(tmp_path / "task2.csv", recs[1].u, recs[1].y, recs[1].dt)
    out = tmp_path / "out"
    main(["compensate", "--model", "linear,mpl", "--model", "narx", "--train",
          str(tmp_path / "task1.csv"), "--validate", str(tmp_path / "task2.csv"), "--input",
          "Ch1,Ch2", "--output", "Fn,Fx", "--time", "t", "--cells", "1", "--order", "3",
          "--narx-delays", "20", "--out", str(out)])
    assert sorted(p.name for p in out.iterdir()) == ["compensation.json", "compensation.png"]
    doc = json.loads((out / "compensation.json").read_text())
    got = {(r["model"], r["task"], r["output"]) for r in doc["metrics"]}
    assert got == {(m, t, o) for m in ("linear", "mpl", "narx") for t in ("task1", "task2")
                   for o in ("Fn", "Fx")}
    assert set(doc["fits"]) == {"linear", "mpl", "narx"}
    assert doc["wilcoxon_between_models"] and doc["wilcoxon_between_tasks"]
    assert (out / "compensation.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_cli_with_dataset_card(stretch_card, tmp_path):
    main(["compensate", "--data", str(stretch_card), "--input", "resistance", "--output", "force",
          "--model", "linear", "--out", str(tmp_path / "o")])
    doc = json.loads((tmp_path / "o" / "compensation.json").read_text())
    assert {r["task"] for r in doc["metrics"]} == {"multisine_600s_1", "multisine_300s_2",
                                                  "2_7-5_4Epin_rand_sawtooth"}


def test_cli_bad_input_exits_2_and_writes_nothing(tmp_path, capsys):
    recs = records(1, T=300)
    good = tmp_path / "good.csv"
    write_csv(good, recs[0].u, recs[0].y, recs[0].dt)
    nan = tmp_path / "nan.csv"
    y = recs[0].y.copy()
    y[17, 0] = np.nan
    write_csv(nan, recs[0].u, y, recs[0].dt)
    jitter = tmp_path / "jitter.csv"
    np.savetxt(jitter, np.column_stack([np.cumsum(np.r_[0, np.tile([0.05, 0.2], 149), 0.05]),
                                        recs[0].u, recs[0].y]),
               delimiter=",", header="t,Ch1,Ch2,Fn,Fx", comments="")
    base = ["compensate", "--input", "Ch1,Ch2", "--output", "Fn,Fx", "--model", "linear"]
    cases = [
        (["--train", str(good), "--output", "Fz", "--time", "t"], "Fz"),      # unknown column
        (["--train", str(nan), "--time", "t"], "NaN"),
        (["--train", str(jitter), "--time", "t"], "not uniformly sampled"),
        (["--train", str(good)], "time"),                                     # neither --time nor --dt
        (["--train", str(good), "--dt", "0.05", "--model", "kalman"], "model"),
        (["--train", str(good), "--dt", "0.05", "--cells", "-1"], "--cells"),
        (["--train", str(tmp_path / "missing.csv"), "--dt", "0.05"], "not found"),
    ]
    for k, (extra, text) in enumerate(cases):
        out = tmp_path / f"out{k}"
        with pytest.raises(SystemExit) as info:
            main(base + extra + ["--out", str(out)])
        assert info.value.code == 2
        err = capsys.readouterr().err
        assert text in err and err.strip().count("\n") == 0, err
        assert not out.exists() or not any(out.iterdir())


def _write(path, t, x, y):
    path.write_text("t,x,y\n" + "".join(f"{float(a)!r},{float(b)!r},{float(c)!r}\n"
                                         for a, b, c in zip(t, x, y)))


@pytest.mark.parametrize("change, message", [
    ("tiny", "time column 't' has a step of 1e-310 s; allowed: steps >= 1e-09 s"),
    ("inf", "column 't' has 1 NaN/missing or infinite value(s), first (infinite) at data row 6"),
    ("small", "tr.csv: column 'x' varies by 2e-300 only (largest |value| 1e-300); allowed: a "
              "spread of 0 (constant) or >= 1e-60: a smaller one is below the precision a fit "
              "needs"),
])
def test_files_that_break_the_fit_are_named(tmp_path, change, message):
    """Steps of 1e-310 s, an inf time cell and values near 1e-300 (refused when read: a fit's
    squares of them underflow)."""
    t = np.arange(400) * 0.01
    x, y = np.sin(3 * t), 2 * np.sin(3 * t) + 0.1 * np.cos(t)
    _write(tmp_path / "v.csv", t, x, y)
    if change == "tiny":
        t = t * 1e-308
    if change == "inf":
        t[5] = np.inf
    if change == "small":
        x, y = x * 1e-300, y * 1e-300
    _write(tmp_path / "tr.csv", t, x, y)
    with pytest.raises(DataError) as exc:
        train = [comp.load_record(tmp_path / "tr.csv", ["x"], ["y"], time="t")]
        comp.compare(train, [comp.load_record(tmp_path / "v.csv", ["x"], ["y"], time="t")],
                     ["linear"])
    assert message in str(exc.value) and "\n" not in str(exc.value)


def test_values_near_1e300_are_one_data_sentence_without_a_numpy_warning():
    """Records (not files) of values near 1e-300: the linear fit's column scale underflows and
    its SVD fails; that is said as a sentence about the data, and numpy's divide-by-zero
    warning does not reach the caller (the command line would print it as a raw line)."""
    import warnings

    t = np.arange(400) * 0.01
    u = np.column_stack([np.sin(3 * t), np.cos(2 * t)]) * 1e-300
    rec = comp.Record(name="tr", u=u, y=u @ [[2.0, 0.5], [0.1, 1.0]], dt=0.01,
                      inputs=("a", "b"), outputs=("p", "q"))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(DataError, match=r"the linear fit on the training records failed "
                           r".*extreme scale \(largest \|input\| 1e-300\)"):
            comp.compare([rec], [dataclasses.replace(rec, name="va")])


def test_cli_values_near_1e300_are_one_line(tmp_path, capsys):
    t = np.arange(400) * 0.01
    x, y = np.sin(3 * t) * 1e-300, 2 * np.sin(3 * t) + 0.1 * np.cos(t)
    for name in ("tr", "va"):
        _write(tmp_path / f"{name}.csv", t, x, y)
    out = tmp_path / "out"
    err = _refused(tmp_path, capsys, "--input", "x", "--output", "y", "--out", str(out))
    assert err.strip().splitlines() == [
        f"error: {tmp_path / 'tr.csv'}: column 'x' varies by 2e-300 only (largest |value| "
        "1e-300); allowed: a spread of 0 (constant) or >= 1e-60: a smaller one is below the "
        "precision a fit needs (its squares underflow to 0; is the unit right?)"]
    assert not out.exists()


def test_records_beyond_the_card_budget_are_refused(monkeypatch):
    monkeypatch.setattr(comp, "MAX_CARD_SAMPLES", 100)
    rec = comp.Record(name="a", u=np.ones((80, 1)), y=np.ones((80, 1)), dt=0.1, inputs=("x",),
                      outputs=("y",))
    with pytest.raises(DataError, match="the records hold 160 samples; at most 100 in all"):
        comp.compare([rec], [dataclasses.replace(rec, name="b")], ["linear"])


def test_the_costly_models_have_a_sample_limit_scaled_by_their_settings():
    rec = comp.Record(name="a", u=np.ones((10, 1)), y=np.ones((10, 1)), dt=0.1, inputs=("x",),
                      outputs=("y",))
    two = dataclasses.replace(rec, u=np.ones((10, 2)), y=np.ones((10, 2)))
    opts = comp.CompensationOptions()
    assert comp.fit_limit("linear", rec, opts) is None
    assert comp.fit_limit("narx", rec, opts) == comp.fit_limit("mpl", rec, opts) == 200_000
    assert comp.fit_limit("mpl", two, opts) == 100_000                  # one fit per output
    assert comp.fit_limit("narx", two, opts) == 100_000                 # twice the features
    assert comp.fit_limit("narx", rec, dataclasses.replace(opts, narx_hidden=40)) == 50_000
    assert comp.fit_limit("narx", rec, dataclasses.replace(opts, narx_input_delays=5)) == 200_000


def test_a_costly_model_beyond_its_limit_is_refused_before_the_fit(monkeypatch):
    monkeypatch.setattr(comp, "MAX_FIT_SAMPLES", {"mpl": 150, "narx": 100})
    t = np.arange(80) * 0.1
    rec = comp.Record(name="a", u=np.sin(t)[:, None], y=np.cos(t)[:, None], dt=0.1,
                      inputs=("x",), outputs=("y",))
    va = dataclasses.replace(rec, name="b")
    assert comp.compare([rec], [va], ["linear"]).rows          # no limit on the linear fit
    for models, m, limit in ((["narx"], "narx", 100), (["linear", "mpl"], "mpl", 150),
                             (list(comp.MODELS), "mpl", 150)):
        with pytest.raises(DataError) as exc:
            comp.compare([rec], [va], models,
                         progress=lambda s: pytest.fail(f"work started: {s}"))
        assert str(exc.value) == (
            f"the records hold 160 samples; the {m} model fits at most {limit} (about 2 "
            "minutes on 2 cores with these settings): use --model linear, or shorten or "
            "decimate the files")


@pytest.mark.parametrize("model", ["narx", "mpl"])
def test_cli_refuses_a_costly_model_on_a_long_record_at_once(tmp_path, capsys, model):
    """A record over the limit (still under the card's memory budget) is refused in one line
    before any fit, instead of a silent fit of many minutes."""
    import time

    t = np.arange(200_001) * 0.01
    for name, part in (("tr", slice(0, 160_000)), ("va", slice(160_000, None))):
        np.savetxt(tmp_path / f"{name}.csv", np.column_stack([t[part], np.sin(t[part]),
                                                               np.cos(t[part])]),
                   delimiter=",", header="t,r,f", comments="", fmt="%.6f")
    out = tmp_path / "out"
    t0 = time.perf_counter()
    err = _refused(tmp_path, capsys, "--input", "r", "--output", "f", "--model", model,
                   "--out", str(out))
    assert time.perf_counter() - t0 < 30
    assert err.strip().splitlines() == [
        f"error: the records hold 200001 samples; the {model} model fits at most 200000 (about "
        "2 minutes on 2 cores with these settings): use --model linear, or shorten or decimate "
        "the files"]
    assert not out.exists()


@pytest.mark.parametrize("fail", ["json", "png", "folder"])
def test_outputs_are_written_as_a_pair_or_not_at_all(tmp_path, monkeypatch, disk_full_at, fail):
    """A full disk while writing either file, or a folder by the plot's name, leaves neither
    file and no temporary one."""
    import errno

    from designlab.errors import OutputError

    t = np.arange(200) * 0.01
    rec = comp.Record(name="a", u=np.sin(3 * t)[:, None], y=2 * np.sin(3 * t)[:, None] + 0.1,
                      dt=0.01, inputs=("x",), outputs=("y",))
    res = comp.compare([rec], [dataclasses.replace(rec, name="b")], ["linear"])
    if fail == "folder":   # a folder by the plot's name: the JSON stood alone
        (tmp_path / "out" / "compensation.png").mkdir(parents=True)
        with pytest.raises(OutputError, match="compensation.png: it is a directory"):
            comp.write_outputs(res, [rec], tmp_path / "out")
        assert [p.name for p in (tmp_path / "out").iterdir()] == ["compensation.png"]
        return
    if fail == "json":
        disk_full_at(r"^\.compensation\..*\.json$")
    else:
        import matplotlib.figure

        def no_space(self, *a, **k):
            raise OSError(errno.ENOSPC, "No space left on device")
        monkeypatch.setattr(matplotlib.figure.Figure, "savefig", no_space)
    with pytest.raises(OutputError, match="no space left"):
        comp.write_outputs(res, [rec], tmp_path / "out")
    assert not (tmp_path / "out").exists()     # nor the folder made for them


def _refused(tmp_path, capsys, *args) -> str:
    """stderr of ``designlab compensate`` on tmp_path's tr.csv / va.csv (time column t) with
    ``args``, which must exit 2."""
    with pytest.raises(SystemExit) as info:
        main(["compensate", "--train", str(tmp_path / "tr.csv"), "--validate",
              str(tmp_path / "va.csv"), "--time", "t", *args])
    assert info.value.code == 2
    return capsys.readouterr().err
