"""TetMesh <-> VTU (ParaView), written atomically.

The file holds the tetrahedra (VTK_TETRA or VTK_QUADRATIC_TETRA, whose node order is the C3D10
order of :class:`TetMesh`) with cell data ``region``, followed by the facet-set triangles
(VTK_TRIANGLE / VTK_QUADRATIC_TRIANGLE) with cell data ``facet_set``; ``-1`` marks "not
applicable". Region names, materials and facet/point set names live in a JSON string in the
field data ``designlab`` (UTF-8 bytes), so :func:`read_vtu` gives back the same mesh.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from designlab.atomic import atomic_write_bytes
from designlab.errors import DataError
from designlab.mesh.tetmesh import TetMesh

_META = "designlab"


def to_pyvista(mesh: TetMesh, facets: bool = True):
    """A ``pyvista.UnstructuredGrid`` of the mesh (and its facet sets, unless ``facets=False``)."""
    import pyvista as pv

    tet_type = pv.CellType.TETRA if mesh.order == 1 else pv.CellType.QUADRATIC_TETRA
    tri_type = pv.CellType.TRIANGLE if mesh.order == 1 else pv.CellType.QUADRATIC_TRIANGLE
    blocks = [(tet_type, np.asarray(mesh.cells, np.int64))]
    region = [np.asarray(mesh.region, np.int64)]
    fset = [np.full(mesh.n_cells, -1, np.int64)]
    names = list(mesh.facet_sets)
    if facets:
        for k, name in enumerate(names):
            tri = np.asarray(mesh.facet_sets[name], np.int64).reshape(-1, 3 * mesh.order)
            blocks.append((tri_type, tri))
            region.append(np.full(len(tri), -1, np.int64))
            fset.append(np.full(len(tri), k, np.int64))
    cells = np.concatenate([np.column_stack([np.full(len(c), c.shape[1]), c]).ravel()
                            for _, c in blocks])
    types = np.concatenate([np.full(len(c), t, np.uint8) for t, c in blocks])
    grid = pv.UnstructuredGrid(cells, types, np.asarray(mesh.points, float))
    grid.cell_data["region"] = np.concatenate(region)
    grid.cell_data["facet_set"] = np.concatenate(fset)
    meta = {"region_names": {str(k): v for k, v in mesh.region_names.items()},
            "materials": dict(mesh.materials), "facet_sets": names,
            "point_sets": {k: np.asarray(v).tolist() for k, v in mesh.point_sets.items()},
            "order": mesh.order}
    # JSON as UTF-8 bytes: readable by VTK/ParaView and by meshio (which rejects string arrays)
    grid.field_data[_META] = np.frombuffer(json.dumps(meta).encode(), np.uint8)
    return grid


def write_vtu(mesh: TetMesh, path: str | os.PathLike, point_data: dict | None = None,
              cell_data: dict | None = None, field_data: dict | None = None) -> Path:
    """Write ``mesh`` (with optional point arrays (n_points, ...) and cell arrays
    (n_cells, ...), e.g. FEM fields, and field data: lists of text or numbers) to a binary
    ``.vtu`` file atomically; returns the path. Facet-set triangles carry NaN in the extra
    cell arrays."""
    path = Path(path)
    if path.suffix != ".vtu":
        raise DataError(f"mesh file {path} must end in .vtu")
    return atomic_write_bytes(path, vtu_bytes(mesh, point_data, cell_data, field_data))


def vtu_bytes(mesh: TetMesh, point_data: dict | None = None, cell_data: dict | None = None,
              field_data: dict | None = None) -> bytes:
    """The binary ``.vtu`` file of :func:`write_vtu`, made in memory."""
    grid = to_pyvista(mesh)
    for k, v in (point_data or {}).items():
        grid.point_data[k] = np.asarray(v, float)
    n_extra = grid.n_cells - mesh.n_cells
    for k, v in (cell_data or {}).items():
        v = np.asarray(v, float)
        grid.cell_data[k] = np.concatenate([v, np.full((n_extra,) + v.shape[1:], np.nan)])
    for k, v in (field_data or {}).items():
        grid.field_data[k] = list(v) if isinstance(v, (list, tuple)) else v
    # VTK's file writer corrupts memory when the disk fills (an abort, a segfault): the file
    # is made in memory, as pyvista's save would write it, and written here
    from pyvista.core.utilities.writer import XMLUnstructuredGridWriter

    writer = XMLUnstructuredGridWriter("mesh.vtu", grid)
    writer._apply_kwargs_safely(texture=None, data_format="binary", compression="zlib")
    writer.writer.WriteToOutputStringOn()
    writer.writer.Write()
    return writer.writer.GetOutputString().encode()


def read_vtu(path: str | os.PathLike) -> TetMesh:
    """Read a mesh written by :func:`write_vtu`."""
    import pyvista as pv

    path = Path(path)
    if not path.is_file():
        raise DataError(f"mesh file {path} does not exist")
    grid = pv.read(path)
    if _META not in grid.field_data:
        raise DataError(f"mesh file {path} has no '{_META}' field data (not written by designlab)")
    meta = json.loads(np.asarray(grid.field_data[_META], np.uint8).tobytes().decode())
    types = np.asarray(grid.celltypes)
    conn = np.asarray(grid.cell_connectivity, np.int64)
    offsets = np.asarray(grid.cell_offsets, np.int64)
    tet_type = pv.CellType.TETRA if meta["order"] == 1 else pv.CellType.QUADRATIC_TETRA
    npc = 4 if meta["order"] == 1 else 10
    npf = 3 if meta["order"] == 1 else 6

    def block(mask, width):
        starts = offsets[:-1][mask]
        return conn[starts[:, None] + np.arange(width)]

    is_tet = types == tet_type
    region = np.asarray(grid.cell_data["region"], np.int64)[is_tet]
    fset_id = np.asarray(grid.cell_data["facet_set"], np.int64)
    tri_all = block(~is_tet, npf) if (~is_tet).any() else np.zeros((0, npf), np.int64)
    fset_of_tri = fset_id[~is_tet]
    facet_sets = {name: tri_all[fset_of_tri == k] for k, name in enumerate(meta["facet_sets"])}
    return TetMesh(np.asarray(grid.points, float), block(is_tet, npc), region,
                   {int(k): v for k, v in meta["region_names"].items()}, dict(meta["materials"]),
                   facet_sets,
                   {k: np.asarray(v, np.int64) for k, v in meta["point_sets"].items()})
