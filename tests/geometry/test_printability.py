"""Printability internals: the two ray backends agree, the per-body cache returns what a fresh
check returns and re-checks a body whose B-rep or rule changed."""

from __future__ import annotations

import numpy as np
import pytest
from build123d import Align, Box, Pos

import designlab.geometry.printability as pr
from designlab.errors import DesignlabError
from designlab.geometry.body import Body
from designlab.geometry.tessellate import tessellate

LOW = (Align.CENTER, Align.CENTER, Align.MIN)


def _fin(width: float = 0.2):
    """A fin ``width`` mm thick, 4 mm long and 3 mm tall on a 10 x 10 x 2 mm plate."""
    return Box(10, 10, 2, align=LOW) + Pos(0, 0, 2) * Box(width, 4, 3, align=LOW)


@pytest.mark.skipif(pr.ray_backend() != "embree", reason="embreex not installed")
def test_embree_and_vtk_rays_agree():
    mesh = tessellate(_fin())
    pts, nrm, _ = pr._area_samples(mesh, 50.0, 2000, 20000, 0)
    a = pr.ray_thickness(mesh, pts, nrm, opposed=pr.WALL_OPPOSED, backend="embree")
    b = pr.ray_thickness(mesh, pts, nrm, opposed=pr.WALL_OPPOSED, backend="vtk")
    assert np.array_equal(np.isfinite(a), np.isfinite(b))
    assert np.isfinite(a).mean() > 0.9
    np.testing.assert_allclose(a[np.isfinite(a)], b[np.isfinite(b)], rtol=0, atol=1e-9)
    assert a.min() == pytest.approx(0.2, abs=1e-9)      # the fin's width, exactly
    # the same decision figures from the whole check with either backend
    fa = pr.feature_sizes(mesh)
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(pr, "ray_backend", lambda: "vtk")
        fb = pr.feature_sizes(mesh)
    assert fa == fb or (fa.min_wall == pytest.approx(fb.min_wall, abs=1e-12)
                        and fa.thin_wall_area == fb.thin_wall_area
                        and fa.thin_skin_area == fb.thin_skin_area)


def test_unknown_ray_backend_is_one_line():
    mesh = tessellate(Box(1, 1, 1))
    with pytest.raises(DesignlabError, match=r"^backend='gpu': allowed 'embree' or 'vtk'$"):
        pr.ray_thickness(mesh, mesh.vertices[:1], mesh.vertex_normals[:1], backend="gpu")


def test_body_cache_returns_the_fresh_report_and_rechecks_changes(monkeypatch):
    pr.clear_cache()
    calls = []
    real = pr.tessellate

    def counting(shape, *a, **k):
        calls.append(1)
        return real(shape, *a, **k)

    monkeypatch.setattr(pr, "tessellate", counting)
    plate = Body("plate", Box(10, 10, 2, align=LOW), "PLA")
    fin = Body("fin", Pos(20, 0, 0) * _fin(), "PLA")
    first = pr.check_part("p", {"plate": plate, "fin": fin})
    assert len(calls) == 2
    assert not first[1].ok and first[1].thin_wall_mm2 == pytest.approx(24.0, rel=0.05)
    # the same B-rep again (a new object built the same way): no tessellation, same reports
    again = pr.check_part("p", {"plate": Body("plate", Box(10, 10, 2, align=LOW), "PLA"),
                                "fin": fin})
    assert len(calls) == 2 and again == first
    # a changed body is checked afresh, the unchanged one still comes from the cache
    wide = Body("fin", Pos(20, 0, 0) * _fin(0.5), "PLA")
    third = pr.check_part("p", {"plate": plate, "fin": wide})
    assert len(calls) == 3 and third[0] == first[0] and third[1].ok
    # a changed rule is part of the key: the fin is re-checked under it
    monkeypatch.setattr(pr, "THIN_AREA_MM2", 100.0)
    assert pr.check_part("p", {"fin": fin})[0].ok and len(calls) == 4
    # a caller's own mesh is checked as given, never taken from the cache
    broken = real(fin.shape)
    broken = type(broken)(broken.vertices, broken.faces[1:], process=False)
    r = pr.check_part("p", {"fin": fin}, meshes={"fin": broken})[0]
    assert not r.watertight and len(calls) == 4
    pr.clear_cache()
