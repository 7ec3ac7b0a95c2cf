"""The output folder's one-writer lock leaves nothing behind (issue: an empty --out holding only
``.designlab.lock`` after a refused input)."""
import subprocess
import sys
import textwrap

import pytest

from designlab.atomic import LOCK_NAME, out_lock
from designlab.errors import DesignlabError


def test_a_folder_the_lock_made_and_nothing_filled_is_removed(tmp_path):
    out = tmp_path / "new" / "out"
    with out_lock(out):
        assert (out / LOCK_NAME).exists()
    assert not out.exists() and (tmp_path / "new").is_dir()


def test_a_folder_with_results_keeps_them_and_loses_the_lock(tmp_path):
    out = tmp_path / "out"
    with out_lock(out):
        (out / "prediction.json").write_text("{}")
    assert sorted(p.name for p in out.iterdir()) == ["prediction.json"]


def test_an_existing_empty_folder_stays(tmp_path):
    with out_lock(tmp_path):
        pass
    assert tmp_path.is_dir() and list(tmp_path.iterdir()) == []


def test_nested_holders_release_once(tmp_path):
    out = tmp_path / "out"
    with out_lock(out):
        with out_lock(out):
            pass
        assert (out / LOCK_NAME).exists()  # the outer holder still holds it
    assert not out.exists()


def test_a_live_holder_refuses_and_its_release_lets_the_next_in(tmp_path):
    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys
        from designlab.atomic import out_lock
        with out_lock({str(out)!r}, "designlab sweep"):
            (__import__("pathlib").Path({str(out)!r}) / "row").write_text("x")
            print("held", flush=True)
            sys.stdin.readline()
        """)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(DesignlabError, match=rf"in use by pid {holder.pid}"):
            out_lock(out).acquire()
        holder.stdin.write("\n")
        holder.stdin.flush()
        assert holder.wait(30) == 0
    finally:
        holder.kill()
        holder.wait()
    assert not (out / LOCK_NAME).exists()
    with out_lock(out):
        assert (out / LOCK_NAME).exists()
    assert (out / "row").exists()


def test_predict_and_export_refuse_an_out_another_run_is_writing(tmp_path, capsys):
    """A second predict or export into the --out of a running one is refused (it replaced the
    first run's files silently)."""
    from designlab.cli import main

    out = tmp_path / "out"
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys
        from designlab.atomic import out_lock
        with out_lock({str(out)!r}, "designlab predict flexure"):
            print("held", flush=True)
            sys.stdin.readline()
        """)], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        for argv in (["predict", "flexure"], ["export", "flexure", "--format", "stl",
                                               "--no-png"]):
            with pytest.raises(SystemExit) as e:
                main([*argv, "--out", str(out)])
            assert e.value.code == 2
            assert f"in use by pid {holder.pid}" in capsys.readouterr().err
        assert sorted(p.name for p in out.iterdir()) == [LOCK_NAME]
    finally:
        holder.stdin.write("\n")
        holder.stdin.flush()
        holder.wait(30)
