"""Fuzz of the command line with bad and hostile inputs: bad values, wrong types, encodings,
markup characters, hostile paths, filesystem faults (read-only and full tmpfs, or their
equivalent), bad sweep configs and options.

Every case must end with exit 2 and one line ``error: ...`` on stderr (no traceback, no
"internal error"), print the offending user text literally (no rich markup), and leave its
``--out`` as it was (not created, or empty). The default run takes a fixed sample of ~40
cases; ``-m slow`` runs all of them (>= 300)."""

from __future__ import annotations

import dataclasses
import os
import random
import subprocess
from pathlib import Path

import pytest

from designlab.cli import main
from designlab.geometry.parts import PARTS

MARKUP = "[/bold]"


def _case(id_, kind, **kw):
    return {"id": id_, "kind": kind, **kw}


def _part_value_cases():
    """Bad values of every part parameter (export/show/mesh/predict)."""
    out = []
    bad = ["nan", "inf", "-inf", "abc", "", MARKUP, "1e999", "1e308", "-1e308", "0x1g"]
    cmds = ["export", "predict", "mesh", "show"]
    for part, cls in PARTS.items():
        for i, f in enumerate(dataclasses.fields(cls)):
            for j, v in enumerate(bad):
                if isinstance(f.default, str) and v in ("", ):
                    continue
                cmd = cmds[(i + j) % len(cmds)]
                out.append(_case(f"set-{cmd}-{part}-{f.name}-{j}", "argv",
                                 argv=[cmd, part, "--set", f"{f.name}={v}"],
                                 expect=[f.name]))
    return out


def _toml_cases():
    """Wrong types and structures in a part config (--config)."""
    out = []
    vals = {"list": "[1, 2]", "table": "{ a = 1 }", "text": '"abc"', "bool": "true",
            "inf": "inf", "nan": "nan", "huge": "1e308", "neg": "-1e300"}
    for part, cls in PARTS.items():
        numeric = [f.name for f in dataclasses.fields(cls)
                   if isinstance(f.default, float)][:6]
        for name in numeric:
            for k, v in vals.items():
                out.append(_case(f"config-{part}-{name}-{k}", "config", part=part,
                                 text=f"{name} = {v}\n", expect=[name]))
        out.append(_case(f"config-{part}-nested", "config", part=part,
                         text=f"[{part}]\n[{part}.extra]\nx = 1\n", expect=["extra"]))
        out.append(_case(f"config-{part}-typo", "config", part=part,
                         text="wdth = 3.0\n", expect=["wdth"]))
        out.append(_case(f"config-{part}-markup", "config", part=part,
                         text=f'"{MARKUP}" = 1.0\n', expect=[MARKUP]))
    return out


ENCODINGS = {
    "binary": b"\x00\x01\x02\xff" * 64,
    "latin1": "width = 3.0 # caf\xe9\n".encode("latin-1"),
    "utf16": "width = 3.0\n".encode("utf-16"),
    "deep": b"x = " + b"[" * 200_000 + b"]" * 200_000 + b"\n",
    "garbage": b"this is = = not toml [[[\n",
    "empty-table-key": b"[]\n",
}


def _encoding_cases():
    out = []
    for name in ENCODINGS:
        for opt in ("export-config", "sweep", "protocol", "card", "model"):
            out.append(_case(f"enc-{opt}-{name}", "encoding", opt=opt, enc=name))
        out.append(_case(f"enc-dir-{name}", "encoding", opt="export-config", enc=name,
                         directory=True))
    return out


def _option_cases():
    out = []
    opts = [
        (["sweep", "{cfg}", "--workers", "-1"], "--workers"),
        (["sweep", "{cfg}", "--workers", "0"], "--workers"),
        (["sweep", "{cfg}", "--workers", "100000"], "--workers"),
        (["sweep", "{cfg}", "--scheduler", "http://x"], "--scheduler"),
        (["optimize", "{cfg}", "--maxiter", "0"], "--maxiter"),
        (["optimize", "{cfg}", "--method", "magic"], "--method"),
        (["optimize", "{cfg}", "--format", "stl,doc"], "doc"),
        (["loop", "--data", "{card}", "--n-se", "nan"], "--n-se"),
        (["loop", "--data", "{card}", "--n-se", "-1"], "--n-se"),
        (["loop", "--data", "{card}", "--min-relative", "-5"], "--min-relative"),
        (["loop", "--data", "{card}", "--min-relative", "inf"], "--min-relative"),
        (["loop", "--data", "{card}", "--max-effects", "1000"], "--max-effects"),
        (["export", "strap", "--nozzle", "nan"], "--nozzle"),
        (["export", "strap", "--nozzle", "-1"], "--nozzle"),
        (["export", "strap", "--layer-height", "inf"], "--layer-height"),
        (["export", "strap", "--format", "exe"], "exe"),
        (["show", "strap", "--width", "0"], "--width"),
        (["show", "strap", "--height", "100000"], "--height"),
        (["mesh", "strap", "--order", "3"], "--order"),
        (["mesh", "strap", "--edge-length", "nan"], "--edge-length"),
        (["mesh", "strap", "--edge-length", "-1"], "--edge-length"),
        (["compensate", "--train", "{csv}", "--input", "P", "--output", "F", "--dt", "nan"],
         "--dt"),
        (["compensate", "--train", "{csv}", "--input", "P", "--output", "F", "--segments",
          "1"], "--segments"),
        (["compensate", "--train", "{csv}", "--input", "P", "--output", "F", "--update",
          "magic"], "--update"),
        (["predict", "strap", "--setting", f"{MARKUP}=1"], MARKUP),
        (["predict", "fingertip", "--set", f"{MARKUP}=1"], MARKUP),
        (["export", "strap", "--set", "[time]=3"], "[time]"),
        (["export", "all", "--set", "width=3"], "PART.NAME=VALUE"),
        (["predict", "wing"], "wing"),
        (["export", "strap", "--set", "novalue"], "NAME=VALUE"),
    ]
    for i, (argv, word) in enumerate(opts):
        out.append(_case(f"opt-{i}-{argv[0]}-{word}", "option", argv=argv, expect=[word]))
    return out


SWEEP_BASE = ('part = "fingertip"\nmethod = "grid"\n[parameters]\nh = [0.0, 3.0]\n'
              '[objectives]\ncondition_number = "min"\n')


def _sweep_cases():
    bad = {
        "unknown-param": ('part = "fingertip"\n[parameters]\nwidht = [1.0, 2.0]\n', "widht"),
        "unknown-fixed": (SWEEP_BASE + "[fixed]\nnope = 1.0\n", "nope"),
        "fixed-range": (SWEEP_BASE + "[fixed]\nr = -5.0\n", "fixed.r"),
        "protocol-key": (SWEEP_BASE + "[protocol]\nnope = 1\n", "protocol.nope"),
        "setting-key": (SWEEP_BASE + "[settings]\nnope = 1\n", "settings.nope"),
        "model-setting": (SWEEP_BASE + "[settings.model]\nedge_lenght = 1.0\n", "edge_lenght"),
        "objective": (SWEEP_BASE.replace("condition_number", "conditon_number"),
                      "conditon_number"),
        "constraint": (SWEEP_BASE + "[constraints]\nprintible = true\n", "printible"),
        "inf-range": (SWEEP_BASE.replace("[0.0, 3.0]", "[0.0, inf]"), "finite"),
        "nan-range": (SWEEP_BASE.replace("[0.0, 3.0]", "[nan, 3.0]"), "finite"),
        "huge-grid": ('part = "fingertip"\n[parameters]\nh = { range = [0.0, 3.0], levels = 10000 }\n'
                      'r = { range = [6.0, 9.0], levels = 10000 }\n', "at most"),
        "samples": ('part = "fingertip"\nmethod = "lhs"\nsamples = 100000000\n'
                    '[parameters]\nh = [0.0, 3.0]\n', "samples"),
        "samples-type": ('part = "fingertip"\nmethod = "lhs"\nsamples = "8"\n'
                         '[parameters]\nh = [0.0, 3.0]\n', "samples"),
        "levels-float": ('part = "fingertip"\n[parameters]\nh = { range = [0.0, 3.0], levels = 2.5 }\n',
                         "levels"),
        "range-type": ('part = "fingertip"\n[parameters]\nh = { range = ["a", 3.0] }\n', "range"),
        "values-empty": ('part = "fingertip"\n[parameters]\nh = { values = [] }\n', "values"),
        "out-of-part-range": ('part = "fingertip"\n[parameters]\nh = [0.0, 1e6]\n', "parameters.h"),
        "part-type": ('part = 3\n[parameters]\nh = [0.0, 3.0]\n', "part"),
        "method": (SWEEP_BASE.replace("grid", "gird"), "grid"),
        "top-typo": (SWEEP_BASE + "objectivs = 1\n", "objectivs"),
        "markup-key": (SWEEP_BASE + f'"{MARKUP}" = 1\n', MARKUP),
        "seed": (SWEEP_BASE + "seed = -1\n", "seed"),
        "target": (SWEEP_BASE.replace('"min"', '{ target = "x" }'), "target"),
        "deep": ("x = " + "[" * 100 + "]" * 100 + "\n", "nest"),
    }
    return [_case(f"sweep-{k}", "sweep", text=t, expect=[w]) for k, (t, w) in bad.items()]


CARD = """
[[files]]
path = "run.csv"
[time]
column = "t"
[inputs]
displacement = { column = "P", unit = "mm" }
[outputs]
force = { column = "F", unit = "N" }
"""


def _card_cases():
    bad = {
        "unti": (CARD.replace('unit = "mm"', 'unti = "m"'), "unti"),
        "rat": (CARD + "[preprocess]\nrat = 5.0\n", "rat"),
        "files-int": ("files = [1]\n" + CARD.replace('[[files]]\npath = "run.csv"\n', ""),
                      "files[1]"),
        "time-int": (CARD.replace('[time]\ncolumn = "t"\n', "time = 3\n"), "time"),
        "rate-text": (CARD + '[preprocess]\nrate = "abc"\n', "rate"),
        "window-0": (CARD + "[repair]\nwindow = 0\n", "window"),
        "lowpass-neg": (CARD + "[preprocess]\nlowpass_hz = -1\n", "lowpass_hz"),
        "bias-neg": (CARD + "[preprocess]\nbias_seconds = -1\n", "bias_seconds"),
        "rate-huge": (CARD + "[preprocess]\nrate = 1e6\n", "rate"),
        "etc-passwd": (CARD.replace("run.csv", "/etc/passwd"), "outside"),
        "dotdot": (CARD.replace("run.csv", "../../../../etc/passwd"), "outside"),
        "markup-col": (CARD.replace('column = "F"', f'column = "{MARKUP}"'), MARKUP),
        "markup-time": (CARD.replace('column = "t"', 'column = "[time]"'), "[time]"),
        "dup-col": ("DUP" + CARD, "more than once"),
        "binary-parquet": ("BINPQ" + CARD.replace("run.csv", "run.parquet"), "Parquet"),
        "missing": (CARD.replace("run.csv", "nope.csv"), "not found"),
        "split": (CARD + "[split]\ntrain = 2\n", "split.train"),
        "role": (CARD.replace('path = "run.csv"', 'path = "run.csv"\nrole = "test"'), "role"),
        "allow-type": ("allow_outside_paths = 1\n" + CARD, "allow_outside_paths"),
        "tiny-values": ("TINY" + CARD, "column 'F' varies by"),
    }
    out = []
    for k, (t, w) in bad.items():
        out.append(_case(f"card-loop-{k}", "card", text=t, expect=[w], cmd="loop"))
        out.append(_case(f"card-comp-{k}", "card", text=t, expect=[w], cmd="compensate"))
    return out


def _model_cases():
    docs = {
        "string-params": '{"format": "designlab-model", "version": 1, "model": {"base": "x"}}',
        "no-format": '{"model": {"base": {}}}',
        "version-2": '{"format": "designlab-model", "version": 2, "model": {"base": {}}}',
        "list": "[1, 2, 3]",
        "nan": '{"format": "designlab-model", "version": 1, "x": NaN}',
        "import": '{"format": "__import__(\'os\').system(\'touch PWNED\')", "version": 1}',
        "outputs-list": '{"format": "designlab-model", "version": 1, '
                        '"model": {"base": {}, "outputs": [1]}}',
        "deep": "[" * 200_000 + "]" * 200_000,
    }
    out = [_case(f"model-{k}", "model", text=t) for k, t in docs.items()]
    effect = ('{"name": "gain_offset", "channel": null, "theta": {}, "beta": %s, "alpha": %s, '
              '"nuisance": []}')
    for k, e, expect in (("beta-short", effect % ("[1.0]", "[]"), "effects[0].beta=[1.0]"),
                         ("alpha-long", effect % ("[0.0, 1.0]", "[0.0]"), "effects[0].alpha=")):
        out.append(_case(f"model-{k}", "model", expect=[expect], text=(
            '{"format": "designlab-model", "version": 1, "model": {"base": {"kind": "linear", '
            '"inputs": {"force": ["displacement"]}, "parameters": {"force": {"intercept": 0.0, '
            '"gains": {"displacement": 0.5}}}}, "outputs": {"force": {"unit": "N", "effects": ['
            + e + ']}}, "inputs": {"displacement": {"unit": "mm", "quantity": "length", '
            '"kind": "drive"}}}}')))
    return out


def _path_cases():
    out = []
    for cmd in ("export", "predict", "mesh", "sweep", "loop"):
        for where in ("proc", "file", "under-file", "readonly", "markup-missing-config"):
            out.append(_case(f"path-{cmd}-{where}", "path", cmd=cmd, where=where))
    return out


ALL = (_part_value_cases() + _toml_cases() + _encoding_cases() + _option_cases()
       + _sweep_cases() + _card_cases() + _model_cases() + _path_cases())
FAST = set(c["id"] for c in random.Random(15).sample(ALL, 40))


def test_there_are_at_least_300_cases():
    assert len(ALL) >= 300
    assert len({c["id"] for c in ALL}) == len(ALL)


def _write_inputs(tmp: Path) -> dict:
    import numpy as np

    t = np.arange(200) * 0.01
    (tmp / "run.csv").write_text("t,P,F\n" + "".join(
        f"{a},{1 + np.sin(a)},{2 + np.cos(a)}\n" for a in t))
    (tmp / "sweep.toml").write_text(SWEEP_BASE)
    (tmp / "card.toml").write_text(CARD)
    return {"cfg": str(tmp / "sweep.toml"), "card": str(tmp / "card.toml"),
            "csv": str(tmp / "run.csv")}


def _run(argv, capsys) -> tuple[int, str]:
    with pytest.raises(SystemExit) as exc:
        main([str(a) for a in argv])
    err = capsys.readouterr().err
    return exc.value.code, err


def _argv_for(case, tmp: Path, out: Path, files: dict) -> list[str]:
    kind = case["kind"]
    if kind in ("argv", "option"):
        argv = [a.format(**files) if "{" in a and a.startswith("{") else a for a in case["argv"]]
        if argv[0] == "show":
            return argv + ["--out", str(out / "part.png")]
        return argv + ["--out", str(out)]
    if kind == "config":
        p = tmp / "part.toml"
        p.write_text(case["text"])
        return ["export", case["part"], "--config", str(p), "--out", str(out)]
    if kind == "encoding":
        p = tmp / ("in.json" if case["opt"] == "model" else "in.toml")
        if case.get("directory"):
            p.mkdir()
        else:
            p.write_bytes(ENCODINGS[case["enc"]])
        opt = case["opt"]
        if opt == "export-config":
            return ["export", "strap", "--config", str(p), "--out", str(out)]
        if opt == "sweep":
            return ["sweep", str(p), "--out", str(out)]
        if opt == "protocol":
            return ["predict", "strap", "--protocol", str(p), "--out", str(out)]
        if opt == "card":
            return ["loop", "--data", str(p), "--out", str(out)]
        return ["loop", "--data", files["card"], "--base", str(p), "--out", str(out)]
    if kind == "sweep":
        p = tmp / "bad_sweep.toml"
        p.write_text(case["text"])
        return ["sweep", str(p), "--out", str(out), "--workers", "1"]
    if kind == "card":
        text = case["text"]
        if text.startswith("DUP"):
            text = text[3:]
            (tmp / "run.csv").write_text("t,P,F,F\n" + "".join(f"{i},1,2,3\n" for i in range(50)))
        if text.startswith("TINY"):       # readings that vary near 1e-300 only
            text = text[4:]
            (tmp / "run.csv").write_text("t,P,F\n" + "".join(
                f"{i * 0.01},{1 + i % 7},{(i % 5) * 1e-300}\n" for i in range(200)))
        if text.startswith("BINPQ"):
            text = text[5:]
            (tmp / "run.parquet").write_bytes(b"PAR1\x00\xff garbage" * 40)
        p = tmp / "bad_card.toml"
        p.write_text(text)
        if case["cmd"] == "loop":
            return ["loop", "--data", str(p), "--out", str(out)]
        return ["compensate", "--data", str(p), "--input", "displacement", "--output", "force",
                "--out", str(out)]
    if kind == "model":
        p = tmp / "model.json"
        p.write_text(case["text"])
        return ["loop", "--data", files["card"], "--base", str(p), "--out", str(out)]
    raise AssertionError(kind)


def _path_argv(case, tmp: Path, files: dict) -> tuple[list[str], Path]:
    where, cmd = case["where"], case["cmd"]
    if where == "proc":
        out = Path("/proc/self/designlab-out")
    elif where == "file":
        out = tmp / "a_file"
        out.write_text("x")
    elif where == "under-file":
        (tmp / "a_file").write_text("x")
        out = tmp / "a_file" / "sub"
    elif where == "readonly":
        out = tmp / "ro" / "out"
    else:
        out = tmp / f"out{MARKUP}"
    missing = str(tmp / f"missing{MARKUP}.toml")
    argv = {"export": ["export", "strap"], "predict": ["predict", "strap"],
            "mesh": ["mesh", "strap"], "sweep": ["sweep", files["cfg"]],
            "loop": ["loop", "--data", files["card"]]}[cmd]
    if where == "markup-missing-config":
        argv = {"export": ["export", "strap", "--config", missing],
                "predict": ["predict", "strap", "--config", missing],
                "mesh": ["mesh", "strap", "--config", missing],
                "sweep": ["sweep", missing], "loop": ["loop", "--data", missing]}[cmd]
    return argv + ["--out", str(out)], out


@pytest.fixture
def readonly_mount(tmp_path):
    """A read-only tmpfs at tmp/ro (root), else a folder without write permission."""
    ro = tmp_path / "ro"
    ro.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "ro,size=64k", "tmpfs", str(ro)],
                             capture_output=True).returncode == 0
    if not mounted:
        ro.chmod(0o500)
    yield ro
    if mounted:
        subprocess.run(["umount", str(ro)], capture_output=True)


def _params():
    return [pytest.param(c, id=c["id"], marks=() if c["id"] in FAST else pytest.mark.slow)
            for c in ALL]


@pytest.mark.parametrize("case", _params())
def test_bad_input_is_one_line_exit_2_nothing_written(case, tmp_path, capsys, monkeypatch,
                                                      request):
    monkeypatch.setenv("DESIGNLAB_LOG_DIR", str(tmp_path / "logs"))
    monkeypatch.chdir(tmp_path)
    files = _write_inputs(tmp_path)
    if case["kind"] == "path":
        if case["where"] == "readonly":
            request.getfixturevalue("readonly_mount")
            if os.geteuid() == 0 and not os.path.ismount(tmp_path / "ro"):
                pytest.skip("root ignores permissions and tmpfs cannot be mounted")
        argv, out = _path_argv(case, tmp_path, files)
    else:
        out = tmp_path / "out"
        argv = _argv_for(case, tmp_path, out, files)
    before = sorted(p.name for p in tmp_path.iterdir())
    code, err = _run(argv, capsys)
    lines = [l for l in err.splitlines() if l.strip()]
    assert code == 2, err
    assert "Traceback" not in err and "internal error" not in err
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    for word in case.get("expect", []):
        assert word in err, (word, err)            # user text printed literally
    if case["kind"] == "path" and case["where"] == "markup-missing-config":
        assert MARKUP in err
    # nothing written: --out not created (or left as it was), no temp or log files
    if case["kind"] != "path" or case["where"] in ("markup-missing-config",):
        assert not out.exists() or not any(out.iterdir())
    after = sorted(p.name for p in tmp_path.iterdir())
    assert [n for n in after if n not in before and n not in ("out", "logs") and
            not n.endswith((".toml", ".json", ".csv", ".parquet"))] == []
    assert not (tmp_path / "logs").exists()
    assert not (tmp_path / "PWNED").exists()


def test_an_unexpected_error_is_one_line_with_a_log_file(tmp_path, capsys, monkeypatch):
    """Anything that is not a user error: one line naming a log file that holds the
    traceback, exit 1."""
    import designlab.geometry.export as export

    def boom(*a, **k):
        raise ZeroDivisionError(f"deliberate {MARKUP}")

    monkeypatch.setenv("DESIGNLAB_LOG_DIR", str(tmp_path / "logs"))
    monkeypatch.setattr(export, "parse_formats", boom)
    code, err = _run(["export", "strap", "--out", str(tmp_path / "o")], capsys)
    assert code == 1
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "internal error ZeroDivisionError" in err and MARKUP in err
    log = Path(lines[0].rsplit("traceback in ", 1)[1])
    assert "Traceback" in log.read_text() and "deliberate" in log.read_text()
    assert "Traceback" not in err


def test_full_disk_leaves_nothing_half_written(tmp_path, capsys, monkeypatch):
    """A tiny tmpfs (or, without root, a write that fails with ENOSPC): one line, exit 2, no
    partial prediction set or temporary file."""
    import errno

    from designlab.atomic import atomic_write_bytes
    from designlab.errors import OutputError

    tiny = tmp_path / "tiny"
    tiny.mkdir()
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=8k", "tmpfs", str(tiny)],
                             capture_output=True).returncode == 0
    try:
        if mounted:
            with pytest.raises(OutputError, match="no space left"):
                atomic_write_bytes(tiny / "big.bin", b"x" * 200_000)
        else:
            def full(*a, **k):
                raise OSError(errno.ENOSPC, "No space left on device")
            monkeypatch.setattr(os, "fsync", full)
            with pytest.raises(OutputError, match="no space left"):
                atomic_write_bytes(tiny / "big.bin", b"x" * 200_000)
        assert list(tiny.iterdir()) == []
    finally:
        if mounted:
            subprocess.run(["umount", str(tiny)], capture_output=True)


# ------------------------------------------------ user text in tables and absurd model numbers
#: the valid CARD with its output channel named ``a[red]b``, read from the column ``[/bold]``
MARKUP_CARD = CARD.replace('force = { column = "F", unit = "N" }',
                           '"a[red]b" = { column = "[/bold]", unit = "N" }')


def _markup_inputs(tmp: Path) -> Path:
    """A valid card whose output channel is ``a[red]b`` read from the column ``[/bold]``."""
    import numpy as np

    t = np.arange(1500) * 0.01
    noise = np.random.default_rng(0).standard_normal(t.size)
    (tmp / "run.csv").write_text("t,P,[/bold]\n" + "".join(
        f"{a:.3f},{1 + np.sin(a):.6f},{2 + 3 * np.sin(a) + 0.05 * e:.6f}\n"
        for a, e in zip(t, noise)))
    (tmp / "card.toml").write_text(MARKUP_CARD)
    return tmp / "card.toml"


@pytest.mark.parametrize("cmd", ["loop", "compensate"])
@pytest.mark.slow
def test_markup_in_a_valid_column_and_channel_is_printed_literally(cmd, tmp_path, capsys,
                                                                   monkeypatch):
    """A column named ``[/bold]`` and a channel ``a[red]b`` are data, not markup: the run
    completes (it crashed with a MarkupError, exit 1) and the tables print the name as it is."""
    monkeypatch.setenv("DESIGNLAB_LOG_DIR", str(tmp_path / "logs"))
    card = _markup_inputs(tmp_path)
    argv = ["loop", "--data", card, "--max-effects", "1"] if cmd == "loop" else [
        "compensate", "--data", card, "--input", "displacement", "--output", "a[red]b",
        "--model", "linear"]
    code = 0
    try:
        main([str(a) for a in argv + ["--out", tmp_path / "out"]])
    except SystemExit as exc:
        code = exc.code or 0
    cap = capsys.readouterr()
    assert code == 0, cap.err
    assert "a[red]b" in cap.out and "Traceback" not in cap.err + cap.out
    assert not (tmp_path / "logs").exists()


@pytest.mark.parametrize("where, value", [
    ("gains", "1e308"), ("gains", "-1e101"), ("intercept", "1e308"), ("intercept", "1" + "0" * 120),
])
def test_model_json_with_an_absurd_parameter_is_exit_2(where, value, tmp_path, capsys,
                                                       monkeypatch):
    """A model.json gain of 1e308 is finite JSON but gives inf predictions: refused, one line."""
    monkeypatch.setenv("DESIGNLAB_LOG_DIR", str(tmp_path / "logs"))
    monkeypatch.chdir(tmp_path)
    files = _write_inputs(tmp_path)
    gain, icpt = (value, "0.5") if where == "gains" else ("2.0", value)
    (tmp_path / "model.json").write_text(
        '{"format": "designlab-model", "version": 1, "model": {"base": {"kind": "linear", '
        '"inputs": {"force": ["displacement"]}, "parameters": {"force": {"intercept": '
        f'{icpt}, "gains": {{"displacement": {gain}}}}}}}}}, "outputs": {{"force": '
        '{"unit": "N", "effects": []}}, "inputs": {"displacement": {"unit": "mm", '
        '"quantity": "length", "kind": "drive"}}}}')
    out = tmp_path / "out"
    code, err = _run(["loop", "--data", files["card"], "--base", tmp_path / "model.json",
                      "--out", out], capsys)
    assert code == 2, err
    lines = [l for l in err.splitlines() if l.strip()]
    assert len(lines) == 1 and "is not allowed: a finite number" in err, err
    assert f"model.base.parameters.force.{where}" in err, err
    assert not out.exists() or not any(out.iterdir())
