"""B-rep -> triangle mesh: one tessellation shared by export, printability checks and meshing (mm).

Accepts a :class:`~designlab.geometry.body.Body`, a build123d or CadQuery shape (anything with a
``wrapped`` ``TopoDS_Shape``) or a raw ``TopoDS_Shape``. OpenCascade's ``BRepMesh`` meshes each
face with a chordal ``tolerance`` (mm) and an ``angular_tolerance`` (rad); faces share their edge
discretisation, so merging coincident vertices gives a closed, consistently oriented mesh.
The defaults (0.01 mm, 0.2 rad) stay well below a 0.1 mm print layer.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import trimesh

from designlab.errors import MeshingError


def topods(obj: Any):
    """The OCP ``TopoDS_Shape`` inside a Body, build123d/CadQuery shape or a TopoDS_Shape; a list
    of those (e.g. build123d's ``ShapeList`` from fusing disjoint solids) becomes a compound."""
    if isinstance(obj, (list, tuple)):
        from OCP.BRep import BRep_Builder
        from OCP.TopoDS import TopoDS_Compound

        if not obj:
            raise MeshingError("cannot tessellate an empty list of shapes")
        builder, comp = BRep_Builder(), TopoDS_Compound()
        builder.MakeCompound(comp)
        for item in obj:
            builder.Add(comp, topods(item))
        return comp
    shape = getattr(obj, "shape", obj)  # Body -> its shape
    shape = getattr(shape, "wrapped", shape)  # build123d / cadquery -> TopoDS_Shape
    if shape is None or not hasattr(shape, "IsNull") or shape.IsNull():
        raise MeshingError(f"cannot tessellate {type(obj).__name__}: not a non-empty B-rep shape")
    return shape


def triangulate(obj: Any, tolerance: float = 0.01,
                angular_tolerance: float = 0.2) -> tuple[np.ndarray, np.ndarray]:
    """Raw per-face triangulation: ``(vertices (n, 3) float mm, faces (m, 3) int)``, outward
    oriented, vertices not merged across faces."""
    from OCP.BRep import BRep_Tool
    from OCP.BRepMesh import BRepMesh_IncrementalMesh
    from OCP.BRepTools import BRepTools
    from OCP.TopAbs import TopAbs_FACE, TopAbs_REVERSED
    from OCP.TopExp import TopExp_Explorer
    from OCP.TopLoc import TopLoc_Location
    from OCP.TopoDS import TopoDS

    if not (tolerance > 0 and angular_tolerance > 0):
        raise MeshingError(f"tessellation tolerances must be > 0, got {tolerance}, "
                           f"{angular_tolerance}")
    shape = topods(obj)
    # drop any triangulation cached on the shape (e.g. a finer one from a glTF export), so the
    # result depends on the tolerances asked for only
    BRepTools.Clean_s(shape)
    BRepMesh_IncrementalMesh(shape, tolerance, False, angular_tolerance, True)
    verts, faces, offset = [], [], 0
    explorer = TopExp_Explorer(shape, TopAbs_FACE)
    while explorer.More():
        face = TopoDS.Face_s(explorer.Current())
        explorer.Next()
        loc = TopLoc_Location()
        poly = BRep_Tool.Triangulation_s(face, loc)
        if poly is None:
            raise MeshingError("OpenCascade could not triangulate a face of the shape")
        n = poly.NbNodes()
        node = poly.Node
        if loc.IsIdentity():            # most faces: the nodes as stored, no transform call
            pts = np.array([node(i).Coord() for i in range(1, n + 1)], float)
        else:                           # OpenCascade's own transform (bit-identical to before)
            trsf = loc.Transformation()
            pts = np.array([node(i).Transformed(trsf).Coord() for i in range(1, n + 1)], float)
        pts = pts.reshape(n, 3)
        triangle = poly.Triangle
        tri = np.array([triangle(j).Get() for j in range(1, poly.NbTriangles() + 1)],
                       dtype=np.int64).reshape(-1, 3) - 1
        if face.Orientation() == TopAbs_REVERSED:
            tri = tri[:, ::-1]
        verts.append(pts)
        faces.append(tri + offset)
        offset += n
    if not faces:
        raise MeshingError("shape has no faces to tessellate")
    return np.vstack(verts), np.vstack(faces)


def tessellate(shape: Any, tolerance: float = 0.01, angular_tolerance: float = 0.2, *,
               check: bool = True) -> trimesh.Trimesh:
    """Merged triangle mesh of a solid, mm.

    With ``check`` (default) a mesh that is not watertight, or encloses no positive volume,
    raises :class:`MeshingError`; ``check=False`` returns it as is (the printability report
    uses that to describe what is wrong).
    """
    v, f = triangulate(shape, tolerance, angular_tolerance)
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=True, validate=False)
    # drop zero-area slivers OpenCascade sometimes leaves on seams
    mesh.update_faces(mesh.nondegenerate_faces(height=1e-12))
    mesh.remove_unreferenced_vertices()
    if check:
        if not mesh.is_watertight:
            raise MeshingError("tessellated shape is not watertight (open or non-manifold "
                               "B-rep); check the part's booleans")
        if not mesh.volume > 0:
            raise MeshingError(f"tessellated shape encloses no positive volume "
                               f"({mesh.volume:.4g} mm^3)")
    return mesh
