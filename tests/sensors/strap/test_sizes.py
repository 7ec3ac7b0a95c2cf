"""Strap sizes for a population: the drawn fingers against the anthropometric table, the size
table, ``--sizes auto``'s rule, the paper's slots beside it, and the command's bad input."""

import numpy as np
import pytest

from designlab.errors import DataError, ParameterError
from designlab.sensors.strap import population as pp


@pytest.mark.parametrize("group", pp.GROUPS)
def test_copula_reproduces_the_table_percentiles_and_correlations(group):
    # whole-mm readings: the table's percentile lies between the shares of draws below and at
    # its value (binomial sampling error of 20000 draws: < 0.4 %; 1 % allowed)
    rows = pp.fit_check(group, n=20000, seed=1)
    for r in rows:
        if "percentile" in r:
            assert r["share_below"] - 0.01 <= r["percentile"] / 100 <= r["share_at_or_below"] + 0.01, r
        else:
            assert abs(r["correlation_drawn"] - r["correlation_table"]) < 0.03, r


def test_draw_is_seeded_and_names_its_assumptions():
    a, b = pp.draw("women", 500, seed=3), pp.draw("women", 500, seed=3)
    assert np.array_equal(a.perimeter, b.perimeter)
    assert not np.array_equal(a.perimeter, pp.draw("women", 500, seed=4).perimeter)
    assert any("ASSUMED fingertip depth" in s for s in a.describe()["assumptions"])
    ratio = a.depth / a.width
    assert ratio.min() >= 0.7 - 1e-9 and ratio.max() <= 1.0 + 1e-9
    men = pp.draw("men", 2000, seed=0)
    assert np.median(men.width) > np.median(pp.draw("women", 2000, seed=0).width)


def test_bad_population_inputs():
    with pytest.raises(ParameterError, match="--population"):
        pp.draw("kids", 100)
    with pytest.raises(ParameterError, match="--fingers"):
        pp.draw("all", 3)
    with pytest.raises(ParameterError, match="depth ratio"):
        pp.DepthAssumption(lo=0.9, hi=0.8)


def test_csv_replaces_the_table(tmp_path):
    f = tmp_path / "fingers.csv"
    f.write_text("width,depth\n" + "".join(f"{14 + k * 0.5},{12 + k * 0.4}\n" for k in range(8)))
    p = pp.from_csv(f)
    assert p.size == 8 and p.group == "csv"
    assert not any("ASSUMED fingertip depth" in s for s in p.assumptions)
    g = tmp_path / "nodepth.csv"
    g.write_text("width,length\n15,25\n")
    with pytest.raises(DataError, match="missing column.*depth"):
        pp.from_csv(g)
    h = tmp_path / "girth.csv"
    h.write_text("width,depth,perimeter\n" + "15,13,45\n" * 5 + "15,13,90\n")
    with pytest.raises(DataError, match="perimeter=90 on row 6"):
        pp.from_csv(h)


# ----------------------------------------------------------------------------------- sizes

from designlab.sensors.strap import sizes as sz  # noqa: E402
from designlab.sensors.strap.fit import default_target  # noqa: E402


@pytest.fixture(scope="module")
def women():
    import designlab.geometry.strap  # noqa: F401  (the CAD import, once per module)

    return pp.draw("women", 1000, seed=0)


def test_auto_picks_the_fewest_sizes_meeting_its_rule(women):
    target = default_target()
    n, tried = sz.auto_count(women, target)
    assert tried[-1]["sizes"] == n and tried[-1]["share_within_goal"] >= sz.GOAL_SHARE
    assert all(r["share_within_goal"] < sz.GOAL_SHARE for r in tried[:-1])
    sizes, _ = sz.partition(women, n, target)
    assert sz.share_within(women, sizes) >= sz.GOAL_SHARE
    # every finger in exactly one size, each strap cut for its median finger
    assert sorted(np.concatenate([s.members for s in sizes])) == list(range(women.size))
    for s in sizes:
        assert np.median(sz.strains(s.part, women.perimeter[s.members])) == \
            pytest.approx(target, abs=2e-3)


def test_spread_is_p5_p95_over_the_mean():
    eps = np.linspace(0.1, 0.3, 101)
    assert sz.spread_percent(eps) == pytest.approx(100 * (0.29 - 0.11) / 0.2)


def test_paper_slots_on_the_reference_finger(tmp_path):
    # circles of the reference radius 9 mm: every finger on the medium slot at the target
    f = tmp_path / "ref.csv"
    f.write_text("width,depth\n" + "18,18\n" * 10)
    pop = pp.from_csv(f)
    target = default_target()
    from designlab.fem.materials import get_material

    slots = sz.paper_slots(pop, target, get_material("PI-ETPU"), None)
    assert [r["slot"] for r in slots["rows"]] == [1, 2, 3]
    mid = slots["rows"][1]
    assert mid["share"] == 1.0 and mid["initial_strain"]["p50"] == pytest.approx(target)
    assert slots["share_within_goal"] == 1.0 and slots["slack_share"] == 0.0


def test_paper_slots_take_each_finger_to_its_closest_slot(women):
    from designlab.fem.materials import get_material

    slots = sz.paper_slots(women, 0.1, get_material("PI-ETPU"), 0.03)
    assert sum(r["share"] for r in slots["rows"]) == pytest.approx(1.0)
    for r in slots["rows"]:
        if r["fingers"]:
            f = r["sum_F_n_V_per_N"]
            assert f["p5"] <= f["p50"] <= f["p95"]


def test_size_table_without_fem(women):
    res = sz.strap_sizes(women, sz.SizesRequest(sizes=3), fem=False)
    rows = res["size_table"]
    assert [r["size"] for r in rows] == [1, 2, 3]
    assert sum(r["share"] for r in rows) == pytest.approx(1.0)
    assert all(r["sum_F_n_V_per_N"] is None for r in rows)
    assert any("ASSUMED fingertip depth" in a for a in res["assumptions"])
    lo = [r["perimeter_range_mm"][0] for r in rows]
    assert lo == sorted(lo)
    assert "| size 1 |" in sz.markdown(res) and "| slot 2 |" in sz.markdown(res)


@pytest.mark.parametrize("bad, match", [(0, "--sizes"), (41, "--sizes"), ("x", "--sizes")])
def test_bad_size_counts(bad, match):
    with pytest.raises(ParameterError, match=match):
        sz.SizesRequest(sizes=bad).count()


@pytest.mark.parametrize("args, name", [
    (["--sizes", "0"], "--sizes"), (["--sizes", "many"], "--sizes"),
    (["--population", "kids"], "--population"), (["--fingers", "3"], "--fingers"),
    (["--fit-by", "girth"], "--fit-by"), (["--target-strain", "2"], "--target-strain"),
    (["--seed", "-1"], "--seed"),
    (["--fingers-csv", "MISSING"], "--fingers-csv"), (["--pulp-model", "p7"], "--pulp-model")])
def test_cli_bad_input_is_one_line_exit_2_nothing_written(tmp_path, run_cli, args, name):
    if "MISSING" in args:
        f = tmp_path / "f.csv"
        f.write_text("width,length\n15,25\n")
        args = [a if a != "MISSING" else f for a in args]
    out = tmp_path / "out"
    rc, _, err = run_cli(["strap-sizes", *args, "--out", out])
    assert rc == 2
    assert name in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.slow
def test_cli_writes_the_sizes_and_their_3mf(tmp_path, run_cli):
    out = tmp_path / "s"
    rc, _, err = run_cli(["strap-sizes", "--population", "men", "--sizes", "2", "--fingers", "200",
                       "--out", out])
    assert rc == 0, err
    import json

    doc = json.loads((out / "sizes.json").read_text())
    assert doc["sizes"] == 2 and len(doc["paper_slots"]["rows"]) == 3
    assert all(r["sum_F_n_V_per_N"]["p50"] > 0 for r in doc["size_table"])
    assert (out / "size_1" / "size_1.3mf").is_file() and (out / "size_2" / "size_2.3mf").is_file()
    assert (out / "run.json").is_file() and (out / "sizes.md").is_file()
    pm = doc["pulp_model"]                   # the hyperelastic pulp at the p50 finger
    assert pm["computed"] and [r["percentile"] for r in pm["fingers"]] == [50]
    band = pm["fingers"][0]["band"]["hyperelastic_over_present"]
    assert 0 < band["min"] <= band["max"] < 2 and pm["assumptions"]
    assert "## The pulp model" in (out / "sizes.md").read_text()


# ---------------------------------------------------------------- predict strap --finger

def test_wearer_settings_map_the_finger_like_fit_strap():
    from designlab.sensors.strap.fit import Finger, REFERENCE_RADIUS
    from designlab.sensors.strap.wearer import wearer_settings

    s, note = wearer_settings("strap", "16,14,25", {}, {"edge_length": "2.0"})
    assert s["finger_radius"] == pytest.approx(Finger(16, 14, 25).equivalent_radius, abs=1e-4)
    assert s["edge_length"] == "2.0" and s["slot"] == 3 and "slot 3" in note
    d = 2 * REFERENCE_RADIUS                 # the reference finger wears the medium slot
    assert wearer_settings("strap", f"{d},{d},25", {}, {})[0]["slot"] == 2
    assert "slot" not in wearer_settings("strap", "16,14,25", {}, {"wrap_length": "60"})[0]


@pytest.mark.parametrize("part, finger, setting", [
    ("fingertip", "16,14,25", []), ("strap", "16,14", []),
    ("strap", "16,14,25", ["--setting", "finger_radius=8"]), ("strap", "nope.stl", [])])
def test_predict_finger_bad_input_exit_2(tmp_path, run_cli, part, finger, setting):
    # (a finger outside the wrap model's range is refused by fit.Finger, naming the size)
    out = tmp_path / "p"
    rc, _, err = run_cli(["predict", part, "--finger", finger, *setting, "--out", out])
    assert rc == 2 and "--finger" in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_vectorised_sensitivity_factor_is_the_models():
    from designlab.fem.materials import get_material
    from designlab.sensors.strap.prestrain import neo_hooke, operating_point

    mat = get_material("PI-ETPU")
    eps = np.array([-0.05, 0.0, 0.05, 0.17, 0.3])
    got = sz.sensitivity_factor(eps, 1800.0, mat)
    for e, f in zip(eps, got):
        want = 1.0 if e <= 0 else operating_point(
            e, 1800.0, mat.gauge_factor, mat.gauge_quadratic, sz.DIVIDER_OHM)[
            "electrical_factor"] / neo_hooke(e)["tangent_over_E"]
        assert f == pytest.approx(want, rel=1e-12)
