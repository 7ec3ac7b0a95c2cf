"""--out values that are no usable folder: one line, exit 2, before any work, nothing written."""

from __future__ import annotations

import os

import pytest

from designlab.cli import main


@pytest.mark.parametrize("argv", [["--out", ""], ["--out="], ["--out", "  "]])
def test_an_empty_out_is_refused_not_the_working_folder(argv, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main(["mesh", "fingertip", *argv])
    assert e.value.code == 2 and "--out=" in capsys.readouterr().err
    assert not os.listdir(tmp_path)


@pytest.mark.parametrize("make", [lambda d: "a" * 300, lambda d: f"x/{'b' * 300}/y",
                                  lambda d: "/".join(["c" * 200] * 25)])
def test_an_out_longer_than_the_system_allows_is_one_line(make, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(SystemExit) as e:
        main(["mesh", "fingertip", "--out", make(tmp_path)])
    err = capsys.readouterr().err
    assert e.value.code == 2 and "file name too long" in err and "internal" not in err
    assert not os.listdir(tmp_path)


def test_a_monte_carlo_report_that_cannot_be_written_takes_its_summary_with_it(
        tmp_path, capsys, monkeypatch):
    """On a full disk uncertainty.json stood without its report.html: now neither (the sample
    files stay, a rerun resumes from them)."""
    from designlab.errors import OutputError
    from designlab.optimize import montecarlo
    from designlab.predict import report, uncertainty

    out = tmp_path / "mc"

    def fake_monte_carlo(part, spec, out_dir, **kw):
        (out_dir / "samples").mkdir(parents=True)
        (out_dir / "samples" / "k.000000.json").write_text("{}")
        (out_dir / "uncertainty.json").write_text("{}")
        return {"ok": 2, "failed": 0, "fem": {"solves_this_run": 0}, "failed_errors": {}}

    def full_disk(out_dir, summary, **kw):
        raise OutputError(f"cannot write {out_dir / 'report.html'}: no space left on the device")

    monkeypatch.setattr(montecarlo, "monte_carlo", fake_monte_carlo)
    monkeypatch.setattr(uncertainty, "summary_rows", lambda s: [])
    monkeypatch.setattr(report, "write_uncertainty_report", full_disk)
    with pytest.raises(SystemExit) as e:
        main(["predict", "flexure", "--samples", "2", "--workers", "1", "--out", str(out)])
    assert e.value.code == 2 and "no space left" in capsys.readouterr().err
    assert sorted(p.name for p in out.rglob("*")) == ["k.000000.json", "samples"]
