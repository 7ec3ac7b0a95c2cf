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


@pytest.mark.slow
@pytest.mark.parametrize("full", ["uncertainty", "report"])
def test_a_monte_carlo_summary_and_its_report_are_written_together(full, tmp_path, capsys,
                                                                   disk_full_at):
    """A full disk while writing uncertainty.json or its report.html leaves neither (the
    summary stood without its report): one line, exit 2, no temporary file; the sample files
    stay and a rerun with room resumes from them and writes both."""
    out = tmp_path / "mc"
    argv = ["predict", "flexure", "--samples", "2", "--workers", "1", "--out", str(out)]
    refused = disk_full_at(rf"^\.+{full}\.")
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert refused and e.value.code == 2 and "no space left" in capsys.readouterr().err
    top = sorted(p.name for p in out.iterdir())
    assert "uncertainty.json" not in top and "report.html" not in top, top
    assert not [n for n in top if ".tmp" in n] and (out / "samples").is_dir(), top
    disk_full_at("^$")       # room again
    main(argv)
    assert (out / "uncertainty.json").is_file() and (out / "report.html").is_file()


@pytest.mark.slow
@pytest.mark.parametrize("name", ["report.html", "design.png", "run.json", "prediction.json"])
def test_a_folder_by_an_output_name_stops_predict_before_anything_moves(name, tmp_path, capsys):
    """A folder in --out by the name of one of predict's files: one line naming that file,
    exit 2, and --out as it was (it named --out itself and left the files moved before it)."""
    out = tmp_path / "o"
    (out / name).mkdir(parents=True)
    with pytest.raises(SystemExit) as e:
        main(["predict", "flexure", "--out", str(out)])
    err = capsys.readouterr().err
    assert e.value.code == 2 and err.count("error:") == 1
    assert f"cannot write {out / name}: it is a directory" in err, err
    assert sorted(p.name for p in out.iterdir()) == [name]
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".")]


@pytest.mark.slow
def test_a_full_disk_while_predicting_names_the_file_in_out(tmp_path, capsys, disk_full_at):
    """The message names --out's file, not the hidden staging folder it was written in first;
    nothing is left beside or in --out."""
    out = tmp_path / "o"
    refused = disk_full_at(r"^\.+prediction\.")
    with pytest.raises(SystemExit) as e:
        main(["predict", "flexure", "--out", str(out)])
    err = capsys.readouterr().err
    assert refused and e.value.code == 2 and err.count("error:") == 1, err
    assert f"{out / 'prediction.json'}" in err and "staging" not in err, err
    assert not out.exists() and not list(tmp_path.iterdir())
