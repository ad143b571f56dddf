"""Scene meshes: Worldsheet grid, post-processing, reduction, quality, export (docs/method.md §4, §5).

Import the stage modules directly (``npsim_core.mesh.grid``, ``.postprocess``,
``.reduce``, ``.quality``, ``.export``); the most used names are re-exported here.
"""

from .grid import grid_mesh, quad_faces
from .postprocess import PostprocessParams, PostprocessResult, SheetLayers, postprocess_mesh
from .types import MeshPart, SceneMesh

__all__ = ["MeshPart", "SceneMesh", "grid_mesh", "quad_faces", "PostprocessParams", "PostprocessResult",
           "SheetLayers", "postprocess_mesh"]
