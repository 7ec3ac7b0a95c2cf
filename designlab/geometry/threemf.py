"""3MF writer: printable objects made of volumes (bodies), each volume on its own extruder.

A multi-material body group (the strap with its conductive traces) must reach the slicer as ONE
object whose volumes stay where they were modelled; separate 3MF objects (or ``<components>``) are
dropped to the bed and arranged apart by PrusaSlicer. So the file holds:

* ``3D/3dmodel.model`` (3MF core): per object one mesh whose triangles are the concatenation of
  its volumes' triangles (each volume a closed shell with its own vertices), a
  ``<basematerials>`` group with one ``<base>`` per material, referenced per triangle
  (``pid``/``p1``) so any core reader (lib3mf, trimesh, Cura...) sees materials and colours, and
  one build item per object placing it on the plate;
* ``Metadata/Slic3r_PE_model.config`` (PrusaSlicer and its forks): per volume the triangle range
  ``firstid``/``lastid`` and metadata ``name``, ``volume_type`` = ``ModelPart``, identity
  ``matrix`` and ``extruder``;
* ``Metadata/model_settings.config`` (BambuStudio/OrcaSlicer): the same volumes as ``<part>``
  entries with their triangle ranges and ``extruder``.

Units: millimetre. The writer only builds bytes; callers write them atomically.
"""

from __future__ import annotations

import io
import zipfile
from dataclasses import dataclass
from typing import Sequence
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from designlab.errors import ParameterError

CORE_NS = "http://schemas.microsoft.com/3dmanufacturing/core/2015/02"
SLIC3RPE_NS = "http://schemas.slic3r.org/3mf/2017/06"
MODEL_PATH = "3D/3dmodel.model"
PRUSA_CONFIG_PATH = "Metadata/Slic3r_PE_model.config"
BAMBU_CONFIG_PATH = "Metadata/model_settings.config"

CONTENT_TYPES = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Types xmlns="http://schemas.openxmlformats.org/package/2006/content-types">'
    '<Default Extension="rels" '
    'ContentType="application/vnd.openxmlformats-package.relationships+xml"/>'
    '<Default Extension="model" '
    'ContentType="application/vnd.ms-package.3dmanufacturing-3dmodel+xml"/>'
    '<Default Extension="config" ContentType="application/xml"/>'
    '</Types>\n')
RELS = (
    '<?xml version="1.0" encoding="UTF-8"?>\n'
    '<Relationships xmlns="http://schemas.openxmlformats.org/package/2006/relationships">'
    '<Relationship Target="/3D/3dmodel.model" Id="rel0" '
    'Type="http://schemas.microsoft.com/3dmanufacturing/2013/01/3dmodel"/>'
    '</Relationships>\n')
IDENTITY_4X4 = "1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1"


@dataclass(frozen=True, eq=False)
class Volume3MF:
    """One closed shell of a 3MF object: vertices (n, 3) mm, faces (m, 3) int (outward)."""

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    extruder: int = 1
    material: str = ""
    color: tuple[float, float, float] = (0.7, 0.7, 0.7)


def hex_color(rgb: Sequence[float]) -> str:
    """``(r, g, b)`` in 0..1 -> ``#RRGGBBFF``."""
    c = np.clip(np.round(np.asarray(rgb, float)[:3] * 255), 0, 255).astype(int)
    return "#{:02X}{:02X}{:02X}FF".format(*c)


def _lines(fmt: str, rows: np.ndarray) -> str:
    return "\n".join(fmt % tuple(r) for r in rows.tolist())


@dataclass(frozen=True, eq=False)
class Object3MF:
    """One printable object: its volumes keep their relative placement; ``translation`` (mm)
    places the object on the build plate (the 3MF build item's transform)."""

    name: str
    volumes: Sequence[Volume3MF]
    translation: tuple[float, float, float] = (0.0, 0.0, 0.0)


def _check_volume(vol: Volume3MF) -> tuple[np.ndarray, np.ndarray]:
    v = np.asarray(vol.vertices, float)
    f = np.asarray(vol.faces, np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
        raise ParameterError(f"volume {vol.name!r}", f"{v.shape}/{f.shape}",
                             "vertices (n, 3) and at least one triangle (m, 3)")
    if not (np.isfinite(v).all() and f.min() >= 0 and f.max() < len(v)):
        raise ParameterError(f"volume {vol.name!r}", "mesh",
                             "finite vertices and triangle indices within range")
    if not (isinstance(vol.extruder, int) and 1 <= vol.extruder <= 16):
        raise ParameterError(f"extruder of {vol.name!r}", vol.extruder, "1 <= value <= 16")
    return v, f


def _base_key(vol: Volume3MF) -> tuple[str, str]:
    return (vol.material or vol.name, hex_color(vol.color))


def model_xml(title: str, objects: Sequence[Object3MF]) -> tuple[str, list[list[tuple[int, int]]]]:
    """The ``3dmodel.model`` text and, per object, each volume's (first, last) triangle index.

    Resource 1 is a ``<basematerials>`` group (one ``<base>`` per material/colour); objects are
    resources 2, 3, ... Each object's default property is its first volume's base; triangles of
    volumes with another base name theirs with ``pid``/``p1``."""
    if not objects or not all(o.volumes for o in objects):
        raise ParameterError("objects", len(objects), "at least one object with one volume")
    bases: dict[tuple[str, str], int] = {}
    for o in objects:
        for vol in o.volumes:
            bases.setdefault(_base_key(vol), len(bases))
    obj_xml, build, all_ranges = [], [], []
    for j, o in enumerate(objects):
        oid = 2 + j
        default = bases[_base_key(o.volumes[0])]
        vert_blocks, tri_blocks, ranges = [], [], []
        v_off = t_off = 0
        for vol in o.volumes:
            v, f = _check_volume(vol)
            vert_blocks.append(_lines('<vertex x="%.9g" y="%.9g" z="%.9g"/>', v))
            b = bases[_base_key(vol)]
            fmt = ('<triangle v1="%d" v2="%d" v3="%d"/>' if b == default else
                   f'<triangle v1="%d" v2="%d" v3="%d" pid="1" p1="{b}"/>')
            tri_blocks.append(_lines(fmt, f + v_off))
            ranges.append((t_off, t_off + len(f) - 1))
            v_off += len(v)
            t_off += len(f)
        all_ranges.append(ranges)
        obj_xml.append(
            f'<object id="{oid}" type="model" name={quoteattr(o.name)} pid="1" '
            f'pindex="{default}">\n<mesh>\n'
            '<vertices>\n' + "\n".join(vert_blocks) + '\n</vertices>\n'
            '<triangles>\n' + "\n".join(tri_blocks) + '\n</triangles>\n</mesh>\n</object>')
        tx, ty, tz = (float(t) for t in o.translation)
        build.append(f'<item objectid="{oid}" transform="1 0 0 0 1 0 0 0 1 '
                     f'{tx:.9g} {ty:.9g} {tz:.9g}"/>')
    base_xml = "\n".join(f'<base name={quoteattr(name)} displaycolor="{color}"/>'
                         for (name, color) in bases)
    text = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<model unit="millimeter" xml:lang="en-US" xmlns="{CORE_NS}" '
        f'xmlns:slic3rpe="{SLIC3RPE_NS}">\n'
        '<metadata name="slic3rpe:Version3mf">1</metadata>\n'
        f'<metadata name="Title">{escape(title)}</metadata>\n'
        '<metadata name="Application">designlab</metadata>\n'
        '<resources>\n'
        f'<basematerials id="1">\n{base_xml}\n</basematerials>\n'
        + "\n".join(obj_xml) + '\n</resources>\n'
        '<build>\n' + "\n".join(build) + '\n</build>\n</model>\n')
    return text, all_ranges


def prusa_config_xml(objects: Sequence[Object3MF],
                     ranges: Sequence[Sequence[tuple[int, int]]]) -> str:
    """``Metadata/Slic3r_PE_model.config``: per object its volumes as triangle ranges with their
    name and extruder."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>"]
    for j, (o, rs) in enumerate(zip(objects, ranges)):
        out += [f' <object id="{2 + j}" instances_count="1">',
                f'  <metadata type="object" key="name" value={quoteattr(o.name)}/>',
                f'  <metadata type="object" key="extruder" value="{o.volumes[0].extruder}"/>']
        for vol, (first, last) in zip(o.volumes, rs):
            out += [f'  <volume firstid="{first}" lastid="{last}">',
                    f'   <metadata type="volume" key="name" value={quoteattr(vol.name)}/>',
                    '   <metadata type="volume" key="volume_type" value="ModelPart"/>',
                    f'   <metadata type="volume" key="matrix" value="{IDENTITY_4X4}"/>',
                    f'   <metadata type="volume" key="extruder" value="{vol.extruder}"/>',
                    '   <mesh edges_fixed="0" degenerate_facets="0" facets_removed="0" '
                    'facets_reversed="0" backwards_edges="0"/>',
                    '  </volume>']
        out.append(" </object>")
    out += ["</config>", ""]
    return "\n".join(out)


def bambu_config_xml(objects: Sequence[Object3MF],
                     ranges: Sequence[Sequence[tuple[int, int]]]) -> str:
    """``Metadata/model_settings.config`` (BambuStudio/OrcaSlicer) for the same volumes."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>"]
    for j, (o, rs) in enumerate(zip(objects, ranges)):
        out += [f'  <object id="{2 + j}">',
                f'    <metadata key="name" value={quoteattr(o.name)}/>',
                f'    <metadata key="extruder" value="{o.volumes[0].extruder}"/>']
        for k, (vol, (first, last)) in enumerate(zip(o.volumes, rs)):
            out += [f'    <part id="{k + 1}" subtype="normal_part" firstid="{first}" '
                    f'lastid="{last}">',
                    f'      <metadata key="name" value={quoteattr(vol.name)}/>',
                    f'      <metadata key="matrix" value="{IDENTITY_4X4}"/>',
                    f'      <metadata key="extruder" value="{vol.extruder}"/>',
                    '    </part>']
        out.append("  </object>")
    out += ["</config>", ""]
    return "\n".join(out)


def threemf_bytes(title: str, objects: Sequence[Object3MF]) -> bytes:
    """A complete .3mf archive (bytes) holding ``objects``."""
    model, ranges = model_xml(title, objects)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("[Content_Types].xml", CONTENT_TYPES)
        z.writestr("_rels/.rels", RELS)
        z.writestr(MODEL_PATH, model)
        z.writestr(PRUSA_CONFIG_PATH, prusa_config_xml(objects, ranges))
        z.writestr(BAMBU_CONFIG_PATH, bambu_config_xml(objects, ranges))
    return buf.getvalue()


def plate_layout(objects: Sequence[Object3MF], gap: float = 5.0) -> list[Object3MF]:
    """Objects placed in a row along x, ``gap`` mm apart, each resting on ``z = 0``, the row
    centred on the origin (a slicer re-centres it on its bed)."""
    boxes = []
    for o in objects:
        v = np.vstack([np.asarray(vol.vertices, float) for vol in o.volumes])
        boxes.append((v.min(0), v.max(0)))
    width = sum(hi[0] - lo[0] for lo, hi in boxes) + gap * (len(boxes) - 1)
    x = -width / 2
    out = []
    for o, (lo, hi) in zip(objects, boxes):
        t = (x - lo[0], -(lo[1] + hi[1]) / 2, -lo[2])
        out.append(Object3MF(o.name, o.volumes, t))
        x += hi[0] - lo[0] + gap
    return out
