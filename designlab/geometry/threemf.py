"""3MF writer: one printable object made of several volumes (bodies), each on its own extruder.

A multi-material part (the strap with its conductive traces) must reach the slicer as ONE object
whose volumes stay where they were modelled; separate 3MF objects (or ``<components>``) are dropped
to the bed and arranged apart by PrusaSlicer. So the file holds:

* ``3D/3dmodel.model`` (3MF core): a single ``<object>`` whose triangles are the concatenation of
  the volumes' triangles (each volume a closed shell with its own vertices), and a
  ``<basematerials>`` group with one ``<base>`` per volume, referenced per triangle (``pid``/``p1``)
  so any core reader (lib3mf, trimesh, Cura...) sees the materials and colours;
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


def model_xml(object_name: str, volumes: Sequence[Volume3MF]) -> tuple[str, list[tuple[int, int]]]:
    """The ``3dmodel.model`` text and each volume's (first, last) triangle index."""
    if not volumes:
        raise ParameterError("volumes", 0, "at least one body to write")
    vert_blocks, tri_blocks, ranges = [], [], []
    v_off = t_off = 0
    for k, vol in enumerate(volumes):
        v = np.asarray(vol.vertices, float)
        f = np.asarray(vol.faces, np.int64)
        if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3 or len(f) == 0:
            raise ParameterError(f"volume {vol.name!r}", f"{v.shape}/{f.shape}",
                                 "vertices (n, 3) and at least one triangle (m, 3)")
        if not (np.isfinite(v).all() and f.min() >= 0 and f.max() < len(v)):
            raise ParameterError(f"volume {vol.name!r}", "mesh",
                                 "finite vertices and triangle indices within range")
        vert_blocks.append(_lines('<vertex x="%.9g" y="%.9g" z="%.9g"/>', v))
        # volume 0 takes the object's default property (pindex 0); others name theirs per triangle
        fmt = ('<triangle v1="%d" v2="%d" v3="%d"/>' if k == 0 else
               f'<triangle v1="%d" v2="%d" v3="%d" pid="1" p1="{k}"/>')
        tri_blocks.append(_lines(fmt, f + v_off))
        ranges.append((t_off, t_off + len(f) - 1))
        v_off += len(v)
        t_off += len(f)
    bases = "\n".join(
        f'<base name={quoteattr(vol.material or vol.name)} displaycolor="{hex_color(vol.color)}"/>'
        for vol in volumes)
    name = quoteattr(object_name)
    text = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        f'<model unit="millimeter" xml:lang="en-US" xmlns="{CORE_NS}" '
        f'xmlns:slic3rpe="{SLIC3RPE_NS}">\n'
        '<metadata name="slic3rpe:Version3mf">1</metadata>\n'
        f'<metadata name="Title">{escape(object_name)}</metadata>\n'
        '<metadata name="Application">designlab</metadata>\n'
        '<resources>\n'
        f'<basematerials id="1">\n{bases}\n</basematerials>\n'
        f'<object id="2" type="model" name={name} pid="1" pindex="0">\n<mesh>\n'
        '<vertices>\n' + "\n".join(vert_blocks) + '\n</vertices>\n'
        '<triangles>\n' + "\n".join(tri_blocks) + '\n</triangles>\n'
        '</mesh>\n</object>\n</resources>\n'
        '<build>\n<item objectid="2"/>\n</build>\n</model>\n')
    return text, ranges


def prusa_config_xml(object_name: str, volumes: Sequence[Volume3MF],
                     ranges: Sequence[tuple[int, int]]) -> str:
    """``Metadata/Slic3r_PE_model.config``: volumes as triangle ranges with their extruder."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>",
           ' <object id="2" instances_count="1">',
           f'  <metadata type="object" key="name" value={quoteattr(object_name)}/>',
           f'  <metadata type="object" key="extruder" value="{volumes[0].extruder}"/>']
    for vol, (first, last) in zip(volumes, ranges):
        out += [f'  <volume firstid="{first}" lastid="{last}">',
                f'   <metadata type="volume" key="name" value={quoteattr(vol.name)}/>',
                '   <metadata type="volume" key="volume_type" value="ModelPart"/>',
                f'   <metadata type="volume" key="matrix" value="{IDENTITY_4X4}"/>',
                f'   <metadata type="volume" key="extruder" value="{vol.extruder}"/>',
                '   <mesh edges_fixed="0" degenerate_facets="0" facets_removed="0" '
                'facets_reversed="0" backwards_edges="0"/>',
                '  </volume>']
    out += [" </object>", "</config>", ""]
    return "\n".join(out)


def bambu_config_xml(object_name: str, volumes: Sequence[Volume3MF],
                     ranges: Sequence[tuple[int, int]]) -> str:
    """``Metadata/model_settings.config`` (BambuStudio/OrcaSlicer) for the same volumes."""
    out = ['<?xml version="1.0" encoding="UTF-8"?>', "<config>", '  <object id="2">',
           f'    <metadata key="name" value={quoteattr(object_name)}/>',
           f'    <metadata key="extruder" value="{volumes[0].extruder}"/>']
    for k, (vol, (first, last)) in enumerate(zip(volumes, ranges)):
        out += [f'    <part id="{k + 1}" subtype="normal_part" firstid="{first}" '
                f'lastid="{last}">',
                f'      <metadata key="name" value={quoteattr(vol.name)}/>',
                f'      <metadata key="matrix" value="{IDENTITY_4X4}"/>',
                f'      <metadata key="extruder" value="{vol.extruder}"/>',
                '    </part>']
    out += ["  </object>", "</config>", ""]
    return "\n".join(out)


def threemf_bytes(object_name: str, volumes: Sequence[Volume3MF]) -> bytes:
    """A complete .3mf archive (bytes) holding one object made of ``volumes``."""
    for vol in volumes:
        if not (isinstance(vol.extruder, int) and 1 <= vol.extruder <= 16):
            raise ParameterError(f"extruder of {vol.name!r}", vol.extruder, "1 <= value <= 16")
    model, ranges = model_xml(object_name, volumes)
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", compression=zipfile.ZIP_DEFLATED) as z:
        z.writestr("[Content_Types].xml", CONTENT_TYPES)
        z.writestr("_rels/.rels", RELS)
        z.writestr(MODEL_PATH, model)
        z.writestr(PRUSA_CONFIG_PATH, prusa_config_xml(object_name, volumes, ranges))
        z.writestr(BAMBU_CONFIG_PATH, bambu_config_xml(object_name, volumes, ranges))
    return buf.getvalue()
