"""PNG pictures of a part: bodies in their colours, bought parts semi-transparent.

Rendering uses pyvista/VTK off screen. The VTK wheels pinned by CadQuery (9.3) need an X server:
when ``DISPLAY`` is unset, one private ``Xvfb`` is started for the process (``-displayfd`` picks a
free display) and stopped at exit; it also dies with the process however that one ends (kill -9
included: Linux parent-death signal). Without an X server and without ``Xvfb`` on the PATH, a
matplotlib (Agg) picture of the same triangles is drawn instead, so export never fails for lack of
a screen.
"""

from __future__ import annotations

import atexit
import os
import shutil
import subprocess
from pathlib import Path
from typing import Mapping

import numpy as np
import trimesh

from designlab.errors import ParameterError
from designlab.geometry.body import Body
from designlab.geometry.tessellate import tessellate

BOUGHT_OPACITY = 0.35
HOST_OPACITY = 0.55
_XVFB: subprocess.Popen | None = None


def _stop_xvfb() -> None:
    global _XVFB
    if _XVFB is not None and _XVFB.poll() is None:
        _XVFB.terminate()
        try:
            _XVFB.wait(timeout=5)
        except subprocess.TimeoutExpired:
            _XVFB.kill()
    _XVFB = None


def ensure_display() -> bool:
    """True when VTK can open a window: ``DISPLAY`` is set, or a private Xvfb was started."""
    global _XVFB
    if os.environ.get("DISPLAY"):
        return True
    xvfb = shutil.which("Xvfb")
    if xvfb is None:
        return False
    import threading

    from designlab.atomic import die_with_parent

    r, w = os.pipe()
    # the parent-death signal fires when the *thread* that started the child ends: arm it from
    # the main thread only (a worker thread's Xvfb is still stopped at exit)
    me = os.getpid()
    pre = ((lambda: die_with_parent(me)) if threading.current_thread() is threading.main_thread()
           else None)
    try:
        _XVFB = subprocess.Popen([xvfb, "-displayfd", str(w), "-screen", "0", "1600x1200x24",
                                  "-nolisten", "tcp"], pass_fds=(w,), preexec_fn=pre,
                                 stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    finally:
        os.close(w)
    num = b""
    with os.fdopen(r, "rb") as fh:  # Xvfb writes the display number once it is ready
        num = fh.readline().strip()
    if not num:
        _stop_xvfb()
        return False
    atexit.register(_stop_xvfb)
    os.environ["DISPLAY"] = ":" + num.decode()
    return True


def _meshes(bodies: Mapping[str, Body], tolerance: float) -> list[tuple[Body, trimesh.Trimesh]]:
    return [(b, tessellate(b.shape, tolerance, 0.5, check=False)) for b in bodies.values()]


def _opacity(body: Body, items) -> float:
    """Bought parts are see-through; so are the printed host bodies of a part that has bought
    parts or bodies on a second extruder (traces) inside, so that those show."""
    if not body.printed:
        return BOUGHT_OPACITY
    inner = any(not b.printed or b.extruder > 1 for b, _ in items)
    return HOST_OPACITY if inner and body.extruder == 1 else 1.0


def _swatch(pl, x: int, y: int, side: int, color) -> None:
    """A filled square of ``color`` at pixel (x, y) (lower left) over the scene."""
    # the classes' own modules: ``import vtk`` loads every VTK module (0.16 s CPU beyond
    # pyvista's, ``python benchmarks/bench_imports.py``)
    from vtkmodules.vtkCommonCore import vtkPoints
    from vtkmodules.vtkCommonDataModel import vtkCellArray, vtkPolyData
    from vtkmodules.vtkRenderingCore import vtkActor2D, vtkPolyDataMapper2D

    pts = vtkPoints()
    for a, b in ((x, y), (x + side, y), (x + side, y + side), (x, y + side)):
        pts.InsertNextPoint(a, b, 0.0)
    poly = vtkCellArray()
    poly.InsertNextCell(4)
    for i in range(4):
        poly.InsertCellPoint(i)
    data = vtkPolyData()
    data.SetPoints(pts)
    data.SetPolys(poly)
    mapper = vtkPolyDataMapper2D()
    mapper.SetInputData(data)
    actor = vtkActor2D()
    actor.SetMapper(mapper)
    actor.GetProperty().SetColor(*[float(c) for c in color[:3]])
    pl.renderer.AddActor2D(actor)


def _render_pyvista(items, path: Path, size: tuple[int, int], title: str) -> None:
    import pyvista as pv

    pl = pv.Plotter(off_screen=True, window_size=list(size))
    pl.set_background("white")
    for body, m in items:
        faces = np.hstack([np.full((len(m.faces), 1), 3), m.faces]).ravel()
        pl.add_mesh(pv.PolyData(np.asarray(m.vertices), faces), color=body.color,
                    opacity=_opacity(body, items), smooth_shading=False, specular=0.2)
    # legend: a swatch in the body's colour, the text in black (a pale body stays readable)
    line = max(16, size[1] // 36)
    for i, (body, _) in enumerate(items):
        y = size[1] - int(2.6 * line) - i * int(1.25 * line)
        _swatch(pl, 12, y, int(0.8 * line), (0.3, 0.3, 0.3))
        _swatch(pl, 13, y + 1, int(0.8 * line) - 2, body.color)
        pl.add_text(f"{body.name} ({body.material}{'' if body.printed else ', bought'})",
                    position=(12 + line + 4, y - 2), font_size=max(7, line // 2), color="black")
    if title:
        pl.add_text(title, position="upper_edge", font_size=12, color="black")
    pl.view_isometric()
    pl.enable_parallel_projection()
    pl.reset_camera()
    pl.screenshot(str(path))
    pl.close()


def _render_matplotlib(items, path: Path, size: tuple[int, int], title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from mpl_toolkits.mplot3d.art3d import Poly3DCollection

    fig = plt.figure(figsize=(size[0] / 100, size[1] / 100), dpi=100)
    ax = fig.add_subplot(projection="3d")
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for body, m in items:
        shade = 0.45 + 0.55 * np.clip(m.face_normals @ light, 0, 1)
        rgb = np.clip(np.outer(shade, body.color), 0, 1)
        alpha = _opacity(body, items)
        ax.add_collection3d(Poly3DCollection(m.triangles, facecolors=np.c_[rgb, np.full(
            len(rgb), alpha)], linewidths=0, label=f"{body.name} ({body.material})"))
        lo, hi = np.minimum(lo, m.bounds[0]), np.maximum(hi, m.bounds[1])
    c, r = (lo + hi) / 2, (hi - lo).max() / 2
    ax.set(xlim=(c[0] - r, c[0] + r), ylim=(c[1] - r, c[1] + r), zlim=(c[2] - r, c[2] + r),
           xlabel="x (mm)", ylabel="y (mm)", zlabel="z (mm)")
    ax.set_box_aspect((1, 1, 1))
    from matplotlib.patches import Patch

    ax.legend(handles=[Patch(facecolor=b.color, edgecolor="0.3", label=f"{b.name} ({b.material})")
                       for b, _ in items], loc="upper left", bbox_to_anchor=(1.02, 1.0),
              labelcolor="black", frameon=False)
    if title:
        ax.set_title(title)
    fig.savefig(path, bbox_inches="tight")
    plt.close(fig)


def render_bodies(bodies: Mapping[str, Body], path: str | Path, size: tuple[int, int] = (1200, 900),
                  title: str = "", tolerance: float = 0.1, backend: str = "auto") -> str:
    """Write a PNG of ``bodies`` to ``path``; returns the backend used (``pyvista`` or
    ``matplotlib``). ``backend="auto"`` prefers pyvista when an X display can be had."""
    check_size(size)
    return render_items(_meshes(bodies, tolerance), path, size, title, backend)


#: largest render side, px (20000 x 20000 exhausted the X server and killed the interpreter)
MAX_RENDER_PX = 8000


def check_size(size) -> tuple[int, int]:
    """``size`` as (width, height): two whole numbers of pixels, 64 to :data:`MAX_RENDER_PX`."""
    try:
        w, h = size
    except (TypeError, ValueError):
        w = h = None
    if not all(isinstance(v, (int, np.integer)) and not isinstance(v, bool)
               and 64 <= v <= MAX_RENDER_PX for v in (w, h)):
        raise ParameterError("size", size, f"(width, height) in whole pixels, 64 to "
                             f"{MAX_RENDER_PX} each")
    _check_address_space(size, int(w) * int(h))
    return int(w), int(h)


#: address space a render takes beyond the process's own: the renderer's set-up and its bytes
#: per pixel (measured peaks: 684 MB at 256 x 256, then 91 B per pixel up to 4096 x 4096)
RENDER_BASE_BYTES = 800e6
RENDER_BYTES_PER_PX = 100.0


def _check_address_space(size, pixels: int) -> None:
    """Refuse a render that cannot fit the process's address-space limit (``ulimit -v``): the
    renderer aborts the interpreter when an allocation fails (8000 x 8000 under 6 GB)."""
    import resource

    limit, _ = resource.getrlimit(resource.RLIMIT_AS)
    if limit == resource.RLIM_INFINITY:
        return
    try:
        with open("/proc/self/statm") as fh:
            used = int(fh.read().split()[0]) * resource.getpagesize()
    except (OSError, ValueError, IndexError):
        return
    room = limit - used - RENDER_BASE_BYTES
    if RENDER_BYTES_PER_PX * pixels > room:
        side = int(np.sqrt(max(room, 0.0) / RENDER_BYTES_PER_PX)) // 256 * 256  # with room
        raise ParameterError("size", size, f"a render that fits the {limit / 1e9:.3g} GB "
                             f"address-space limit of this process: about {side} x {side} px "
                             "or fewer")


def portable_items(bodies: Mapping[str, Body], tolerance: float = 0.1) -> list[tuple]:
    """The bodies tessellated as plain data that pickles (another process draws them with
    :func:`render_items`): ``(body without its shape, vertices, faces)`` per body."""
    import dataclasses

    return [(dataclasses.replace(b, shape=None), np.asarray(m.vertices), np.asarray(m.faces))
            for b, m in _meshes(bodies, tolerance)]


def render_items(items, path: str | Path, size: tuple[int, int] = (1200, 900), title: str = "",
                 backend: str = "auto") -> str:
    """:func:`render_bodies` of tessellated bodies: ``(Body, trimesh)`` pairs or the
    :func:`portable_items` triples."""
    check_size(size)
    items = [it if len(it) == 2 else (it[0], trimesh.Trimesh(it[1], it[2], process=False))
             for it in items]
    path = Path(path)
    if backend == "auto":
        backend = "pyvista" if ensure_display() else "matplotlib"
    if backend == "pyvista":
        _render_pyvista(items, path, size, title)
    elif backend == "matplotlib":
        _render_matplotlib(items, path, size, title)
    else:
        from designlab.errors import ParameterError

        raise ParameterError("backend", backend, "one of auto, pyvista, matplotlib")
    return backend
