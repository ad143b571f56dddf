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
* Compressed GLB (``export_glb(..., compress=True)``, what a frame's export writes): each
  part's geometry is one ``KHR_draco_mesh_compression`` blob (Google's Draco through DracoPy,
  the encoder trimesh and Blender use) holding POSITION, TEXCOORD_0 and the per-vertex custom
  attributes ``_LABEL`` (uint8 labelId) and ``_LIGHT_ID`` (uint16/uint32); the texture is a
  JPEG (quality 90). Draco reorders vertices and faces (that is where most of its gain comes
  from: 10x against 1.3x in order), so face labels and light ids are not stored per face but
  follow from the vertices by :meth:`MeshPart.face_label` / :meth:`MeshPart.face_light_id`;
  unreferenced vertices are dropped. Positions are quantised onto a grid of
  ``2**bits`` steps over each part's extent, ``bits`` chosen so that no vertex moves more than
  ``max_error_m`` (default 5 mm; stated in the scene ``extras`` as ``position_error_m``), uv
  onto steps of 1/8 pixel. :func:`read_glb` loads either kind back into a :class:`SceneMesh`.

Empty parts are skipped everywhere.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from ..errors import NpsimInputError
from ..io import atomic_path, write_image
from .types import MeshPart, SceneMesh

__all__ = ["export_ply", "export_obj", "export_glb", "export_mesh", "read_glb", "run_length", "FORMATS",
           "GLB_MAX_ERROR_M", "GLB_DRACO_MAX_FACES"]

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
    """Write the whole scene as one binary PLY (see module doc for the properties), streamed:
    the header from the counts, then the vertices and the faces part by part in blocks of
    :data:`PLY_BLOCK` rows, so memory stays at one block (a 28 M-face mesh needed 1 GB of
    records at once)."""
    path = Path(path)
    parts = _parts(mesh)
    nv = sum(p.n_vertices for _, p in parts)
    nf = sum(p.n_faces for _, p in parts)
    vdt = np.dtype([("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("s", "<f4"), ("t", "<f4"), ("label", "u1"),
                    ("light_id", "<i4"), ("part", "<i4")])
    fdt = np.dtype([("n", "u1"), ("v", "<i4", (3,)), ("label", "u1"), ("light_id", "<i4"), ("part", "<i4")])
    header = ["ply", "format binary_little_endian 1.0",
              "comment NPSim scene mesh, OpenCV camera frame (x right, y down, z forward), metres",
              f"comment image {mesh.width} {mesh.height}"]
    header += [f"comment part {i} {p.name} {int(p.foreground)}" for i, p in parts]
    header += [f"element vertex {nv}", "property float x", "property float y", "property float z",
               "property float s", "property float t", "property uchar label", "property int light_id",
               "property int part", f"element face {nf}", "property list uchar int vertex_indices",
               "property uchar label", "property int light_id", "property int part", "end_header"]
    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(("\n".join(header) + "\n").encode("ascii"))
            for i, p in parts:
                for k in range(0, p.n_vertices, PLY_BLOCK):
                    sl = slice(k, k + PLY_BLOCK)
                    va = np.empty(len(p.vertices[sl]), dtype=vdt)
                    va["x"], va["y"], va["z"] = p.vertices[sl, 0], p.vertices[sl, 1], p.vertices[sl, 2]
                    va["s"], va["t"] = p.uv[sl, 0], p.uv[sl, 1]
                    va["label"], va["light_id"], va["part"] = p.label[sl], p.light_id[sl], i
                    fh.write(va.tobytes())
            vo = 0
            for i, p in parts:
                for k in range(0, p.n_faces, PLY_BLOCK):
                    sl = slice(k, k + PLY_BLOCK)
                    f = p.faces[sl]
                    fa = np.empty(len(f), dtype=fdt)
                    fa["n"] = 3
                    fa["v"] = f + vo
                    block = replace(p, faces=f)  # the same vertices: face labels of this block only
                    fa["label"], fa["light_id"] = block.face_label(), block.face_light_id()
                    fa["part"] = i
                    fh.write(fa.tobytes())
                vo += p.n_vertices
    return path


#: Rows of vertices or faces a streamed PLY writes at a time (:func:`export_ply`).
PLY_BLOCK = 1 << 20


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
                # One %-format of a whole block (C-level) writes the same text as a per-row
                # f-string in ~40 % of the time (4000x3000: ~90 s of export).
                for k in range(0, p.n_vertices, OBJ_BLOCK):
                    v = p.vertices[k:k + OBJ_BLOCK].astype(np.float64)
                    fh.write(("v %.6g %.6g %.6g\n" * len(v)) % tuple(v.ravel().tolist()))
                for k in range(0, p.n_vertices, OBJ_BLOCK):
                    uv = p.uv[k:k + OBJ_BLOCK].astype(np.float64)
                    fh.write(("vt %.7g %.7g\n" * len(uv)) % tuple(uv.ravel().tolist()))
                for k in range(0, p.n_faces, OBJ_BLOCK):
                    f = np.repeat(p.faces[k:k + OBJ_BLOCK].astype(np.int64) + off, 2, axis=1)
                    fh.write(("f %d/%d %d/%d %d/%d\n" * len(f)) % tuple(f.ravel().tolist()))
                off += p.n_vertices
    lines = ["newmtl scene", "Ka 1 1 1", "Kd 1 1 1", "Ks 0 0 0", "d 1", "illum 1"]
    if image is not None:
        write_image(tex, np.asarray(image))
        lines.append(f"map_Kd {tex.name}")
    with atomic_path(mtl) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="ascii")
    return path


#: Largest distance (metres) a vertex of a compressed GLB may move by quantisation.
GLB_MAX_ERROR_M = 0.005
#: Meshes with more faces get a plain GLB from :func:`export_mesh` even when compression is asked
#: for: Draco's encoder is superlinear (0.26 / 1.0 / 4.2 M faces of a grid: 1.9 / 13 / 102 s at
#: load 8), while a frame's reduced mesh (0.8 M faces at 2048x1024) takes 1.3 s.
GLB_DRACO_MAX_FACES = 2_000_000


def export_glb(mesh: SceneMesh, path: str | Path, image: np.ndarray | None = None, *, compress: bool = False,
               max_error_m: float = GLB_MAX_ERROR_M) -> Path:
    """Write a binary glTF: one named node per part, face labels in the mesh extras (see module doc).

    ``compress``: Draco-compressed geometry with per-vertex labels and light ids and a JPEG
    texture, every vertex within ``max_error_m`` metres of its position (module doc).
    """
    if compress:
        return _export_glb_draco(mesh, Path(path), image, max_error_m)
    return _export_glb_plain(mesh, Path(path), image)


def _export_glb_plain(mesh: SceneMesh, path: Path, image: np.ndarray | None) -> Path:
    """The uncompressed GLB, streamed: the layout (offsets of every array) is known from the
    counts, so the JSON is written first and then each part's float32 positions, uv and uint32
    indices straight from its arrays -- no float64 copies (trimesh's scene export of a 28 M-face
    mesh peaked at ~1.7 GB above the mesh)."""
    import json
    import struct

    import cv2

    parts = _parts(mesh)
    views: list[dict] = []
    accessors: list[dict] = []
    meshes, nodes = [], []
    offset = 0

    def add(nbytes: int, target: int | None = None) -> int:
        nonlocal offset
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": nbytes,
                      **({} if target is None else {"target": target})})
        offset += nbytes + (-nbytes % 4)
        return len(views) - 1

    flip = np.array([1.0, -1.0, -1.0], np.float32)
    for _, p in parts:
        nv, nf = p.n_vertices, p.n_faces
        lo, hi = p.vertices.min(0) * flip, p.vertices.max(0) * flip  # y, z flipped: min and max swap
        vmin, vmax = np.minimum(lo, hi), np.maximum(lo, hi)
        accessors.append({"bufferView": add(12 * nv, 34962), "componentType": 5126, "count": nv, "type": "VEC3",
                          "min": [float(x) for x in vmin], "max": [float(x) for x in vmax]})
        attr = {"POSITION": len(accessors) - 1}
        if image is not None:
            accessors.append({"bufferView": add(8 * nv, 34962), "componentType": 5126, "count": nv, "type": "VEC2"})
            attr["TEXCOORD_0"] = len(accessors) - 1
        accessors.append({"bufferView": add(12 * nf, 34963), "componentType": 5125, "count": 3 * nf, "type": "SCALAR"})
        prim = {"attributes": attr, "indices": len(accessors) - 1, "mode": 4}
        if image is not None:
            prim["material"] = 0
        meshes.append({"name": p.name, "primitives": [prim],
                       "extras": {"part": p.name, "foreground": bool(p.foreground),
                                  "face_labels_rle": run_length(p.face_label()),
                                  "face_light_ids_rle": run_length(p.face_light_id())}})
        nodes.append({"name": p.name, "mesh": len(meshes) - 1})
    doc = {"asset": {"version": "2.0", "generator": "NPSim"}, "scene": 0,
           "scenes": [{"nodes": list(range(len(nodes))),
                       "extras": {"npsim": {"width": mesh.width, "height": mesh.height,
                                            "frame": "glTF: OpenCV camera frame rotated 180 deg about x (x, -y, -z)"}}}],
           "nodes": nodes, "meshes": meshes, "accessors": accessors}
    png = b""
    if image is not None:
        ok, enc = cv2.imencode(".png", cv2.cvtColor(np.ascontiguousarray(np.asarray(image)[..., :3]), cv2.COLOR_RGB2BGR))
        if not ok:
            raise RuntimeError("OpenCV could not encode the mesh texture as PNG")
        png = enc.tobytes()
        doc.update(images=[{"bufferView": add(len(png)), "mimeType": "image/png"}],
                   samplers=[{"magFilter": 9729, "minFilter": 9729}], textures=[{"sampler": 0, "source": 0}],
                   materials=[{"name": "scene", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                         "metallicFactor": 0.0, "roughnessFactor": 1.0}}])
    doc["buffers"] = [{"byteLength": offset}]
    doc["bufferViews"] = views
    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * (-len(js) % 4)

    def pad(fh, n: int) -> None:
        fh.write(b"\0" * (-n % 4))

    with atomic_path(path) as tmp:
        with open(tmp, "wb") as fh:
            fh.write(struct.pack("<4sII", b"glTF", 2, 12 + 8 + len(js) + 8 + offset))
            fh.write(struct.pack("<I4s", len(js), b"JSON") + js)
            fh.write(struct.pack("<I4s", offset, b"BIN\0"))
            for _, p in parts:  # in the order of the views above; blocks of rows keep the copies small
                for k in range(0, p.n_vertices, PLY_BLOCK):
                    fh.write(np.ascontiguousarray(p.vertices[k:k + PLY_BLOCK] * flip, dtype="<f4").tobytes())
                pad(fh, 12 * p.n_vertices)
                if image is not None:
                    for k in range(0, p.n_vertices, PLY_BLOCK):
                        fh.write(np.ascontiguousarray(p.uv[k:k + PLY_BLOCK], dtype="<f4").tobytes())
                    pad(fh, 8 * p.n_vertices)
                for k in range(0, p.n_faces, PLY_BLOCK):
                    fh.write(np.ascontiguousarray(p.faces[k:k + PLY_BLOCK], dtype="<u4").tobytes())
                pad(fh, 12 * p.n_faces)
            if png:
                fh.write(png)
                pad(fh, len(png))
    return path


def _glb_bytes(doc: dict, binary: bytes) -> bytes:
    """A GLB container: header, JSON chunk (space padded), BIN chunk (zero padded)."""
    import json
    import struct

    js = json.dumps(doc, separators=(",", ":")).encode("utf-8")
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(js) + 8 + len(binary)
    return b"".join([struct.pack("<4sII", b"glTF", 2, total), struct.pack("<I4s", len(js), b"JSON"), js,
                     struct.pack("<I4s", len(binary), b"BIN\0"), binary])


def _quant_bits(extent: float, max_error: float) -> int:
    """Bits of a uniform grid over ``extent`` whose half step is at most ``max_error``."""
    if extent <= 0:
        return 8
    return int(np.clip(np.ceil(np.log2(extent / (2.0 * max_error) + 1.0)), 8, 30))


def _export_glb_draco(mesh: SceneMesh, path: Path, image: np.ndarray | None, max_error_m: float) -> Path:
    import DracoPy
    import cv2

    if not max_error_m > 0:
        raise NpsimInputError(f"GLB max_error_m must be > 0 m, got {max_error_m}")
    blobs: list[bytes] = []
    views: list[dict] = []

    def add_view(data: bytes) -> int:
        off = sum(len(b) for b in blobs)
        blobs.append(data + b"\0" * (-len(data) % 4))
        views.append({"buffer": 0, "byteOffset": off, "byteLength": len(data)})
        return len(views) - 1

    accessors: list[dict] = []
    meshes, nodes = [], []
    uv_bits = int(np.clip(np.ceil(np.log2(8.0 * max(mesh.width, mesh.height, 1))), 10, 30))
    flip = np.array([1.0, -1.0, -1.0], np.float32)
    worst = 0.0
    for _, p in _parts(mesh):
        v = np.ascontiguousarray(p.vertices.astype(np.float32) * flip)
        extent = float(np.ptp(v, axis=0).max()) if len(v) else 0.0
        bits = _quant_bits(extent, max_error_m / np.sqrt(3.0))  # half a step per axis: sqrt(3) of it in 3D
        worst = max(worst, np.sqrt(3.0) * extent / (2 ** bits - 1) / 2.0)
        lid = np.asarray(p.light_id)
        lid_t = (np.uint16, 5123) if (lid.size == 0 or (lid.min() >= 0 and lid.max() < 65536)) else (np.uint32, 5125)
        if lid.size and lid.min() < 0:
            raise NpsimInputError(f"mesh part {p.name}: negative light ids cannot be written to a GLB")
        buf = DracoPy.encode(v, np.ascontiguousarray(p.faces, dtype=np.uint32), quantization_bits=bits,
                             compression_level=6, preserve_order=False,
                             tex_coord=p.uv.astype(np.float64), tex_coord_quantization_bits=uv_bits,
                             generic_attributes={"label": p.label.astype(np.uint8).reshape(-1, 1),
                                                 "light_id": lid.astype(lid_t[0]).reshape(-1, 1)})
        # decode once: the counts and bounds the accessors must state, and the ids draco assigned
        dec = DracoPy.decode(buf)
        ids = {}
        for a in dec.attributes:
            key = {0: "POSITION", 3: "TEXCOORD_0"}.get(a["attribute_type"]) or {"label": "_LABEL",
                                                                                 "light_id": "_LIGHT_ID"}.get(a["name"])
            if key:
                ids[key] = int(a["unique_id"])
        if len(ids) != 4:
            raise RuntimeError(f"draco dropped an attribute of mesh part {p.name}: kept {sorted(ids)}")
        pts, nv = np.asarray(dec.points, np.float32), len(dec.points)
        attr = {}
        for key, ctype, typ, extra in (("POSITION", 5126, "VEC3", {"min": pts.min(0).tolist(), "max": pts.max(0).tolist()}),
                                       ("TEXCOORD_0", 5126, "VEC2", {}), ("_LABEL", 5121, "SCALAR", {}),
                                       ("_LIGHT_ID", lid_t[1], "SCALAR", {})):
            accessors.append({"componentType": ctype, "count": nv, "type": typ, **extra})
            attr[key] = len(accessors) - 1
        accessors.append({"componentType": 5125, "count": int(np.asarray(dec.faces).size), "type": "SCALAR"})
        prim = {"attributes": attr, "indices": len(accessors) - 1, "mode": 4,
                "extensions": {"KHR_draco_mesh_compression": {"bufferView": add_view(buf), "attributes": ids}}}
        if image is not None:
            prim["material"] = 0
        meshes.append({"name": p.name, "primitives": [prim], "extras": {"part": p.name, "foreground": bool(p.foreground)}})
        nodes.append({"name": p.name, "mesh": len(meshes) - 1})
    doc = {"asset": {"version": "2.0", "generator": "NPSim"}, "scene": 0,
           "scenes": [{"nodes": list(range(len(nodes))),
                       "extras": {"npsim": {"width": mesh.width, "height": mesh.height,
                                            "frame": "glTF: OpenCV camera frame rotated 180 deg about x (x, -y, -z)",
                                            "position_error_m": worst,
                                            "face_attributes": "from the vertices' _LABEL/_LIGHT_ID: label most "
                                                               "vertices share (first on ties), light id when all three do"}}}],
           "nodes": nodes, "meshes": meshes, "accessors": accessors,
           "extensionsUsed": ["KHR_draco_mesh_compression"], "extensionsRequired": ["KHR_draco_mesh_compression"]}
    if image is not None:
        rgb = np.ascontiguousarray(np.asarray(image)[..., :3])
        ok, jpg = cv2.imencode(".jpg", cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR), [cv2.IMWRITE_JPEG_QUALITY, 90])
        if not ok:
            raise RuntimeError("OpenCV could not encode the mesh texture as JPEG")
        doc.update(images=[{"bufferView": add_view(jpg.tobytes()), "mimeType": "image/jpeg"}],
                   samplers=[{"magFilter": 9729, "minFilter": 9729}], textures=[{"sampler": 0, "source": 0}],
                   materials=[{"name": "scene", "pbrMetallicRoughness": {"baseColorTexture": {"index": 0},
                                                                         "metallicFactor": 0.0, "roughnessFactor": 1.0}}])
    binary = b"".join(blobs)
    doc["buffers"] = [{"byteLength": len(binary)}]
    doc["bufferViews"] = views
    with atomic_path(path) as tmp:
        tmp.write_bytes(_glb_bytes(doc, binary))
    return path


def read_glb(path: str | Path) -> SceneMesh:
    """Load a GLB written by :func:`export_glb` (compressed or not) back into a :class:`SceneMesh`
    in the OpenCV camera frame. ``pixel`` comes from the uv; a plain GLB has no per-vertex
    labels (they are per face in its extras), so its vertices take the label of a face they
    belong to.
    """
    import json
    import struct

    from .types import MeshPart

    path = Path(path)
    data = path.read_bytes()
    try:
        magic, _, _ = struct.unpack_from("<4sII", data, 0)
        jlen, jtype = struct.unpack_from("<I4s", data, 12)
        if magic != b"glTF" or jtype != b"JSON":
            raise ValueError("not a GLB")
        doc = json.loads(data[20:20 + jlen])
        blen, _ = struct.unpack_from("<I4s", data, 20 + jlen)
        binary = data[28 + jlen:28 + jlen + blen]
    except (struct.error, ValueError) as exc:
        raise NpsimInputError(f"{path}: not a readable GLB ({exc})") from None
    info = doc["scenes"][doc.get("scene", 0)].get("extras", {}).get("npsim", {})
    W, H = int(info.get("width", 0)), int(info.get("height", 0))
    ctypes = {5121: np.uint8, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
    ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}

    def view(i: int) -> bytes:
        v = doc["bufferViews"][i]
        return binary[v.get("byteOffset", 0):v.get("byteOffset", 0) + v["byteLength"]]

    def accessor(i: int) -> np.ndarray:
        a = doc["accessors"][i]
        arr = np.frombuffer(view(a["bufferView"]), dtype=ctypes[a["componentType"]], offset=a.get("byteOffset", 0),
                            count=a["count"] * ncomp[a["type"]])
        return arr.reshape(a["count"], -1) if ncomp[a["type"]] > 1 else arr

    parts = []
    for node in doc["nodes"]:
        m = doc["meshes"][node["mesh"]]
        prim = m["primitives"][0]
        ext = prim.get("extensions", {}).get("KHR_draco_mesh_compression")
        if ext is not None:
            import DracoPy

            dec = DracoPy.decode(view(ext["bufferView"]))
            by_id = {a["unique_id"]: np.asarray(a["data"]) for a in dec.attributes}
            got = {k: by_id[i] for k, i in ext["attributes"].items()}
            v, faces = got["POSITION"].reshape(-1, 3), np.asarray(dec.faces).reshape(-1, 3)
            uv = got["TEXCOORD_0"].reshape(-1, 2)
            label = got["_LABEL"].reshape(-1).astype(np.uint8)
            light = got["_LIGHT_ID"].reshape(-1).astype(np.int32)
        else:
            at = prim["attributes"]
            v, uv = accessor(at["POSITION"]), accessor(at["TEXCOORD_0"]) if "TEXCOORD_0" in at else None
            faces = accessor(prim["indices"]).reshape(-1, 3)
            extras = m.get("extras", {})
            flab = np.repeat(*np.array(extras.get("face_labels_rle", [[0, len(faces)]])).T).astype(np.uint8)
            flight = np.repeat(*np.array(extras.get("face_light_ids_rle", [[0, len(faces)]])).T).astype(np.int32)
            label = np.zeros(len(v), np.uint8)
            light = np.zeros(len(v), np.int32)
            label[faces.ravel()] = np.repeat(flab, 3)
            light[faces.ravel()] = np.repeat(flight, 3)
            if uv is None:
                uv = np.zeros((len(v), 2), np.float32)
        v = np.asarray(v, np.float32) * np.array([1.0, -1.0, -1.0], np.float32)
        uv = np.asarray(uv, np.float32)
        pixel = np.stack([uv[:, 0] * W - 0.5, (1.0 - uv[:, 1]) * H - 0.5], axis=1).astype(np.float32)
        extras = m.get("extras", {})
        parts.append(MeshPart(extras.get("part", m.get("name", node.get("name", ""))), v,
                              faces.astype(np.int64), uv, pixel, label, light, bool(extras.get("foreground", False))))
    return SceneMesh(parts=parts, width=W, height=H)


def export_mesh(mesh: SceneMesh, folder: str | Path, stem: str = "mesh", formats=("ply",),
                image: np.ndarray | None = None, *, glb_compress: bool = False) -> dict[str, Path]:
    """Export in each of ``formats`` (subset of ``FORMATS``) to ``folder/stem.<ext>``; returns the paths.
    ``glb_compress``: the GLB Draco-compressed (:func:`export_glb`) when the mesh has at most
    :data:`GLB_DRACO_MAX_FACES` faces."""
    glb_compress = glb_compress and mesh.n_faces <= GLB_DRACO_MAX_FACES
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
            out[f] = export_glb(mesh, p, image, compress=glb_compress)
    return out
