"""The Python API: parts with params()/show()/_repr_png_, dl.predict on a part
object, the Prediction's summary/plot/_repr_html_, and the getting-started notebook."""

from __future__ import annotations

from pathlib import Path

import pytest

from conftest import ROOT


def test_part_api():
    import designlab as dl

    part = dl.Fingertip(h=3, r=9)
    rows = part.params()
    h = next(r for r in rows if r["name"] == "h")
    assert (h["value"], h["unit"], h["meaning"]) == (3, "mm", "straight height of the fingertip")
    assert "<table>" in rows._repr_html_() and "straight height" in str(rows)
    png = part._repr_png_()
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 5000
    assert {"Fingertip", "Strap", "Flexure", "predict"} <= set(dir(dl))
    with pytest.raises(AttributeError):
        dl.no_such_name


@pytest.mark.slow
def test_facade_names_are_the_part_classes_with_their_api():
    """``dl.Fingertip``/``dl.Strap``/``dl.Flexure`` are the built-in sensors' definitions:
    subclasses of the geometry modules' classes and of ``SensorDefinition`` (looked up by
    class, not by sensor name), the same as ``dl.PARTS`` holds, and carry ``params()`` even
    when the facade is the first thing imported (a fresh interpreter)."""
    import subprocess
    import sys

    import designlab as dl
    from designlab.geometry.fingertip import CantileverFingertip
    from designlab.geometry.flexure import SpringFlexure
    from designlab.geometry.strap import ArchStrap

    for facade, cad in zip((dl.Fingertip, dl.Strap, dl.Flexure),
                           (CantileverFingertip, ArchStrap, SpringFlexure)):
        assert issubclass(facade, cad) and issubclass(facade, dl.SensorDefinition)
        assert facade() == cad()
    from designlab.sensors.registry import BUILT_IN

    assert {dl.PARTS[n] for n in BUILT_IN} == {dl.Fingertip, dl.Strap, dl.Flexure}
    code = ("import designlab as dl; print(*(n for n in ('Fingertip', 'Strap', 'Flexure') "
            "if len(getattr(dl, n)().params()) > 0))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         timeout=300, check=True).stdout.split()
    assert out == ["Fingertip", "Strap", "Flexure"]


def test_show_writes_a_png_in_a_script(tmp_path):
    import designlab as dl

    path = dl.Strap().show(tmp_path / "strap.png")
    assert Path(path).read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_predict_takes_a_part_object_and_a_name():
    import designlab as dl

    part = dl.Flexure()
    a = dl.predict(part)
    b = dl.predict("flexure")
    assert isinstance(a, dl.Prediction) and a.params == b.params
    assert a.condition_number == b.condition_number
    text = a.summary()
    assert "flexure virtual test" in text and "K_f diagonal" in text
    assert "<table>" in a._repr_html_()


@pytest.mark.slow
def test_getting_started_notebook_runs():
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(ROOT / "examples" / "getting_started.ipynb", as_version=4)
    NotebookClient(nb, timeout=900, kernel_name="python3",
                   resources={"metadata": {"path": str(ROOT)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    kinds = {k for o in outputs for k in o.get("data", {})}
    assert {"image/png", "text/html"} <= kinds        # the part's picture, the tables


def test_cli_params_lists_every_field(capsys, monkeypatch):
    from designlab.cli import main
    from designlab.cli.app import console
    from designlab.geometry.api import field_rows
    from designlab.geometry.parts import PARTS

    with pytest.raises(SystemExit) as exc:
        main(["params", "nope"])
    assert exc.value.code == 2
    # wide enough that no name is wrapped, whatever width the console took at import
    monkeypatch.setattr(console, "width", 250)
    main(["params", "strap"])
    out = capsys.readouterr().out
    for r in field_rows(PARTS["strap"]):
        assert r["name"] in out
    assert "trace_thickness" in out and "mm" in out
