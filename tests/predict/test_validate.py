"""``designlab validate``: each sensor beside its paper. The fingertip's goals are the numbers
``designlab predict fingertip`` used to write under ``paper_comparison`` (the expected values
below are that prediction.json's, default design and settings), the strap's and the flexure's
the same numbers as their predictions; the json and the report written; bad input is one line,
exit 2, nothing written."""

from __future__ import annotations

import json
import re

import pytest

from designlab.predict.validate import ALL, report_markdown, sensors_for, validated_sensors

#: the goals of the default fingertip's paper comparison (default design and settings), as
#: ``designlab validate`` reads them from its prediction (``paper_comparison``:
#: ``contact.goals.*``, ``contact.compressed_change_r1_to_r5``, ``contact.table_III_design``)
FINGERTIP_GOALS = {
    "G1 hysteresis h1 / h9": 2.881,                         # h1_over_h9_mean_of_draws
    "lowest mean G1 hysteresis": 1.464048330578291,        # value_with_readout_mean_of_draws_pct
    "lowest mean G2 hysteresis": 4.584323798259176,
    "compressed-sensor change h9 -> h1, of the first span": 102.97909105156653,
    "compressed-sensor change h9 -> h1, of the applied force": 46.45,
    "compressed-sensor change r1 -> r5, of the first span": 750.5864882537038,
    "P_z relative error over the x/y errors": 0.7752,
    "condition number (Table III design)": 8.24145835237604,
    "lateral load direction error at the heaviest weight": 1.329047561323254,
    "radial force relative error": 0.454978136053543,       # relative_error_per_axis x
}
#: the met flags of the same prediction's goals (and of its sentences: cond(A), radial, rotation)
FINGERTIP_MET = {"G1 hysteresis h1 / h9": True, "lowest mean G1 hysteresis": True,
                 "lowest mean G2 hysteresis": False,
                 "compressed-sensor change h9 -> h1, of the first span": False,
                 "compressed-sensor change h9 -> h1, of the applied force": True,
                 "P_z relative error over the x/y errors": False,
                 "condition number (Table III design)": False}
#: ``designlab predict strap`` / ``predict flexure`` (defaults): prediction.json ->
#: electrical.resistance_at_rest_ohm; force_error_test.per_axis.x.std
STRAP_RESISTANCE_OHM = 1799.9999999999998
FLEXURE_FORCE_STD_X_N = 0.25010855930996445


@pytest.fixture(scope="module")
def validated(tmp_path_factory):
    from designlab.predict.validate import validate

    out = tmp_path_factory.mktemp("validate")
    return out, validate(ALL, out)


def _goal(section: dict, prefix: str) -> dict:
    (g,) = [g for g in section["goals"] if g["name"].startswith(prefix)]
    return g


@pytest.mark.slow
def test_fingertip_goals_are_the_old_predictions_paper_comparison(validated):
    _, data = validated
    ft = data["fingertip"]
    for prefix, value in FINGERTIP_GOALS.items():
        assert _goal(ft, prefix)["value"] == value, prefix
    for prefix, met in FINGERTIP_MET.items():
        assert _goal(ft, prefix)["met"] is met, prefix
    pc = ft["details"]["paper_comparison"]
    assert pc["condition_number_predicted"] == 8.24145835237604
    assert pc["condition_number_paper"] == 34.92
    assert set(pc["contact"]["goals"]) == {"G1_falls_monotonically_h1_to_h9", "lowest_mean_G1",
                                           "lowest_mean_G2", "compressed_change_h9_to_h1",
                                           "Pz_error_over_xy"}
    assert pc["contact"]["table_II_design"]["base_below_ball_centre_mm"] == pytest.approx(25.43)
    assert pc["contact"]["matches"] and pc["contact"]["does_not_match"]
    for g in ft["goals"]:
        assert g["why"].endswith(".") and not re.search(r"\. [A-Z]", g["why"]), g["name"]


@pytest.mark.slow
def test_strap_and_flexure_goals_read_their_predictions_numbers(validated):
    _, data = validated
    assert _goal(data["strap"], "gauge resistance")["value"] == STRAP_RESISTANCE_OHM / 1e3
    assert data["strap"]["details"]["electrical"]["resistance_at_rest_ohm"] == \
        STRAP_RESISTANCE_OHM
    assert _goal(data["flexure"], "force error std, x")["value"] == FLEXURE_FORCE_STD_X_N
    assert _goal(data["flexure"], "force error std, x")["paper"] == 0.30461   # Table I
    diag = _goal(data["flexure"], "mean |error| over the measured diagonal, the beam chain at")
    assert diag["met"] is True and 12 < diag["value"] < 13.5


@pytest.mark.slow
def test_the_json_and_the_report_written(validated):
    out, data = validated
    doc = json.loads((out / "validation.json").read_text())
    assert doc["format"] == "designlab-validation" and doc["sensors"] == data
    assert list(data) == validated_sensors()
    for section in data.values():
        assert section["goals"] and section["paper"]
        for g in section["goals"]:
            assert set(g) == {"name", "value", "paper", "target", "met", "why"}
    md = (out / "validation.md").read_text()
    assert md == report_markdown(data)
    assert "![paper_comparison.png](paper_comparison.png)" in md
    assert (out / "paper_comparison.png").stat().st_size > 10_000
    assert not [p for p in out.iterdir() if p.name.startswith(".")]      # no temporary left


def test_names_are_checked_before_anything_runs():
    from designlab.errors import ParameterError

    assert sensors_for(ALL) == validated_sensors() and len(validated_sensors()) >= 3
    assert sensors_for(validated_sensors()[0]) == validated_sensors()[:1]
    with pytest.raises(ParameterError, match="sensor='wing'"):
        sensors_for("wing")


def test_cli_bad_input_is_one_line_exit_2_nothing_written(tmp_path, capsys):
    from designlab.cli import main

    a_file = tmp_path / "file"
    a_file.write_text("x")
    for argv, needle in ((["validate", "wing", "--out", str(tmp_path / "a")], "sensor='wing'"),
                         (["validate", "fingertips", "--out", str(tmp_path / "b")], "sensor="),
                         (["validate", ALL, "--out", str(a_file)], "--out"),
                         (["validate", ALL], "--out")):
        with pytest.raises(SystemExit) as e:
            main(argv)
        assert e.value.code == 2, argv
        err = capsys.readouterr().err.strip()
        assert needle in err and "Traceback" not in err and "\n" not in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


@pytest.mark.slow
def test_cli_writes_the_run_folder_and_prints_the_goals(tmp_path, capsys):
    from designlab.cli import main

    name = [n for n in validated_sensors() if n == "flexure"][0]
    main(["validate", name, "--out", str(tmp_path)])
    printed = capsys.readouterr().out
    assert "flexure: seed 002" in printed and printed.count("yes") >= 3   # the met goals
    doc = json.loads((tmp_path / "validation.json").read_text())
    assert list(doc["sensors"]) == [name]
    run = json.loads((tmp_path / "run.json").read_text())
    assert run["what"] == f"validate {name}"
    assert (tmp_path / "validation.md").is_file()
