"""The VTU file is made in memory and written by the package's atomic writer: the bytes
pyvista's own save gives, and a full disk is one OutputError (VTK's file writer crashed)."""

from __future__ import annotations

import errno

import numpy as np
import pytest

from designlab.errors import OutputError
from designlab.mesh.io import read_vtu, to_pyvista, write_vtu
from designlab.mesh.tetmesh import box_tet_mesh


def _mesh():
    return box_tet_mesh(10, 5, 2, 4, 2, 1).quadratic()


def test_the_file_is_pyvistas_and_reads_back(tmp_path):
    mesh = _mesh()
    u = np.random.default_rng(0).normal(size=(mesh.n_points, 3))
    write_vtu(mesh, tmp_path / "a.vtu", point_data={"u": u})
    grid = to_pyvista(mesh)
    grid.point_data["u"] = u
    grid.save(tmp_path / "b.vtu", binary=True)
    assert (tmp_path / "a.vtu").read_bytes() == (tmp_path / "b.vtu").read_bytes()
    np.testing.assert_array_equal(read_vtu(tmp_path / "a.vtu").cells, mesh.cells)


def test_a_full_disk_is_one_line_and_leaves_nothing(tmp_path, monkeypatch):
    monkeypatch.setattr("builtins.open", _FullOpen(open))
    with pytest.raises(OutputError, match="no space left on the device"):
        write_vtu(_mesh(), tmp_path / "m.vtu")
    assert list(tmp_path.iterdir()) == []


class _FullOpen:
    """``open`` whose binary files refuse to take data (a full disk)."""

    def __init__(self, real):
        self.real = real

    def __call__(self, file, mode="r", *a, **k):
        fh = self.real(file, mode, *a, **k)
        if "w" in mode and "b" in mode:
            def write(data):
                raise OSError(errno.ENOSPC, "No space left on device")
            fh.write = write
        return fh


@pytest.mark.parametrize("full", ["vtu", "json"])
def test_save_mesh_writes_the_pair_or_neither(full, tmp_path, disk_full_at):
    """mesh.vtu and mesh.json as a set: a full disk at either leaves neither, nor the --out
    folder made for them (the VTU stood alone when the report did not fit)."""
    from build123d import Box

    from designlab.geometry.body import Body
    from designlab.mesh.meshing import mesh_bodies_detailed, save_mesh

    res = mesh_bodies_detailed([Body("b", Box(4, 4, 4), "ABS")], {}, edge_length=2.0)
    refused = disk_full_at(rf"^\.mesh\..*\.{full}$")
    with pytest.raises(OutputError, match="no space left"):
        save_mesh(res, tmp_path / "out")
    assert refused and not (tmp_path / "out").exists()
    disk_full_at("^$")
    vtu, js = save_mesh(res, tmp_path / "out")
    assert read_vtu(vtu).n_cells == res.mesh.n_cells and js.is_file()
