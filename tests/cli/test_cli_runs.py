"""What the command line does with a run's folder and what it tells the user: ``--out`` that
holds another run is refused (one line, exit 2) unless ``--overwrite``; every writing command
leaves ``run.json``; a sweep resumes its own config; shell completion offers the sensors; the
commands end with what to open next. Cheap: sweeps use the analytic evaluator."""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pandas as pd
import pytest

from conftest import ROOT
from designlab.cli import main

CFG_A = ('part = "fingertip"\nmethod = "grid"\n[parameters]\n'
         'h = { range = [0.0, 2.0], levels = 2 }\nr = { range = [6.0, 8.0], levels = 2 }\n'
         '[objectives]\ncondition_number = "min"\n')
CFG_B = CFG_A.replace("levels = 2 }\nr", "levels = 3 }\nr").replace("[6.0, 8.0]", "[7.0, 9.0]")


@pytest.fixture
def cheap_sweeps(monkeypatch, tmp_path):
    """Sweeps through the CLI with the analytic evaluator (no FEM); two configs on disk."""
    from sweep_fixtures import quadratic

    import designlab.optimize.sweep as sw

    monkeypatch.setattr(sw, "default_evaluator", quadratic)
    monkeypatch.setenv("DESIGNLAB_LOG_DIR", str(tmp_path / "logs"))
    a, b = tmp_path / "a.toml", tmp_path / "b.toml"
    a.write_text(CFG_A)
    b.write_text(CFG_B)
    return a, b


def _run(args, capsys):
    """(exit code, stdout, stderr) of ``designlab ARGS``."""
    try:
        main([str(x) for x in args])
        rc = 0
    except SystemExit as exc:
        rc = exc.code
    cap = capsys.readouterr()
    return rc, cap.out, cap.err


def _keys(out: Path) -> set[str]:
    return set(pd.read_parquet(out / "results.parquet")["key"])


@pytest.mark.slow
def test_sweep_refuses_another_config_and_resumes_its_own(cheap_sweeps, tmp_path, capsys):
    a, b = cheap_sweeps
    out = tmp_path / "out"
    rc, so, _ = _run(["sweep", a, "--out", out, "--workers", "1"], capsys)
    assert rc == 0 and "open next:" in so
    run = json.loads((out / "run.json").read_text())
    assert run["what"] == "sweep" and run["identity"] and run["settings"]["config"] == str(a)
    keys_a = _keys(out)
    assert len(keys_a) == 4
    # the same config again resumes (nothing new), and optimize of it may share the folder
    rc, so, _ = _run(["sweep", a, "--out", out, "--workers", "1"], capsys)
    assert rc == 0 and "0 evaluated, 4 from the store" in so
    # another config: one line, exit 2, nothing of it written
    before = sorted(p.name for p in (out / "results").iterdir())
    rc, so, se = _run(["sweep", b, "--out", out, "--workers", "1"], capsys)
    assert rc == 2
    assert se.count("\n") == 1 and se.startswith("error: --out=")
    assert "holds another run" in se and "--overwrite" in se
    assert sorted(p.name for p in (out / "results").iterdir()) == before
    assert _keys(out) == keys_a
    # --overwrite replaces the rows: only config B's designs remain
    rc, so, _ = _run(["sweep", b, "--out", out, "--workers", "1", "--overwrite"], capsys)
    assert rc == 0
    keys_b = _keys(out)
    assert len(keys_b) == 6 and not keys_b & keys_a
    assert json.loads((out / "run.json").read_text())["settings"]["config"] == str(b)


def test_other_commands_refuse_a_sweep_folder(cheap_sweeps, tmp_path, capsys):
    a, _ = cheap_sweeps
    out = tmp_path / "out"
    assert _run(["sweep", a, "--out", out, "--workers", "1"], capsys)[0] == 0
    listing = sorted(p.name for p in out.iterdir())
    for args in (["predict", "fingertip"], ["export", "fingertip", "--format", "stl"]):
        rc, _, se = _run([*args, "--out", out], capsys)
        assert rc == 2 and "holds another run" in se and se.count("\n") == 1, args
    assert sorted(p.name for p in out.iterdir()) == listing


@pytest.mark.slow
def test_export_writes_run_json_and_says_what_to_open(tmp_path, capsys):
    out = tmp_path / "e"
    rc, so, _ = _run(["export", "flexure", "--format", "3mf", "--out", out], capsys)
    assert rc == 0
    run = json.loads((out / "run.json").read_text())
    assert run["what"] == "export flexure" and run["settings"]["formats"] == "3mf"
    assert "wire_diameter" in run["settings"]["parts"]["flexure"] or run["settings"]["parts"]["flexure"]
    nxt = [ln for ln in so.splitlines() if ln.startswith("open next:")]
    assert nxt and "flexure.3mf" in nxt[0] and "slicer" in nxt[0], so
    # the same export again is allowed, and so is another part's (its own subfolder)
    assert _run(["export", "flexure", "--format", "3mf", "--out", out], capsys)[0] == 0
    assert _run(["export", "strap", "--format", "3mf", "--no-png", "--out", out], capsys)[0] == 0
    assert (out / "strap" / "strap.3mf").is_file() and (out / "flexure" / "flexure.3mf").is_file()
    assert json.loads((out / "run.json").read_text())["what"] == "export strap"
    # a predict into an export folder is another command: refused before any work
    rc, _, se = _run(["predict", "flexure", "--out", out], capsys)
    assert rc == 2 and "holds another run" in se
    assert not (out / "prediction.json").exists()


def test_a_folder_without_run_json_is_used_as_it_is(tmp_path, capsys):
    out = tmp_path / "e"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    rc, _, _ = _run(["export", "flexure", "--format", "stl", "--no-png", "--out", out], capsys)
    assert rc == 0 and (out / "notes.txt").read_text() == "mine"


@pytest.mark.slow
def test_shell_completion_offers_the_sensors(tmp_path):
    """The real completion protocol (bash), as the shell calls it."""
    from designlab.sensors.registry import BUILT_IN, SENSORS, known_names

    exe = Path(sys.executable).with_name("designlab")
    env = {**os.environ, "_DESIGNLAB_COMPLETE": "complete_bash", "COMP_WORDS": "designlab predict ",
           "COMP_CWORD": "2"}
    got = subprocess.run([str(exe)], env=env, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path).stdout.split()
    # the built-in three, and the definitions this process registered that the child finds
    assert set(BUILT_IN) <= set(got) <= set(SENSORS) | set(known_names())
    env.update(COMP_WORDS="designlab export f")
    got = subprocess.run([str(exe)], env=env, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path).stdout.split()
    assert got and all(n.startswith("f") for n in got) and "fingertip" in got
    env.update(COMP_WORDS="designlab export a")
    got = subprocess.run([str(exe)], env=env, capture_output=True, text=True, timeout=120,
                         cwd=tmp_path).stdout.split()
    assert got == ["all"]


def test_show_all_is_refused_with_the_sensor_names(tmp_path, capsys):
    from designlab.sensors.registry import SENSORS

    rc, _, se = _run(["show", "all", "--out", tmp_path / "x.png"], capsys)
    assert rc == 2 and all(n in se for n in SENSORS)


def test_mesh_quality_option_has_the_settings_name():
    """``--mesh-quality`` (the FEMSettings name; ``--quality`` kept as an alias); the loop's
    --base help names the load-arm form."""
    import typer.main

    from designlab.cli.app import app

    cmds = typer.main.get_command(app).commands
    opts = {o for p in cmds["mesh"].params for o in p.opts}
    assert {"--mesh-quality", "--quality"} <= opts
    base = next(p for p in cmds["loop"].params if "--base" in p.opts)
    assert "load-arm[:LOAD,ARM[,ANGLE]]" in base.help


def test_every_part_parameter_has_a_meaning(capsys):
    """``designlab params PART`` explains every field: a non-empty meaning for each, and a unit
    or the allowed choices."""
    from designlab.geometry.api import field_rows
    from designlab.geometry.parts import PARTS

    for name, cls in PARTS.items():
        rows = field_rows(cls)
        assert rows
        empty = [r["name"] for r in rows if not r["meaning"].strip()]
        assert not empty, f"{name}: no meaning for {empty}"
        for r in rows:
            assert r["unit"] or r["allowed"], (name, r["name"])
        rc, so, _ = _run(["params", name], capsys)
        assert rc == 0 and rows[0]["name"] in so


@pytest.mark.slow
def test_flexure_reports_the_wire_stress_and_what_next(tmp_path, capsys):
    """The flexure's mesh-free models give the wire stress (Wahl): predict and flexure print it
    (CLI, prediction.json, report), and predict names deformed.vtu only when it wrote one."""
    out = tmp_path / "p"
    rc, so, _ = _run(["predict", "flexure", "--out", out], capsys)
    assert rc == 0
    text = " ".join(so.split())
    assert "not computed" not in text and "smallest safety factor" in text
    nxt = [ln for ln in so.splitlines() if ln.startswith("open next:")]
    assert nxt and "report.html" in nxt[0]
    assert ("deformed.vtu" in nxt[0]) == (out / "deformed.vtu").is_file()
    assert "Not computed for this design" not in (out / "report.html").read_text()
    stress = json.loads((out / "prediction.json").read_text())["stress"]
    assert 2 < stress["min_safety_factor"] < 10
    rc, so, _ = _run(["flexure", "--json", tmp_path / "k.json"], capsys)
    assert rc == 0
    text = " ".join(so.split())
    # `designlab flexure` computes the wire stress (closed form and beam chain) per load case
    assert "not computed" not in text and "spring wire stress" in text and "open next:" in text
    assert json.loads((tmp_path / "k.json").read_text())["stress"]["min_safety_factor"] > 2


@pytest.mark.slow
def test_flexure_with_friction_in_the_chain(tmp_path, capsys):
    """``--mu``: the beam chain's frictional 6x6 (a secant, stiffer than frictionless at the
    working load); outside 0..2 one line naming the option, exit 2."""
    rc, so, _ = _run(["flexure", "--mu", "0.3", "--json", tmp_path / "f.json"], capsys)
    assert rc == 0 and "chain with friction mu 0.3" in " ".join(so.split())
    rc, _, _ = _run(["flexure", "--json", tmp_path / "n.json"], capsys)
    f, n = (json.loads((tmp_path / k).read_text()) for k in ("f.json", "n.json"))
    assert f["chain_info"]["mu"] == 0.3 and "mu" not in n["chain_info"]
    rc, _, se = _run(["flexure", "--mu", "3"], capsys)
    assert rc == 2 and "--mu" in se and len(se.strip().splitlines()) == 1


def test_flexure_curved_only_with_the_solid_fem(capsys):
    """``--curved`` / ``--straight`` (the solid FEM's TET10) without ``--fem``: one line naming it,
    exit 2 (the curved mesh itself: tests/mesh/test_mesh_curved.py, tests/sensors/flexure/test_flexure_fem.py)."""
    for flag in ("--curved", "--straight"):
        rc, _, se = _run(["flexure", flag], capsys)
        assert rc == 2 and flag in se and "--fem" in se and len(se.strip().splitlines()) == 1


def test_sweep_identity_covers_the_config_and_the_uncertainty_table():
    """The fingerprint ``--out`` compares: the same config gives the same one; another swept
    range, setting, or Monte Carlo spec of a robust sweep gives another."""
    import dataclasses

    from designlab.cli.runs import config_identity
    from designlab.optimize.robust import load_sweep
    from designlab.optimize.space import sweep_config
    from designlab.params import load_toml

    cfg, ev = load_sweep(ROOT / "examples" / "uncertainty_sweep_flexure.toml")
    again, ev2 = load_sweep(ROOT / "examples" / "uncertainty_sweep_flexure.toml")
    assert config_identity(cfg, ev.spec) == config_identity(again, ev2.spec)
    other = dataclasses.replace(ev.spec, samples=ev.spec.samples + 1)
    assert config_identity(cfg, ev.spec) != config_identity(cfg, other)
    assert config_identity(cfg, ev.spec) != config_identity(cfg)
    a = sweep_config(load_toml(ROOT / "examples" / "sweep_fingertip_quick.toml"))
    b = dataclasses.replace(a, settings={"model": {"edge_length": 2.5}})
    assert config_identity(a) != config_identity(b)


def test_show_says_what_to_open_next(tmp_path, capsys):
    png = tmp_path / "f.png"
    rc, so, _ = _run(["show", "flexure", "--out", png, "--width", "320", "--height", "240"],
                     capsys)
    assert rc == 0 and png.is_file()
    nxt = [ln for ln in so.splitlines() if ln.startswith("open next:")]
    assert nxt and str(png) in nxt[0] and "designlab params flexure" in nxt[0]


def test_overwrite_waits_for_no_one_and_removes_nothing_of_a_running_sweep(cheap_sweeps, tmp_path,
                                                                            capsys):
    """--overwrite of a folder another process is writing: refused (the folder's lock), its
    rows untouched."""
    import textwrap
    import time

    a, b = cheap_sweeps
    out = tmp_path / "out"
    assert _run(["sweep", a, "--out", out, "--workers", "1"], capsys)[0] == 0
    keys = _keys(out)
    holder = subprocess.Popen([sys.executable, "-c", textwrap.dedent(f"""
        import sys, time
        from designlab.atomic import out_lock
        with out_lock({str(out)!r}, "designlab sweep"):
            print("held", flush=True)
            time.sleep(60)
        """)], stdout=subprocess.PIPE, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        rc, _, se = _run(["sweep", b, "--out", out, "--workers", "1", "--overwrite"], capsys)
        assert rc == 2 and "in use by" in se
        assert _keys(out) == keys and (out / "results").is_dir()
    finally:
        holder.kill()
        holder.wait()
    time.sleep(0.1)
    assert _run(["sweep", b, "--out", out, "--workers", "1", "--overwrite"], capsys)[0] == 0
    assert not _keys(out) & keys


@pytest.mark.parametrize("argv, text", [
    (["sweep", "x.toml", "--out", "o", "--bogus"], "No such option: --bogus"),
    (["predict"], "Missing argument 'part'"),
    (["sweep", "x.toml", "--out", "o", "--workers", "two"], "'--workers'"),
    (["nosuch"], "No such command 'nosuch'"),
])
def test_usage_errors_are_one_line_exit_2(argv, text, capsys):
    """The command parser's errors (typer carries its own click) are a user error: one line
    naming the option, exit 2 -- not an internal error with a log file."""
    with pytest.raises(SystemExit) as e:
        main(argv)
    err = capsys.readouterr().err.strip()
    assert e.value.code == 2
    assert text in err and "internal error" not in err and len(err.splitlines()) == 1


@pytest.mark.slow
def test_console_script_exit_runs_handlers_flushes_and_keeps_the_code():
    """``designlab`` (main() without argv) ends without the interpreter's teardown: the exit
    handlers still run, the output is complete, and the exit code is the command's."""
    import subprocess
    import sys

    prog = ("import atexit, sys; atexit.register(lambda: print('handler ran', file=sys.stderr));"
            "sys.argv = ['designlab'] + sys.argv[1:]; from designlab.cli import main; main()")
    ok = subprocess.run([sys.executable, "-c", prog, "params", "strap"], capture_output=True,
                        text=True, timeout=120)
    assert ok.returncode == 0 and "handler ran" in ok.stderr
    assert "edge_length" in ok.stdout or "strap parameters" in ok.stdout
    bad = subprocess.run([sys.executable, "-c", prog, "params", "nope"], capture_output=True,
                         text=True, timeout=120)
    assert bad.returncode == 2 and "handler ran" in bad.stderr
    assert "part='nope' is not allowed" in bad.stderr


@pytest.mark.parametrize("argv, needle", [
    # the built-in three first, then any definition this process registered
    (["predict", "fingertp", "--out", "{o}"],
     re.compile(r"part='fingertp' is not allowed: one of strap, fingertip, flexure(, \w+)* \(or "
                r"a sensor definition: FILE\.py\[:Class\] or module:Class\) \(did you mean "
                r"'fingertip'\?\)")),
    (["export", "fingrtip", "--out", "{o}"], "(did you mean 'fingertip'?)"),
    (["params", "strp"], "(did you mean 'strap'?)"),
    (["loop", "--data", str(ROOT / "examples" / "stretch_card.toml"), "--base", "stretch-fme",
      "--out", "{o}"], "or a model .json file (did you mean 'stretch-fem'?)"),
    (["predict", "fingertip", "--setting", "solver=pardso", "--out", "{o}"],
     "settings.solver='pardso' is not allowed: one of auto, direct, pardiso, cholmod, amg (did "
     "you mean 'pardiso'?)"),
    (["flexure", "--frame", "camra"], "one of spring, camera (did you mean 'camera'?)"),
    (["optimize", str(ROOT / "examples" / "sweep_fingertip_quick.toml"), "--method", "surogate",
      "--out", "{o}"], "(did you mean 'surrogate'?)"),
])
def test_a_misspelt_name_gets_the_close_one(argv, needle, tmp_path, capsys):
    """A misspelt sensor, part, loop base, setting choice or option: one line naming it, what is allowed and the close
    one, exit 2, nothing written."""
    out = tmp_path / "o"
    with pytest.raises(SystemExit) as e:
        main([a.format(o=out) for a in argv])
    err = capsys.readouterr().err
    assert e.value.code == 2 and not out.exists()
    errors = [line for line in err.splitlines() if line.startswith("error:")]
    found = needle.search(errors[0]) if isinstance(needle, re.Pattern) else needle in errors[0]
    assert len(errors) == 1 and found, errors


@pytest.mark.parametrize("toml, needle", [
    ("weigths_g = [0, 10]\n", "a parameter of HangingWeightTest: dt_s, "),
    ('preset = "optimised"\n', "one of tested, optimized (did you mean 'optimized'?)"),
])
def test_a_misspelt_protocol_key_gets_the_close_one(toml, needle, tmp_path, capsys):
    (tmp_path / "p.toml").write_text(toml)
    with pytest.raises(SystemExit) as e:
        main(["predict", "fingertip", "--protocol", str(tmp_path / "p.toml"), "--out",
              str(tmp_path / "o")])
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert e.value.code == 2 and not (tmp_path / "o").exists()
    assert len(errors) == 1 and needle in errors[0] and "(did you mean '" in errors[0]


@pytest.mark.parametrize("args, text", [
    (["optimize", "{two}", "--method", "surrogate"], "exactly one objective for method surrogate"),
    (["optimize", "{none}"], "at least one objective"),
    (["optimize", "{two}", "--method", "de"], "exactly one objective for method de"),
    (["sweep", "{a}", "--scheduler", "tcp://127.0.0.1:1"], "reachable Dask scheduler"),
    (["optimize", "{a}", "--scheduler", "tcp://127.0.0.1:1"], "reachable Dask scheduler"),
])
@pytest.mark.slow
def test_objectives_the_method_cannot_use_or_no_scheduler_write_nothing(
        args, text, cheap_sweeps, tmp_path, capsys, monkeypatch):
    """Objectives the optimiser cannot use and an unreachable scheduler are refused before
    ``run.json`` (or anything else) is written: no new folder, and a folder holding a run
    keeps every file as it was."""
    import functools

    import designlab.cli.options as options

    monkeypatch.setattr(options, "check_scheduler",   # the unreachable address fails sooner
                        functools.partial(options.check_scheduler, timeout_s=0.5))
    a, _ = cheap_sweeps
    two, none = tmp_path / "two.toml", tmp_path / "none.toml"
    two.write_text(CFG_A + 'printed_volume_mm3 = "min"\n')
    none.write_text(CFG_A.split("[objectives]")[0])
    paths = {"a": a, "two": two, "none": none}
    argv = [str(x).format(**paths) for x in args]
    out = tmp_path / "fresh"
    rc, _, se = _run([*argv, "--out", out, "--workers", "1"], capsys)
    assert rc == 2 and text in se and se.count("error:") == 1, se
    assert not out.exists()
    used = tmp_path / "used"                  # a folder of the same config's sweep
    cfg = {"a": a, "two": two, "none": none}[args[1].strip("{}")]
    assert _run(["sweep", cfg, "--out", used, "--workers", "1"], capsys)[0] == 0
    before = {p: (p.stat().st_mtime_ns, p.read_bytes()) for p in used.rglob("*") if p.is_file()}
    rc, _, se = _run([*argv, "--out", used, "--workers", "1"], capsys)
    assert rc == 2 and text in se
    assert {p: (p.stat().st_mtime_ns, p.read_bytes())
            for p in used.rglob("*") if p.is_file()} == before


def test_a_reachable_scheduler_passes_the_check():
    """The scheduler check connects to a live scheduler and lets it be."""
    distributed = pytest.importorskip("distributed")
    from designlab.cli.options import check_scheduler

    with distributed.LocalCluster(n_workers=1, processes=False, dashboard_address=None) as cl:
        check_scheduler(cl.scheduler_address)
        with distributed.Client(cl.scheduler_address) as client:   # still serving
            assert client.submit(sum, [1, 2]).result() == 3


@pytest.mark.parametrize("full", ["results", "pareto", "sensitivity", "report"])
def test_a_sweep_report_on_a_full_disk_is_all_or_nothing(full, cheap_sweeps, tmp_path, capsys,
                                                         disk_full_at):
    """The disk fills while the output set (results.parquet, pareto.png, sensitivity.png,
    report.html) is written: one line, exit 2, the previous set unchanged (none of it
    replaced), no temporary file; the store stays for the resume, which writes the set once
    there is room."""
    a = tmp_path / "two.toml"     # two objectives: a Pareto plot too
    a.write_text(CFG_A + 'printed_volume_mm3 = "min"\n')
    out = tmp_path / "out"
    assert _run(["sweep", a, "--out", out, "--workers", "1"], capsys)[0] == 0
    names = ("results.parquet", "pareto.png", "sensitivity.png", "report.html")
    before = {n: ((out / n).stat().st_ino, (out / n).read_bytes()) for n in names}
    refused = disk_full_at(rf"^\.+{full}\.")
    rc, _, se = _run(["sweep", a, "--out", out, "--workers", "1"], capsys)
    assert refused and rc == 2 and se.count("error:") == 1 and "no space left" in se, se
    assert {n: ((out / n).stat().st_ino, (out / n).read_bytes()) for n in names} == before
    assert [p.name for p in out.iterdir() if ".tmp" in p.name] == []


def _fem_writing(task):
    """The analytic design, after writing its FEM stage to the sweep's ``fem/`` (as the real
    evaluator does): a full disk fails that write."""
    from designlab.atomic import atomic_write_bytes
    from sweep_fixtures import quadratic

    atomic_write_bytes(Path(task["fem_cache"]) / f"{task['key']}.npz", b"stage")
    return quadratic(task)


@pytest.mark.parametrize("cmd", [["sweep"], ["optimize", "--method", "pareto"]])
def test_a_design_on_a_full_disk_stops_the_run_and_is_not_stored_failed(
        cmd, cheap_sweeps, tmp_path, capsys, monkeypatch, disk_full_at):
    """A design whose FEM stage cannot be written (no space left) did not fail for a reason of
    its own: the run stops with exit 2 and one line naming the file and the full disk (not
    "constraints that no design satisfies"), stores no row for it and writes no table or
    report; once there is room, the same command evaluates every design."""
    import designlab.cli.sweep as cli_sweep
    import designlab.optimize.optimizer as opt
    import designlab.optimize.sweep as sw

    monkeypatch.setattr(sw, "default_evaluator", _fem_writing)
    monkeypatch.setattr(opt, "default_evaluator", _fem_writing)   # its own name for it
    monkeypatch.setattr(cli_sweep, "_export_chosen", lambda *a, **k: [])   # no FEM here
    a, _ = cheap_sweeps
    a.write_text(CFG_A + 'printed_volume_mm3 = "min"\n')
    out = tmp_path / "out"
    refused = disk_full_at(r"\.npz$")
    rc, so, se = _run([*cmd, a, "--out", out, "--workers", "1"], capsys)
    assert refused and rc == 2, (rc, so, se)
    lines = [x for x in se.splitlines() if x.startswith("error:")]
    assert len(lines) == 1 and "no space left" in lines[0] and ".npz" in lines[0], se
    assert "constraints" not in se and "failed" not in so
    assert not (out / "results.parquet").exists() and not (out / "report.html").exists()
    assert not list((out / "results").glob("*.parquet")) if (out / "results").exists() else True
    disk_full_at("^$")       # room again
    rc, so, se = _run([*cmd, a, "--out", out, "--workers", "1"], capsys)
    assert rc == 0, se
    rows = pd.read_parquet(out / "results.parquet")
    assert len(rows) == 4 and (rows["status"] == "ok").all()
    if cmd == ["sweep"]:
        assert "4 evaluated, 0 from the store, 0 failed" in so


def test_a_design_stored_failed_for_a_full_disk_is_evaluated_again(cheap_sweeps, tmp_path,
                                                                    capsys):
    """A row an older run stored with a full-disk error is not the design's result: a plain
    rerun evaluates that design again (a design's own failure stays reused)."""
    from designlab.optimize.space import load_sweep_config
    from designlab.optimize.store import ResultStore
    from designlab.optimize.sweep import _row, tasks_of

    a, _ = cheap_sweeps
    out = tmp_path / "out"
    assert _run(["sweep", a, "--out", out, "--workers", "1"], capsys)[0] == 0
    cfg, store = load_sweep_config(a), ResultStore(out)
    t = tasks_of(cfg)[0]
    (store.cache_dir / f"{t['key']}.json").unlink()
    store.put(t["key"], _row(t, {}, f"OutputError: cannot write {out}/fem/x.npz: no space left "
                                    "on the device", float("nan"), cfg), None)
    rc, so, _ = _run(["sweep", a, "--out", out, "--workers", "1"], capsys)
    assert rc == 0 and "1 evaluated, 3 from the store, 0 failed" in so, so


def test_a_write_failure_keeps_its_kind_across_processes():
    """The worker's error text says whether the file system refused a write; the kind
    survives pickling (the process pool, Dask) and is read from the text alone too."""
    import errno
    import pickle

    from designlab.atomic import os_error
    from designlab.optimize.executors import _guarded
    from designlab.optimize.failures import is_write_failure

    def full(task):
        try:
            raise OSError(errno.ENOSPC, "No space left on device")
        except OSError as exc:
            raise os_error(Path("/o/fem/k.npz"), exc) from None

    def own(task):
        raise ValueError("h=4 is a deliberately failing design")

    _, err = _guarded(full, None)
    assert is_write_failure(pickle.loads(pickle.dumps(err))) and is_write_failure(str(err))
    _, err = _guarded(own, None)
    assert not is_write_failure(pickle.loads(pickle.dumps(err)))
    assert not is_write_failure("ParameterError: x='no space left on the device' is not "
                                "allowed")


@pytest.mark.slow
@pytest.mark.parametrize("full", ["results", "optimize", "pareto", "report"])
def test_optimize_outputs_on_a_full_disk_are_all_or_nothing(full, cheap_sweeps, tmp_path,
                                                            capsys, monkeypatch, disk_full_at):
    """results.parquet, optimize.json and the report set are written together: a full disk
    while writing any of them leaves none (exit 2, one line, no temporary file); the store's
    rows stay for the rerun."""
    import designlab.cli.sweep as cli_sweep

    monkeypatch.setattr(cli_sweep, "_export_chosen", lambda *a, **k: [])   # no FEM here
    a = tmp_path / "two.toml"
    a.write_text(CFG_A + 'printed_volume_mm3 = "min"\n')
    out = tmp_path / "out"
    refused = disk_full_at(rf"^\.+{full}\.")
    rc, _, se = _run(["optimize", a, "--out", out, "--workers", "1", "--method", "pareto"],
                     capsys)
    assert refused and rc == 2 and se.count("error:") == 1 and "no space left" in se, se
    left = sorted(p.name for p in out.iterdir())
    assert left == ["cache", "fem", "results", "run.json"] or \
        left == ["cache", "results", "run.json"], left


@pytest.mark.slow
def test_a_failed_export_of_the_chosen_design_writes_no_optimize_outputs(cheap_sweeps, tmp_path,
                                                                         capsys, monkeypatch):
    """The chosen design's export fails (its prediction, a full disk): results.parquet,
    optimize.json and the report are not written either (exit 2, one line)."""
    import designlab.cli.sweep as cli_sweep
    from designlab.errors import OutputError

    def fails(*a, **k):
        raise OutputError("cannot write chosen/fingertip.stl: no space left on the device")

    monkeypatch.setattr(cli_sweep, "_export_chosen", fails)
    a = tmp_path / "two.toml"
    a.write_text(CFG_A + 'printed_volume_mm3 = "min"\n')
    out = tmp_path / "out"
    rc, _, se = _run(["optimize", a, "--out", out, "--workers", "1", "--method", "pareto"],
                     capsys)
    assert rc == 2 and se.count("error:") == 1 and "no space left" in se, se
    assert not {"results.parquet", "optimize.json", "report.html"} & {
        p.name for p in out.iterdir()}


def test_the_chosen_design_is_exported_only_once_predicted(tmp_path, monkeypatch):
    """export_design predicts first: a design whose prediction fails leaves no file to print;
    one whose report cannot be written takes its print files with it."""
    from designlab.errors import OutputError
    from designlab.optimize import evaluate
    import designlab.predict.record as record
    import designlab.predict.run as run

    def no_prediction(*a, **k):
        raise OutputError("the prediction failed")

    monkeypatch.setattr(run, "predict", no_prediction)
    with pytest.raises(OutputError):
        evaluate.export_design("flexure", {}, tmp_path / "a", formats="stl")
    assert not (tmp_path / "a").exists() or not list((tmp_path / "a").rglob("*.stl"))
    monkeypatch.setattr(run, "predict", lambda *a, **k: object())

    def full_disk(*a, **k):
        raise OutputError("cannot write prediction.json: no space left on the device")

    monkeypatch.setattr(record, "write_prediction", full_disk)
    with pytest.raises(OutputError):
        evaluate.export_design("flexure", {}, tmp_path / "b", formats="stl")
    assert not list((tmp_path / "b").rglob("*.stl"))
