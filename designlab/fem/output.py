"""Result files: VTU fields (pyvista, via mesh.io) and a PNG of the deformed shape (pyvista off screen).

Both writers are atomic (temporary file in the target folder, then ``os.replace``). TET10 cells
are written as VTK quadratic tetrahedra (same node order as C3D10). PNG rendering needs an X
server for the VTK wheels here: :func:`designlab.geometry.render.ensure_display` starts a
private Xvfb when ``DISPLAY`` is unset; without one a matplotlib (Agg) picture of the deformed
boundary is drawn instead.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from designlab.atomic import atomic_path
from designlab.mesh.tetmesh import TetMesh


def write_vtu(path, mesh: TetMesh, point_data: dict | None = None,
              cell_data: dict | None = None, field_data: dict | None = None) -> Path:
    """Write ``mesh`` with point/cell arrays ((n, ...) / (m, ...)) and field data to a .vtu
    file atomically (:func:`designlab.mesh.io.write_vtu`: regions, facet sets and names
    included)."""
    from designlab.mesh.io import write_vtu as write_mesh_vtu

    return write_mesh_vtu(mesh, path, point_data, cell_data, field_data)


def result_fields(result, which=None) -> tuple[dict, dict]:
    """(point_data, cell_data) of a StaticResult (``which`` = case, default first) or a
    HistoryResult (``which`` = step, default last; batch: (case index, step)): displacement
    (mm), cell-mean strain (xx yy zz xy xz yz), and for static results stress and von Mises
    (MPa)."""
    from designlab.fem.static import von_mises

    model = result.model
    if hasattr(result, "history"):
        step = -1 if which is None else which
        if result.batch:
            case, step = (0, -1) if which is None else which
            u = result.U[:, case, step]
        else:
            u = result.U[:, step]
        eps = (model.B @ u[: 3 * model.n_points]).reshape(model.mesh.n_cells, -1, 6)
        return ({"displacement": u[: 3 * model.n_points].reshape(-1, 3)},
                {"strain": eps.mean(1)})
    case = result.cases[0] if which is None else which
    s = result.stress(case)
    return ({"displacement": result.displacement(case)},
            {"strain": result.strain(case).mean(1), "stress": s.mean(1),
             "von_mises": von_mises(s).mean(1)})


def write_result_vtu(path, result, which=None) -> Path:
    """VTU of a result's fields (see :func:`result_fields`)."""
    pd, cd = result_fields(result, which)
    return write_vtu(path, result.model.mesh, pd, cd)


def auto_scale(mesh: TetMesh, u: np.ndarray, fraction: float = 0.1) -> float:
    """Warp factor making the largest displacement ``fraction`` of the bounding-box diagonal."""
    umax = float(np.linalg.norm(u, axis=1).max()) if len(u) else 0.0
    diag = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    return fraction * diag / umax if umax > 0 else 1.0


def write_png(path, mesh: TetMesh, u: np.ndarray, scale: float | str = "auto",
              title: str = "", size=(800, 600), loads=(), case: str = "") -> Path:
    """PNG of the deformed mesh (warped by ``u`` x ``scale``) coloured by |u| (mm), atomic.
    Every region is drawn with its outline and listed (name, material); ``loads``: arrows
    ``(point, direction, force_N)`` pointing at where the load acts; ``case``: the load case
    in words (printed under the title)."""
    from designlab.geometry.render import ensure_display

    path = Path(path)
    u = np.asarray(u, float).reshape(-1, 3)
    k = auto_scale(mesh, u) if scale == "auto" else float(scale)
    label = f"{title + '  ' if title else ''}displacement magnitude (mm), warp x{k:.3g}"
    bodies = ", ".join(f"{mesh.region_names[r]} ({mesh.materials.get(mesh.region_names[r], '?')})"
                       for r in sorted(mesh.region_names) if np.any(mesh.region == r))
    lines = [label] + ([f"load case: {case}"] if case else []) + [f"bodies: {bodies}"]
    with atomic_path(path) as tmp:
        if ensure_display():
            _png_pyvista(tmp, mesh, u, k, "\n".join(_wrap(lines, size[0])), size, loads)
        else:
            _png_matplotlib(tmp, mesh, u, k, "\n".join(_wrap(lines, size[0])), size, loads)
    return path


def _wrap(lines: list[str], width_px: int) -> list[str]:
    import textwrap

    n = max(40, width_px // 8)
    return [w for line in lines for w in textwrap.wrap(line, n)]


def _arrow_geometry(mesh: TetMesh, loads):
    """(start, direction, length, text) of each load arrow: it ends at the load point."""
    diag = float(np.linalg.norm(np.ptp(mesh.points, axis=0)))
    out = []
    for point, direction, force in loads:
        if point is None or direction is None:
            continue
        d = np.asarray(direction, float)
        d = d / (np.linalg.norm(d) or 1.0)
        L = 0.3 * diag
        out.append((np.asarray(point, float) - L * d, d, L,
                    f"F = {force:.3g} N" if force is not None else "F"))
    return out


def _png_pyvista(path, mesh, u, k, label, size, loads=()):
    import pyvista as pv

    pv.OFF_SCREEN = True
    ctype = pv.CellType.QUADRATIC_TETRA if mesh.order == 2 else pv.CellType.TETRA
    cells = np.hstack([np.full((mesh.n_cells, 1), mesh.cells.shape[1]), mesh.cells]).ravel()
    grid = pv.UnstructuredGrid(cells, np.full(mesh.n_cells, ctype, np.uint8),
                               np.asarray(mesh.points, float))
    grid.point_data["u"] = u
    grid.point_data["displacement (mm)"] = np.linalg.norm(u, axis=1)
    pl = pv.Plotter(off_screen=True, window_size=list(size))
    pl.set_background("white")
    grid.cell_data["region"] = np.asarray(mesh.region)
    warped = grid.warp_by_vector("u", factor=k)
    pl.add_mesh(grid.outline(), color="grey")
    pl.add_mesh(warped, scalars="displacement (mm)", cmap="viridis", show_edges=False,
                scalar_bar_args={"title": "displacement (mm)", "color": "black"})
    for r in np.unique(mesh.region):      # each body's outline, so that every body shows
        body = warped.extract_cells(np.flatnonzero(mesh.region == r))
        pl.add_mesh(body.extract_feature_edges(feature_angle=40), color="black",
                    line_width=1)
    for start, d, L, text in _arrow_geometry(mesh, loads):
        pl.add_mesh(pv.Arrow(start=start, direction=d, scale=L, tip_length=0.25,
                             tip_radius=0.08, shaft_radius=0.03), color="red")
        pl.add_point_labels([start], [text], text_color="red", font_size=14,
                            shape_opacity=0.0, show_points=False, always_visible=True)
    pl.add_text(label, position="upper_edge", font_size=9, color="black")
    pl.view_isometric()
    pl.reset_camera()
    pl.screenshot(str(path))
    pl.close()


def _png_matplotlib(path, mesh, u, k, label, size, loads=()):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    tri = mesh.boundary_facets()
    x = mesh.points + k * u
    mag = np.linalg.norm(u, axis=1)[tri].mean(1)
    fig = plt.figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    norm = plt.Normalize(mag.min(), max(mag.max(), mag.min() + 1e-30))
    ax.add_collection3d(Poly3DCollection(x[tri], facecolors=plt.cm.viridis(norm(mag)),
                                         linewidths=0))
    lo, hi = x.min(0), x.max(0)
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set(xlim=(c[0] - r, c[0] + r), ylim=(c[1] - r, c[1] + r), zlim=(c[2] - r, c[2] + r),
           xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)")
    for start, d, L, text in _arrow_geometry(mesh, loads):
        ax.quiver(*start, *(L * d), color="red", arrow_length_ratio=0.25)
        ax.text(*start, text, color="red")
    fig.colorbar(plt.cm.ScalarMappable(norm=norm, cmap="viridis"), ax=ax, label="|u| (mm)")
    ax.set_title(label, fontsize=9)
    fig.savefig(path, format="png")
    plt.close(fig)
