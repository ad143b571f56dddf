"""Scene meshes: Worldsheet grid, post-processing, reduction, export (SPEC §3-4)."""

from .types import MeshPart, SceneMesh

__all__ = ["MeshPart", "SceneMesh"]
