"""Tetrahedral meshes (mm): the TetMesh container, meshing of a part's bodies, named facet sets, quality, VTU I/O."""
