"""One writer for every output of a frame: masks, depth, normals, meshes, nights, manifest.

File names (``<name>`` = the frame's name)::

    <name>_labelIds.png, <name>_uncertain.png, light annotation files   masks
    <name>_depth_refined.png + _vis.png                                  depth (16-bit PNG, metres*256, 0 invalid)
    <name>_depth_{input,refined}.npy, _depth_input.png + _vis.png        extras only (--full-outputs)
    <name>_normals_refined.{npy,png} + _vis.png                          normals (camera frame)
    <name>_mesh.{ply,glb,obj}                                            mesh (GLB Draco-compressed)
    <name>_night_<k>.png, _linear.npy, _labelIds.png, _lights.json       night k (seed = night.seed + k)
    <name>_export.json                                                   manifest

A frame's outputs are committed as a whole: everything is written into a staging folder
inside the output folder (``.<name>.partial-*``), and only when all of it is there are the
files moved into place -- the previous manifest removed first, files of the previous
result that the new one does not write removed after, the new manifest last. A failed or
cancelled export leaves the previous result untouched. The manifest -- inputs,
parameters, the depth source, each stage's real compute time, each night's seed, spp,
variant, light counts and step times, the files with their checksums, library versions --
makes a folder complete: :func:`verify_frame` checks it (``npsim batch --skip-existing``).
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
import threading
import time
from pathlib import Path
from typing import Callable

import numpy as np

from ..camera import normals_from_depth
from ..errors import NpsimCancelled, NpsimInputError
from ..memory import release_free_memory
from .chain import Chain, ChainResults
from .params import ChainParams

__all__ = ["EXPORT_KINDS", "export_frame", "frame_errors", "versions", "check_output_folder", "verify_frame",
           "file_checksum", "check_mesh_formats"]

EXPORT_KINDS = ("masks", "depth", "normals", "mesh", "nights")


def versions() -> dict[str, str]:
    """Versions of NPSim and the libraries whose numbers end up in the outputs."""
    from importlib import metadata

    out = {}
    for dist in ("npsim", "numpy", "opencv-contrib-python-headless", "torch", "mitsuba", "trimesh"):
        try:
            out[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            out[dist] = "not installed"
    return out


def frame_errors(chain: Chain, res: ChainResults, stereo_max_m: float | None = None,
                 stereo_holdout: float | None = None) -> dict:
    """Scores of the input and refined depth against the frame's reference (ground truth, else
    stereo; :mod:`npsim_core.scoring`): ``{"reference", "input", "refined"}``; empty without one.
    When the input is the stereo, only its held-out pixels are scored (``depth.stereo_holdout``)."""
    from ..scoring import held_out, reference_of, score_depth

    if stereo_max_m is None:
        stereo_max_m = ChainParams().depth.stereo_max_m
    if stereo_holdout is None:
        stereo_holdout = ChainParams().depth.stereo_holdout
    ref = reference_of(chain.scene, stereo_max_m, held_out(res.depth_source, chain.scene.provenance, stereo_holdout))
    if ref is None or res.depth_in is None:
        return {}
    labels = chain.scene.labels
    return {"reference": ref.kind, "input": score_depth(res.depth_in, res.intrinsics, labels, ref),
            "refined": score_depth(res.depth, res.intrinsics, labels, ref)}


def check_mesh_formats(formats) -> None:
    """Raise :class:`NpsimInputError` unless ``formats`` is a non-empty subset of ply, obj, glb."""
    from ..mesh.export import FORMATS

    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise NpsimInputError(f"mesh formats: unknown {bad or 'empty'}; choose from {', '.join(FORMATS)}")


def check_output_folder(folder: str | Path) -> Path:
    """Create ``folder`` if needed and make sure files can be written there -- before any
    computation, so a bad ``-o`` costs nothing. Raises :class:`NpsimInputError` naming the path."""
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise NpsimInputError(f"{folder}: exists and is not a folder; choose another output folder")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, probe = tempfile.mkstemp(prefix=".npsim-write-test-", dir=folder)
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise NpsimInputError(f"{folder}: cannot write there ({exc.strerror or exc}); choose another output "
                              "folder or fix its permissions") from None
    return folder


def file_checksum(path: str | Path) -> str:
    """BLAKE2b-128 of a file's bytes (hex), read in 1 MiB blocks."""
    h = hashlib.blake2b(digest_size=16)
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def verify_frame(folder: str | Path, name: str | None = None) -> str | None:
    """None when ``folder`` holds a complete export (of frame ``name``, or of its one manifest):
    the manifest and every file it lists, with matching checksums; else the reason."""
    folder = Path(folder)
    manifests = [folder / f"{name}_export.json"] if name else sorted(folder.glob("*_export.json"))
    if not manifests or not manifests[0].is_file():
        return "no manifest"
    try:
        doc = json.loads(manifests[0].read_text())
        sums = doc["checksums"]
    except (OSError, ValueError, KeyError, TypeError):
        return f"{manifests[0].name} is unreadable or has no checksums"
    for fname in doc.get("files", []):
        p = folder / fname
        if not p.is_file():
            return f"{fname} is missing"
        if sums.get(fname) != file_checksum(p):
            return f"{fname} differs from the manifest's checksum"
    return None


def _commit(staging: Path, folder: Path, names: list[str], manifest_name: str, manifest: dict) -> None:
    """Move the staged files into ``folder``: old manifest out first, new manifest in last."""
    from ..io import write_json

    old_manifest = folder / manifest_name
    old_files: list[str] = []
    if old_manifest.is_file():
        try:
            old_files = list(json.loads(old_manifest.read_text()).get("files", []))
        except (OSError, ValueError, AttributeError):
            old_files = []
        old_manifest.unlink()
    for fname in names:
        os.replace(staging / fname, folder / fname)
    for fname in set(old_files) - set(names) - {manifest_name}:
        if "/" not in fname and "\\" not in fname:
            (folder / fname).unlink(missing_ok=True)
    write_json(old_manifest, manifest)


def export_frame(chain: Chain, params: ChainParams, folder: str | Path, *, nights: int = 1,
                 kinds: tuple[str, ...] = EXPORT_KINDS, mesh_formats: tuple[str, ...] | None = None,
                 cancel: threading.Event | None = None, progress: Callable[[float, str], None] | None = None,
                 inputs: dict | None = None) -> list[Path]:
    """Write ``kinds`` of ``chain``'s frame (and ``nights`` nights) to ``folder``.

    Returns the written paths, the manifest ``<name>_export.json`` last. ``progress(fraction,
    text)`` reports as it goes; ``inputs`` (e.g. the command line's paths) goes into the manifest.
    What is written follows ``params.export`` (``mesh_formats`` overrides its formats). All or
    nothing: see the module doc.
    """
    if mesh_formats is None:
        mesh_formats = params.export.mesh_formats
    bad = [k for k in kinds if k not in EXPORT_KINDS]
    if bad:
        raise NpsimInputError(f"unknown export kinds {bad}; choose from {EXPORT_KINDS}")
    if nights < 0:
        raise NpsimInputError(f"nights must be >= 0, got {nights}")
    if "mesh" in kinds:
        check_mesh_formats(mesh_formats)
    folder = check_output_folder(folder)
    n = chain.scene.name
    n_nights = nights if "nights" in kinds else 0
    steps, done = 2 + n_nights, [0]

    def step(text: str) -> None:
        if cancel is not None and cancel.is_set():
            raise NpsimCancelled("export cancelled")
        if progress is not None:
            progress(done[0] / steps, text)
        done[0] += 1

    step("computing depth refinement and mesh")
    res = chain.compute(params, until="mesh", cancel=cancel)
    if res.mesh.n_faces == 0 and ("mesh" in kinds or n_nights):
        raise NpsimInputError(f"{n}: the mesh has no faces (all sky, or no valid depth within "
                              f"{params.mesh.far_limit:g} m), so there is no mesh or night to write")
    from ..io import staging_prefix

    staging = Path(tempfile.mkdtemp(prefix=staging_prefix(n), dir=folder))
    try:
        return _export_staged(chain, params, res, folder, staging, nights=n_nights, kinds=kinds,
                              mesh_formats=mesh_formats, cancel=cancel, step=step, progress=progress, inputs=inputs)
    finally:
        shutil.rmtree(staging, ignore_errors=True)


def _export_staged(chain: Chain, params: ChainParams, res: ChainResults, folder: Path, staging: Path, *,
                   nights: int, kinds, mesh_formats, cancel, step, progress, inputs) -> list[Path]:
    from ..annotation import save_annotation
    from ..io import depth_to_rgb, normals_to_rgb, write_depth_png, write_image, write_json, write_npy
    from ..io import write_normals_png

    s, n = chain.scene, chain.scene.name
    n_nights = nights
    written: list[Path] = []
    step("writing masks, depth, normals, mesh")

    def put(path: Path, write, data) -> None:
        write(path, data)
        written.append(path)

    if "masks" in kinds:
        put(staging / f"{n}_labelIds.png", write_image, s.labels)
        if res.uncertain is not None:
            put(staging / f"{n}_uncertain.png", write_image, res.uncertain.astype(np.uint8) * 255)
        if chain.annotation is not None:
            written += list(save_annotation(chain.annotation, staging, n).values())
    ex = params.export
    depth_info: dict = {}
    if "depth" in kinds:
        # By default only the refined depth, as a Cityscapes-style 16-bit PNG (metres*256, 0 =
        # invalid; 1.3 MB against 8.4 MB of float32 at 2048x1024, steps of 3.9 mm): the input
        # depth is the dataset's own stereo or the prior, so it and the float32 maps only with
        # extras (--full-outputs).
        d = res.depth
        put(staging / f"{n}_depth_refined.png", write_depth_png, d)
        far = np.isfinite(d) & (d > 65535 / 256.0)
        depth_info = {"refined_png": "metres*256, 0 invalid", "step_m": 1 / 256.0,
                      "clipped_beyond_255.99_m": int(np.count_nonzero(far))}
        put(staging / f"{n}_depth_refined_vis.png", write_image, depth_to_rgb(d))
        if ex.extras:
            put(staging / f"{n}_depth_refined.npy", write_npy, d.astype(np.float32))
            if res.depth_in is not None:
                put(staging / f"{n}_depth_input.npy", write_npy, res.depth_in.astype(np.float32))
                put(staging / f"{n}_depth_input.png", write_depth_png, res.depth_in)
                put(staging / f"{n}_depth_input_vis.png", write_image, depth_to_rgb(res.depth_in))
    if "normals" in kinds:
        nr = normals_from_depth(res.depth, res.intrinsics)
        if ex.extras:
            put(staging / f"{n}_normals_refined.npy", write_npy, nr)
            put(staging / f"{n}_normals_refined.png", write_normals_png, nr)
        put(staging / f"{n}_normals_refined_vis.png", write_image, normals_to_rgb(nr))
        del nr  # 25 MB at 2048x1024, not kept through the nights
    mesh_info = {"faces": int(res.mesh.n_faces), "vertices": int(res.mesh.n_vertices),
                 "reduced_by_budget": res.mesh_result.reduced}
    if "mesh" in kinds and ex.mesh != "none":
        # in a function of its own: the written meshes are gone before the nights' peak
        written += _write_meshes(chain, params, res, staging, mesh_formats, mesh_info)
    # Scored before the nights: afterwards the Mitsuba scene is cached and scoring's normal maps
    # and reference came on top of it (the frame's peak).
    errors = frame_errors(chain, res, params.depth.stereo_max_m, params.depth.stereo_holdout)
    release_free_memory()
    nights_info = []
    night_timings: dict = {}
    for k in range(n_nights):
        step(f"rendering night {k + 1}/{n_nights}")
        seed = params.night.seed + k
        # What the manifest reads from the scene, taken before the frame's last night drops it
        # (``release_scene``: the denoiser's peak then comes without the scene; same files).
        t_in = time.perf_counter()
        built, _, _, run = chain.night_inputs(params, cancel=cancel)
        t_in = time.perf_counter() - t_in  # the scene and guides (the first night), counted as the night's
        night_timings.update(run.timings)
        render_mesh, area_ids = built.info.get("render_mesh", ""), set(built.area_keys)
        materials = built.info.get("materials", "")  # which albedo: the scene's, de-lit or the fallback
        del built, run
        frame = chain.night_final(res, params, seed=seed, cancel=cancel, release_scene=k == n_nights - 1)
        frame.timings["night_inputs"] = frame.timings.get("night_inputs", 0.0) + t_in
        release_free_memory()  # the render's and the denoiser's temporaries
        stem = f"{n}_night_{k}"
        put(staging / f"{stem}.png", write_image, frame.image)
        if ex.extras:
            put(staging / f"{stem}_linear.npy", write_npy, frame.linear)
        put(staging / f"{stem}_labelIds.png", write_image, s.labels)
        put(staging / f"{stem}_lights.json", write_json, frame.active.to_json())
        on = len(frame.active.on_ids)
        nights_info.append({"night": k, "seed": seed, "spp": frame.spp, "variant": frame.variant,
                            "denoiser": frame.denoiser,
                            "denoiser_quality": (params.denoise.oidn_quality if frame.denoiser == "oidn" else ""),
                            "max_depth": int(params.night.final_max_depth), "render_faces": frame.faces,
                            "render_mesh": render_mesh, "materials": materials,
                            "lights_on": on, "lights": len(frame.active.lights),
                            "lights_without_faces": sorted(int(i) for i in set(frame.active.lights) - area_ids),
                            "exposure": {k2: (None if isinstance(v, float) and not np.isfinite(v) else
                                              round(v, 6) if isinstance(v, float) else v)
                                         for k2, v in frame.exposure.items()},
                            "seconds": round(frame.elapsed + t_in, 3),
                            "timings": {k2: round(v, 3) for k2, v in frame.timings.items()},
                            "realism": frame.realism})  # structure ratio + global stats (npsim_core.realism)
    # The night stages' times when they ran (their results are cached in the chain).
    timings = dict(res.timings)
    timings.update(night_timings)
    names = [p.name for p in written]
    manifest = {
        "format": "npsim-export", "scene": n, "size": [s.width, s.height], "inputs": inputs or {},
        "provenance": {k: str(v) for k, v in s.provenance.items() if k != "files"},
        "depth_source": res.depth_source, "warnings": list(s.provenance.get("warnings", [])),
        # share of guessed pixels (the pop-up prior's confidence; None for files, stereo, networks)
        "depth_confidence": chain.engine.run(("geometry",), params).results["geometry"].scene.provenance.get(
            "confidence"),
        "params": params.to_json(),
        "timings": {k: round(v, 4) for k, v in timings.items()},
        "mesh": mesh_info, "depth": depth_info,
        "refine": None if res.refine is None else {"steps": int(res.refine.steps), "diverged": bool(res.refine.diverged),
                                                   "message": res.refine.message},
        "lights": _lights_info(chain.lights(params)),
        "errors": errors, "nights": nights_info, "kinds": list(kinds),
        "files": names, "checksums": {nm: file_checksum(staging / nm) for nm in names}, "versions": versions()}
    if cancel is not None and cancel.is_set():
        raise NpsimCancelled("export cancelled")
    _commit(staging, folder, names, f"{n}_export.json", manifest)
    out = [folder / nm for nm in names] + [folder / f"{n}_export.json"]
    if progress is not None:
        progress(1.0, f"exported {len(out)} files")
    return out


def _write_meshes(chain: Chain, params: ChainParams, res: ChainResults, staging: Path, mesh_formats,
                  mesh_info: dict) -> list[Path]:
    """Write the frame's mesh(es) (``params.export.mesh``) into ``staging``; fills ``mesh_info``."""
    from ..mesh.export import GLB_DRACO_MAX_FACES, GLB_MAX_ERROR_M, export_mesh
    from .stages import lit_mesh

    n, ex, written = chain.scene.name, params.export, []
    meshes = []
    ann = chain.lights(params).annotation
    if ex.mesh in ("reduced", "both"):
        small, how = lit_mesh(res.mesh_result, ann, ex.mesh_tolerance, params.mesh.far_limit)
        meshes.append((f"{n}_mesh", small))
        mesh_info["written"] = {"faces": int(small.n_faces), "what": how}
    if ex.mesh in ("full", "both"):
        meshes.append((f"{n}_mesh" if ex.mesh == "full" else f"{n}_mesh_full", lit_mesh(res.mesh_result, ann)[0]))
        if ex.mesh == "full":
            mesh_info["written"] = {"faces": int(res.mesh.n_faces), "what": "the chain's mesh"}
    for stem, m in meshes:
        if "glb" in mesh_formats:
            mesh_info.setdefault("glb", {})[f"{stem}.glb"] = (
                {"compression": "KHR_draco_mesh_compression", "max_position_error_m": GLB_MAX_ERROR_M,
                 "texture": "JPEG quality 90"} if m.n_faces <= GLB_DRACO_MAX_FACES else
                {"compression": "none", "why": f"more than {GLB_DRACO_MAX_FACES} faces"})
        # a Draco-compressed GLB up to GLB_DRACO_MAX_FACES (positions within GLB_MAX_ERROR_M:
        # the reduced mesh of a 2048x1024 frame 19 -> 1.4 MB)
        out = export_mesh(m, staging, stem=stem, formats=tuple(mesh_formats), image=chain.scene.image,
                          glb_compress=True)
        written += list(out.values())
        if "obj" in out:  # its material and texture files beside it
            written += [p for p in (out["obj"].with_suffix(".mtl"), out["obj"].with_name(f"{stem}_texture.png"))
                        if p.exists()]
    return written


def _lights_info(lights) -> dict:
    """The manifest's record of the light annotation the nights used (:class:`~.stages.LightsResult`)."""
    ann = lights.annotation
    ids = [] if ann is None else ann.instance_ids()
    info = {"source": lights.source, "note": lights.note, "count": len(ids),
            "groups": 0 if ann is None else len(ann.groups)}
    if lights.confidence:
        info["confidence"] = {str(k): round(float(v), 3) for k, v in sorted(lights.confidence.items())}
    return info
