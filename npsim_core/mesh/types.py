"""Mesh data types shared by the mesh kernel, the renderer, the exporters and the viewer.

All coordinates are in the OpenCV camera frame (x right, y down, z forward),
metres. Faces are wound so that the geometric normal
``(v1 - v0) x (v2 - v0)`` points toward the camera (n·P < 0), i.e. the front
face looks at the camera, matching the normal convention of docs/method.md §1.3.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np


@dataclass
class MeshPart:
    """One triangle sheet (the background, or one foreground object).

    Attributes
    ----------
    name : str
        ``"background"`` or e.g. ``"car_3"`` (class name + object index).
    vertices : (V, 3) float32
        Camera-frame positions in metres.
    faces : (F, 3) int32 or int64
        Vertex indices, front face toward the camera.
    uv : (V, 2) float32
        Texture coordinates ``((u + 0.5) / W, 1 - (v + 0.5) / H)`` of the source pixel.
    pixel : (V, 2) float32
        Source pixel (u, v) of each vertex (integers for grid vertices).
    label : (V,) uint8
        Cityscapes labelId of each vertex.
    light_id : (V,) int32
        Light instance id (classId*1000+index) under each vertex, 0 = none.
    foreground : bool
        True for foreground-object sheets.
    source : (V,) int32 (int64 for images of 2**31 pixels or more) or None
        Flat pixel index (``v * W + u``) each vertex belongs to: its own pixel, or for the extra
        vertices that close depth steps the grid corner they continue (their ``pixel`` lies
        between pixels). None: the rounded ``pixel``.
    """

    name: str
    vertices: np.ndarray
    faces: np.ndarray
    uv: np.ndarray
    pixel: np.ndarray
    label: np.ndarray
    light_id: np.ndarray
    foreground: bool = False
    source: np.ndarray | None = None

    @property
    def n_vertices(self) -> int:
        return int(len(self.vertices))

    @property
    def n_faces(self) -> int:
        return int(len(self.faces))

    def face_label(self) -> np.ndarray:
        """(F,) uint8 labelId per face: the label most of its three vertices share (first vertex on ties)."""
        if self.n_faces == 0:
            return np.zeros(0, dtype=np.uint8)
        l = self.label[self.faces]
        pick = np.where(l[:, 1] == l[:, 2], l[:, 1], l[:, 0])
        return pick.astype(np.uint8)

    def face_light_id(self) -> np.ndarray:
        """(F,) int32 light instance id per face: nonzero only when all three vertices share it."""
        if self.n_faces == 0:
            return np.zeros(0, dtype=np.int32)
        l = self.light_id[self.faces]
        same = (l[:, 0] == l[:, 1]) & (l[:, 1] == l[:, 2])
        return np.where(same, l[:, 0], 0).astype(np.int32)

    def edge_on_faces(self) -> np.ndarray:
        """(F,) bool: faces whose vertices' image positions (``pixel``) are collinear -- seen
        exactly edge-on from the camera, like the walls that close depth steps."""
        if self.n_faces == 0:
            return np.zeros(0, dtype=bool)
        q = self.pixel.astype(np.float64)[self.faces]
        area2 = (q[:, 1, 0] - q[:, 0, 0]) * (q[:, 2, 1] - q[:, 0, 1]) - (q[:, 1, 1] - q[:, 0, 1]) * (q[:, 2, 0] - q[:, 0, 0])
        return np.abs(area2) < 1e-6

    def face_normals(self) -> np.ndarray:
        """(F, 3) unit geometric normals (toward the camera for front faces)."""
        v = self.vertices.astype(np.float64)
        f = self.faces
        n = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 0]])
        norm = np.linalg.norm(n, axis=1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return (n / norm).astype(np.float32)


@dataclass
class SceneMesh:
    """The whole scene: a background sheet plus foreground sheets, and the camera it came from."""

    parts: list[MeshPart]
    width: int
    height: int
    #: Free-form record of how it was made (stage parameters, timings, counts).
    info: dict = field(default_factory=dict)

    @property
    def n_faces(self) -> int:
        return sum(p.n_faces for p in self.parts)

    @property
    def n_vertices(self) -> int:
        return sum(p.n_vertices for p in self.parts)

    def part(self, name: str) -> MeshPart:
        for p in self.parts:
            if p.name == name:
                return p
        raise KeyError(name)


def limit_far(mesh: SceneMesh, far_limit: float | None) -> SceneMesh:
    """``mesh`` with every vertex deeper than ``far_limit`` (metres, z) pulled along its camera ray
    onto the limit (its pixel does not move). A reduced mesh's merged cells may overshoot the
    limit by their tolerance where the depth reaches it; the far limit promises no deeper vertex."""
    if far_limit is None or not any(p.n_vertices and float(p.vertices[:, 2].max()) > far_limit for p in mesh.parts):
        return mesh
    parts = []
    for p in mesh.parts:
        z = p.vertices[:, 2]
        if p.n_vertices and float(z.max()) > far_limit:
            scale = np.minimum(1.0, far_limit / np.maximum(z, 1e-12)).astype(np.float32)
            p = replace(p, vertices=(p.vertices * scale[:, None]).astype(np.float32))
        parts.append(p)
    return replace(mesh, parts=parts)


def with_light_ids(mesh: SceneMesh, light_ids: np.ndarray | None) -> SceneMesh:
    """``mesh`` with each vertex's light id read from the light instance map ``light_ids``
    ((H, W) int, 0 = none; None: every id 0) at its pixel (``MeshPart.source``, else the
    rounded ``pixel``).

    A foreground vertex and a background vertex that no foreground vertex covers take their
    pixel's id; a background vertex behind an object (a foreground vertex on its pixel) takes 0
    -- the light is on the object in front. This is what the post-processing kernel assigns,
    so the geometry is built once and the lights follow the annotation. Exact for the
    full-resolution meshes of the chain, where every foreground pixel has a vertex; a reduced
    mesh's merged cells must respect light borders, so reduce the lit sheets instead
    (:meth:`~npsim_core.mesh.postprocess.SheetLayers.with_lights`).
    """
    from .grid import light_id_map

    H, W = mesh.height, mesh.width
    lid = light_id_map(light_ids, (H, W)).ravel()
    if light_ids is None:
        return replace(mesh, parts=[replace(p, light_id=np.zeros(p.n_vertices, np.int32)) for p in mesh.parts])

    def flat(p: MeshPart) -> np.ndarray:
        if p.source is not None:
            return p.source
        px = np.rint(p.pixel).astype(np.int64)
        return np.clip(px[:, 1], 0, H - 1) * W + np.clip(px[:, 0], 0, W - 1)

    covered = np.zeros(H * W, dtype=bool)
    for p in mesh.parts:
        if p.foreground and p.n_vertices:
            covered[flat(p)] = True
    parts = []
    for p in mesh.parts:
        f = flat(p)
        ids = lid[f] if p.foreground else np.where(covered[f], 0, lid[f])
        parts.append(replace(p, light_id=ids.astype(np.int32)))
    return replace(mesh, parts=parts)
