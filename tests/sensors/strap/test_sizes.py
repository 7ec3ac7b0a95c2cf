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
