"""A definition's bodies from a STEP file whose solids are named: the names, volumes and places
come back as written, a bad file is one line, and a load cell drawn as STEP predicts what the
same load cell drawn in build123d does."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from build123d import Box, Cylinder, Pos

import designlab as dl
from designlab.errors import ParameterError
from designlab.geometry.assembly import assembly, save_assembly_step

ROOT = Path(__file__).resolve().parents[3]


class _Two:
    """Two bodies, one moved off the origin, as a part's build() gives them."""

    def build(self):
        from designlab.geometry.body import Body

        return {"plate": Body("plate", Box(20, 10, 2), "PLA"),
                "post": Body("post", Pos(4, -2, 3) * Cylinder(2, 4), "steel")}


def test_named_solids_come_back_with_their_names_volumes_and_places(tmp_path):
    path = save_assembly_step(assembly(_Two(), "two"), tmp_path / "two.step")
    got = dl.step_solids(path)
    assert sorted(got) == ["plate", "post"]
    for name, body in _Two().build().items():
        assert got[name].volume == pytest.approx(body.shape.volume, rel=1e-9)
        a, b = got[name].bounding_box(), body.shape.bounding_box()
        assert np.allclose(tuple(a.min), tuple(b.min), atol=1e-6)
        assert np.allclose(tuple(a.max), tuple(b.max), atol=1e-6)


@pytest.mark.parametrize("content", [None, "not a step file\n", "ISO-10303-21;\nEND-ISO;\n"])
def test_a_missing_or_unreadable_file_is_one_line(tmp_path, content):
    path = tmp_path / "bad.step"
    if content is not None:
        path.write_text(content)
    with pytest.raises(ParameterError) as exc:
        dl.step_solids(path)
    assert exc.value.name == "step" and "\n" not in str(exc.value)


@pytest.mark.slow
def test_a_load_cell_drawn_as_step_predicts_as_drawn_in_build123d(tmp_path):
    from designlab.sensors import registry
    from designlab.sensors.generic import virtual as g

    LoadCell = registry.load_class(str(ROOT / "examples" / "sensors" / "load_cell.py"))
    step = save_assembly_step(assembly(LoadCell(), "cell"), tmp_path / "cell.step")

    class StepCell(LoadCell):
        name = "step_cell"

        def bodies(self):
            return {"beam": dl.Solid(dl.step_solids(step)["beam"], self.material)}

    out = []
    for cls in (LoadCell, StepCell):
        settings = g.settings_class(cls)(mesh_convergence=False, viscoelastic=False)
        out.append(g.run(cls(), settings=settings).report)
    # the STEP round trip re-parametrises the faces and gmsh places its nodes a little
    # differently: the gauge's reading per N agrees to 1e-3 (the mesh's own error bar between
    # 1.5x coarser and this mesh is about 1e-2, docs/sensors/load_cell.md)
    a, b = (r["sensitivity"]["gauge"] for r in out)
    assert a.keys() == b.keys() and abs(a["tip_Fz"]) > 0
    for k in a:
        assert b[k] == pytest.approx(a[k], rel=1e-3, abs=1e-9 * abs(a["tip_Fz"]))
    n = [r["mesh"]["n_points"] for r in out]
    assert abs(n[1] - n[0]) <= 0.02 * n[0]
