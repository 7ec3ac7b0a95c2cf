"""What a part offers in Python and notebooks: ``part.params()`` (a table of name, value, unit,
allowed values, meaning), ``part.show()`` (pyvista: interactive in a notebook, an off-screen PNG
in a script) and ``_repr_png_`` (Jupyter shows the part)."""

from __future__ import annotations

import dataclasses
import html
from pathlib import Path
from typing import Any

from designlab.params import allowed_text


def field_rows(obj_or_cls: Any) -> list[dict[str, Any]]:
    """One row per field of a parameter dataclass: name, value (default for a class), default,
    unit, allowed values, meaning (the metadata's ``doc``)."""
    cls = obj_or_cls if isinstance(obj_or_cls, type) else type(obj_or_cls)
    rows = []
    for f in dataclasses.fields(cls):
        if f.name.startswith("_"):
            continue
        meta = dict(f.metadata or {})
        default = f.default if f.default is not dataclasses.MISSING else (
            f.default_factory() if f.default_factory is not dataclasses.MISSING else None)
        value = default if isinstance(obj_or_cls, type) else getattr(obj_or_cls, f.name)
        if meta.get("lo") is None and meta.get("hi") is None and not meta.get("choices"):
            allowed = {bool: "true or false", int: "an integer", float: "a number",
                       str: "text", tuple: "a list"}.get(type(default), "")
        else:
            allowed = allowed_text(meta)
        rows.append({"name": f.name, "value": value, "default": default,
                     "unit": meta.get("unit", ""), "allowed": allowed,
                     "meaning": meta.get("doc", "")})
    return rows


class ParamTable(list):
    """Rows of :func:`field_rows`; prints as text, shows as HTML."""

    COLUMNS = ("name", "value", "unit", "allowed", "meaning")

    def rows_text(self) -> list[list[str]]:
        def f(v: Any) -> str:
            if isinstance(v, float):
                return f"{v:.6g}"
            if isinstance(v, bool):
                return "true" if v else "false"
            return "" if v is None else str(v)
        return [[f(r[c]) for c in self.COLUMNS] for r in self]

    def __str__(self) -> str:
        rows = [list(self.COLUMNS)] + self.rows_text()
        w = [max(len(r[i]) for r in rows) for i in range(len(self.COLUMNS))]
        return "\n".join("  ".join(c.ljust(w[i]) for i, c in enumerate(r)).rstrip() for r in rows)

    def _repr_html_(self) -> str:
        head = "".join(f"<th>{c}</th>" for c in self.COLUMNS)
        body = "".join("<tr>" + "".join(f"<td>{html.escape(c)}</td>" for c in r) + "</tr>"
                       for r in self.rows_text())
        return f"<table><tr>{head}</tr>{body}</table>"


def _in_notebook() -> bool:
    try:
        from IPython import get_ipython
    except ImportError:
        return False
    ip = get_ipython()
    return ip is not None and type(ip).__name__ == "ZMQInteractiveShell"


class PartAPI:
    """Mixin of the part dataclasses (no fields)."""

    def params(self) -> ParamTable:
        """Every parameter: name, value, unit, allowed values, meaning."""
        return ParamTable(field_rows(self))

    def render(self, path: str | Path, size: tuple[int, int] = (900, 675)) -> Path:
        """A PNG of the part (bodies coloured, bought parts see-through) at ``path``."""
        from designlab.geometry.render import check_size, render_bodies

        check_size(size)      # before the part is built
        path = Path(path)
        render_bodies(self.build(), path, size=size, title=type(self).__name__)
        return path

    def show(self, path: str | Path | None = None):
        """In a notebook: an interactive pyvista view. In a script: an off-screen PNG at
        ``path`` (default ``<ClassName>.png`` in the working folder), returned."""
        if _in_notebook() and path is None:
            import pyvista as pv

            from designlab.geometry.render import _meshes, _opacity, ensure_display

            ensure_display()
            items = _meshes(self.build(), 0.1)
            pl = pv.Plotter(notebook=True)
            for body, m in items:
                import numpy as np

                faces = np.hstack([np.full((len(m.faces), 1), 3), m.faces]).ravel()
                pl.add_mesh(pv.PolyData(np.asarray(m.vertices), faces), color=body.color,
                            opacity=_opacity(body, items), label=f"{body.name} ({body.material})")
            return pl.show()
        return self.render(path or f"{type(self).__name__}.png")

    def _repr_png_(self) -> bytes:
        import tempfile

        with tempfile.TemporaryDirectory() as d:
            return self.render(Path(d) / "part.png", size=(640, 480)).read_bytes()
