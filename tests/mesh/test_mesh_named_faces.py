"""Facet sets from named B-rep faces (gmsh physical surface groups), with the facet predicates
as the fallback."""

from __future__ import annotations

import numpy as np
import pytest
from build123d import Align, Box, Pos

from designlab.errors import MeshingError
from designlab.geometry.body import Body
from designlab.mesh import brep
from designlab.mesh.meshing import mesh_bodies_detailed, mesh_part_detailed

pytestmark = pytest.mark.skipif(not brep.available(), reason="gmsh not installed")

LOW = (Align.CENTER, Align.CENTER, Align.MIN)


def _tri_set(tri) -> set[tuple[int, ...]]:
    return {tuple(t) for t in np.asarray(tri)[:, :3]}


class PredicatesOnly:
    """The default fingertip without its ``named_faces``: every facet set from its predicates."""

    def __init__(self, part):
        self.part = part

    def __getattr__(self, name):
        if name == "named_faces":
            raise AttributeError(name)
        return getattr(self.part, name)


@pytest.mark.slow
def test_named_sets_equal_the_predicate_sets_on_the_fingertip():
    from designlab.geometry.parts import make_part

    part = make_part("fingertip", None)          # names the ball seat and the well floors
    named = mesh_part_detailed(part, order=1, edge_length=3.0, mesher="gmsh")
    plain = mesh_part_detailed(PredicatesOnly(part), order=1, edge_length=3.0, mesher="gmsh")
    sets = ("ball_seat", "sensor_well_1", "sensor_well_2", "sensor_well_3")
    assert named.named_sets == sets and plain.named_sets == ()
    assert named.report()["facet_sets_from_brep_faces"] == list(sets)
    # naming faces does not change the mesh
    assert np.array_equal(named.mesh.points, plain.mesh.points)
    assert np.array_equal(named.mesh.cells, plain.mesh.cells)
    for name in sets:
        a, b = named.mesh.facet_sets[name], plain.mesh.facet_sets[name]
        assert len(a) > 50 and _tri_set(a) == _tri_set(b), name   # same triangles, same winding
    # the sets the part does not name still come from its predicates
    for name in ("bolt_head", "cap_mount"):
        assert _tri_set(named.mesh.facet_sets[name]) == _tri_set(plain.mesh.facet_sets[name])


def _stack():
    lower = Body("lower", Box(4, 4, 2, align=LOW), "ABS")
    upper = Body("upper", Pos(0, 0, 2) * Box(4, 4, 2, align=LOW), "ABS")
    return lower, upper


def _top_face(body: Body):
    return body.shape.faces().sort_by()[-1]


def test_interface_face_falls_back_to_the_predicate_and_split_faces_are_found():
    lower, upper = _stack()
    bottom = lower.shape.faces().sort_by()[0]
    # the lower box's top face is the interface (not boundary): its set comes from the predicate
    preds = {"top_of_lower": lambda c, n: n[:, 2] > 0.9,      # the upper box's top, boundary
             "bottom": lambda c, n: n[:, 2] < -0.9}
    named = {"top_of_lower": [("lower", _top_face(lower))], "bottom": [("lower", bottom)]}
    res = mesh_bodies_detailed([lower, upper], preds, edge_length=1.0, order=1, mesher="gmsh",
                               named_faces=named)
    assert res.named_sets == ("bottom",)
    m = res.mesh
    c = m.points[m.facet_sets["top_of_lower"]].mean(axis=1)
    assert np.allclose(c[:, 2], 4.0)                        # the predicate's triangles
    c = m.points[m.facet_sets["bottom"]].mean(axis=1)
    assert np.allclose(c[:, 2], 0.0)
    area = np.linalg.norm(np.cross(*(m.points[m.facet_sets["bottom"]][:, 1:] -
                                     m.points[m.facet_sets["bottom"]][:, :1]).transpose(1, 0, 2)),
                          axis=1).sum() / 2
    assert area == pytest.approx(16.0)


def test_named_face_errors_are_one_line():
    lower, upper = _stack()
    with pytest.raises(MeshingError, match=r"named face set 'x': body 'nope' is not meshed "
                                           r"\(meshed: lower, upper\)"):
        mesh_bodies_detailed([lower, upper], {}, edge_length=1.0, mesher="gmsh",
                             named_faces={"x": [("nope", _top_face(lower))]})
    elsewhere = Pos(50, 0, 0) * Box(1, 1, 1)
    with pytest.raises(MeshingError) as exc:
        mesh_bodies_detailed([lower], {}, edge_length=1.0, mesher="gmsh",
                             named_faces={"far": [("lower", elsewhere.faces()[0])]})
    assert "named face set 'far'" in str(exc.value) and "\n" not in str(exc.value)
