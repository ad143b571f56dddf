"""Scene mesh export: PLY (per-vertex and per-face labels), OBJ (+MTL, image texture), GLB.

Coordinate frames
-----------------
* PLY and OBJ keep NPSim's OpenCV camera frame (x right, y down, z forward,
  metres): the files are data exchange for this pipeline and round-trip exactly.
* GLB follows glTF's convention (y up, camera looking down -z): positions are
  rotated 180 degrees about x, ``(x, y, z) -> (x, -y, -z)``. A rotation keeps
  the winding, so front faces still face the camera at the origin.

Per-face data
-------------
* PLY: one binary little-endian file for the whole scene; vertex properties
  ``x y z s t label light_id part``, face properties ``vertex_indices label
  light_id part``; header comments ``part <index> <name> <foreground 0/1>``.
* OBJ: one ``o <part name>`` per part (foreground objects are named parts),
  ``vt`` from the per-vertex uv, material ``scene`` textured with the image.
* GLB: one node and mesh per part, named after it; the mesh ``extras`` hold
  ``{"part", "foreground", "face_labels_rle": [[labelId, count], ...],
  "face_light_ids_rle": [...]}`` (run-length encoded in face order), the scene
  ``extras`` the image size and the frame convention.

Empty parts are skipped everywhere.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..errors import NpsimInputError
from ..io import atomic_path, write_image
from .types import MeshPart, SceneMesh

__all__ = ["export_ply", "export_obj", "export_glb", "export_mesh", "run_length", "FORMATS"]

FORMATS = ("ply", "obj", "glb")


def run_length(values: np.ndarray) -> list[list[int]]:
    """``[[value, count], ...]`` of consecutive runs."""
    v = np.asarray(values)
    if v.size == 0:
        return []
    starts = np.flatnonzero(np.concatenate([[True], v[1:] != v[:-1]]))
    counts = np.diff(np.concatenate([starts, [len(v)]]))
    return [[int(v[s]), int(c)] for s, c in zip(starts, counts)]


def _parts(mesh: SceneMesh) -> list[tuple[int, MeshPart]]:
    if not isinstance(mesh, SceneMesh):
        raise NpsimInputError(f"expected a SceneMesh, got {type(mesh).__name__}")
    return [(i, p) for i, p in enumerate(mesh.parts) if p.n_faces > 0]


def export_ply(mesh: SceneMesh, path: str | Path) -> Path:
    """Write the whole scene as one binary PLY (see module doc for the properties)."""
    path = Path(path)
    parts = _parts(mesh)
    nv = sum(p.n_vertices for _, p in parts)
    nf = sum(p.n_faces for _, p in parts)
    vdt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("s", "<f4"), ("t", "<f4"), ("label", "u1"),
                    ("light_id", "<i4"), ("part", "<i4")])
    fdt = np.dtype([("n", "u1"), ("v", "<i4", (3,)), ("label", "u1"), ("light_id", "<i4"), ("part", "<i4")])
    va = np.empty(nv, dtype=vdt)
    fa = np.empty(nf, dtype=fdt)
    vo = fo = 0
    header = ["ply", "format binary_little_endian 1.0",
              "comment NPSim scene mesh, OpenCV camera frame (x right, y down, z forward), metres",
              f"comment image {mesh.width} {mesh.height}"]
    for i, p in parts:
        header.append(f"comment part {i} {p.name} {int(p.foreground)}")
        n, m = p.n_vertices, p.n_faces
        sl = slice(vo, vo + n)
        va["x"][sl], va["y"][sl], va["z"][sl] = p.vertices[:, 0], p.vertices[:, 1], p.vertices[:, 2]
        va["s"][sl], va["t"][sl] = p.uv[:, 0], p.uv[:, 1]
        va["label"][sl], va["light_id"][sl], va["part"][sl] = p.label, p.light_id, i
        fl = slice(fo, fo + m)
        fa["n"][fl] = 3
        fa["v"][fl] = p.faces + vo
        fa["label"][fl], fa["light_id"][fl], fa["part"][fl] = p.face_label(), p.face_light_id(), i
        vo += n
        fo += m
    header += [f"element vertex {nv}", "property float x", "property float y", "property float z",
               "property float s", "property float t", "property uchar label", "property int light_id",
               "property int part", f"element face {nf}", "property list uchar int vertex_indices",
               "property uchar label", "property int light_id", "property int part", "end_header"]
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii"))
            fh.write(va.tobytes())
            fh.write(fa.tobytes())
    return path


#: Rows of vertices or faces formatted at a time by :func:`export_obj`.
OBJ_BLOCK = 1 << 18


def export_obj(mesh: SceneMesh, path: str | Path, image: np.ndarray | None = None) -> Path:
    """Write OBJ + MTL (+ PNG texture when ``image`` is given); one ``o`` group per part."""
    path = Path(path)
    parts = _parts(mesh)
    mtl = path.with_suffix(".mtl")
    tex = path.with_name(path.stem + "_texture.png")
    with atomic_path(path) as tmp:
        with open(tmp, "w", encoding="ascii") as fh:
            fh.write("# NPSim scene mesh, OpenCV camera frame (x right, y down, z forward), metres\n")
            fh.write(f"mtllib {mtl.name}\n")
            off = 1
            for _, p in parts:
                fh.write(f"o {p.name}\ng {p.name}\nusemtl scene\n")
                # in blocks of rows: the whole text of a 28 M-face mesh (2 GB, and its Python lists)
                # took 10.9 GB at once
                for k in range(0, p.n_vertices, OBJ_BLOCK):
                    v = p.vertices[k:k + OBJ_BLOCK].astype(np.float64).tolist()
                    fh.write("".join(f"v {x:.6g} {y:.6g} {z:.6g}\n" for x, y, z in v))
                for k in range(0, p.n_vertices, OBJ_BLOCK):
                    uv = p.uv[k:k + OBJ_BLOCK].astype(np.float64).tolist()
                    fh.write("".join(f"vt {s:.7g} {t:.7g}\n" for s, t in uv))
                for k in range(0, p.n_faces, OBJ_BLOCK):
                    f = (p.faces[k:k + OBJ_BLOCK].astype(np.int64) + off).tolist()
                    fh.write("".join(f"f {a}/{a} {b}/{b} {c}/{c}\n" for a, b, c in f))
                off += p.n_vertices
    lines = ["newmtl scene", "Ka 1 1 1", "Kd 1 1 1", "Ks 0 0 0", "d 1", "illum 1"]
    if image is not None:
        write_image(tex, np.asarray(image))
        lines.append(f"map_Kd {tex.name}")
    with atomic_path(mtl) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


def export_glb(mesh: SceneMesh, path: str | Path, image: np.ndarray | None = None) -> Path:
    """Write a binary glTF: one named node per part, face labels in the mesh extras (see module doc)."""
    import trimesh
    from PIL import Image

    path = Path(path)
    scene = trimesh.Scene()
    tex = Image.fromarray(np.ascontiguousarray(image)) if image is not None else None
    for _, p in _parts(mesh):
        v = p.vertices.astype(np.float64) * np.array([1.0, -1.0, -1.0])
        if tex is not None:
            visual = trimesh.visual.TextureVisuals(uv=p.uv.astype(np.float64),
                                                   material=trimesh.visual.material.SimpleMaterial(image=tex))
        else:
            visual = None
        tm = trimesh.Trimesh(vertices=v, faces=p.faces, visual=visual, process=False, validate=False)
        tm.metadata = {"part": p.name, "foreground": bool(p.foreground),
                       "face_labels_rle": run_length(p.face_label()),
                       "face_light_ids_rle": run_length(p.face_light_id())}
        scene.add_geometry(tm, node_name=p.name, geom_name=p.name)
    scene.metadata = {"npsim": {"width": mesh.width, "height": mesh.height,
                                "frame": "glTF: OpenCV camera frame rotated 180 deg about x (x, -y, -z)"}}
    data = scene.export(file_type="glb")
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)
    return path


def export_mesh(mesh: SceneMesh, folder: str | Path, stem: str = "mesh", formats=("ply",),
                image: np.ndarray | None = None) -> dict[str, Path]:
    """Export in each of ``formats`` (subset of ``FORMATS``) to ``folder/stem.<ext>``; returns the paths."""
    folder = Path(folder)
    out: dict[str, Path] = {}
    for f in formats:
        f = f.lower().strip()
        if f not in FORMATS:
            raise NpsimInputError(f"unknown mesh format {f!r}; choose from {', '.join(FORMATS)}")
        p = folder / f"{stem}.{f}"
        if f == "ply":
            out[f] = export_ply(mesh, p)
        elif f == "obj":
            out[f] = export_obj(mesh, p, image)
        else:
            out[f] = export_glb(mesh, p, image)
    return out
