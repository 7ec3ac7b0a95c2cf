"""Files written as a set (designlab.atomic.FileSet): all in place, or, when one cannot be
written (a full disk), none changed and no temporary file left."""

from __future__ import annotations

import os
import subprocess

import pytest

from designlab.atomic import TEMP_NAME, FileSet, sweep_temps
from designlab.errors import OutputError


def test_a_set_that_does_not_fit_leaves_the_previous_set(tmp_path):
    """On a real full file system (a 64 kB tmpfs, as root) the third file does not fit: the
    first two keep their previous contents and no temporary file is left."""
    disk = tmp_path / "disk"
    disk.mkdir()
    if subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", str(disk)],
                      capture_output=True).returncode != 0:
        pytest.skip("needs root to mount a tmpfs (disk_full_at covers the rest)")
    try:
        for name in ("a.json", "b.png"):
            (disk / name).write_bytes(b"old")
        with pytest.raises(OutputError, match="c.html: no space left on the device"):
            with FileSet() as fs:
                fs.write_json(disk / "a.json", {"x": 1})
                fs.write_bytes(disk / "b.png", b"new")
                fs.write_bytes(disk / "c.html", b"x" * 200_000)
        assert sorted(p.name for p in disk.iterdir()) == ["a.json", "b.png"]
        assert (disk / "a.json").read_bytes() == b"old" == (disk / "b.png").read_bytes()
    finally:
        subprocess.run(["umount", str(disk)], capture_output=True)


def test_a_committed_set_is_in_place_and_a_killed_one_is_swept(tmp_path):
    with FileSet() as fs:
        fs.write_json(tmp_path / "a.json", {"x": float("nan")})
        tmp = fs.path(tmp_path / "b.html")
        tmp.write_bytes(b"<html>")
        assert TEMP_NAME.match(tmp.name) and fs.targets() == [tmp_path / "a.json",
                                                                tmp_path / "b.html"]
    assert (tmp_path / "a.json").read_text() == '{\n "x": null\n}'
    assert (tmp_path / "b.html").read_bytes() == b"<html>"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.json", "b.html"]
    # the temporaries of a writer killed before its commit: removed by sweep_temps
    dead = tmp_path / f".c.{2 ** 22 + 12345}.abcdefgh.tmp.json"
    dead.write_bytes(b"{}")
    assert sweep_temps(tmp_path) == [dead]


def test_an_empty_file_or_a_folder_in_the_way_aborts_the_set(tmp_path):
    (tmp_path / "b.png").mkdir()
    with pytest.raises(OutputError, match="b.png: it is a directory"):
        with FileSet() as fs:
            fs.write_bytes(tmp_path / "a.json", b"{}")
            fs.write_bytes(tmp_path / "b.png", b"png")
    assert [p.name for p in tmp_path.iterdir()] == ["b.png"]   # a.json not moved either
    with pytest.raises(OutputError, match="empty file"):
        with FileSet() as fs:
            fs.path(tmp_path / "c.json")
    assert os.listdir(tmp_path) == ["b.png"]


def test_an_aborted_set_removes_the_folders_it_made_and_no_other(tmp_path):
    """A failed set leaves no empty --out behind: the folders made for it go, a folder that
    was there or holds another file stays."""
    from designlab.atomic import FileSet

    (tmp_path / "kept").mkdir()
    fs = FileSet()
    fs.write_bytes(tmp_path / "new" / "deep" / "a.json", b"{}")
    fs.write_bytes(tmp_path / "kept" / "b.json", b"{}")
    fs.write_bytes(tmp_path / "other" / "c.json", b"{}")
    (tmp_path / "other" / "theirs.txt").write_text("x")     # written meanwhile by another
    fs.abort()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["kept", "other"]
    assert [p.name for p in (tmp_path / "other").iterdir()] == ["theirs.txt"]
    assert list((tmp_path / "kept").iterdir()) == []
