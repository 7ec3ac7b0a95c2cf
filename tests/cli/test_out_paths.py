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
