"""One writer for every output of a frame: masks, depth, normals, meshes, nights, manifest.

File names (``<name>`` = the frame's name)::

    <name>_labelIds.png, <name>_uncertain.png, light annotation files   masks
    <name>_depth_{input,refined}.{npy,png} + _vis.png                    depth (metres; PNG metres*256)
    <name>_normals_refined.{npy,png} + _vis.png                          normals (camera frame)
    <name>_mesh.{ply,glb,obj}                                            mesh
    <name>_night_<k>.png, _linear.npy, _labelIds.png, _lights.json       night k (seed = night.seed + k)
    <name>_export.json                                                   manifest

Every file is written atomically (a temporary file renamed into place). The manifest --
inputs, parameters, the depth source, each stage's real compute time, each night's
seed, spp, variant, light counts and step times, the files, library versions -- is
written last, so a folder with a manifest is complete.
"""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Callable

import numpy as np

from ..camera import normals_from_depth
from ..errors import NpsimCancelled, NpsimInputError
from .chain import Chain, ChainResults
from .params import ChainParams

__all__ = ["EXPORT_KINDS", "export_frame", "frame_errors", "versions"]

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


def frame_errors(chain: Chain, res: ChainResults) -> dict[str, dict[str, float]]:
    """Errors of the input and refined depth/normals against the frame's ground truth (what it has
    of it: depth and normals separately); empty without ground truth."""
    from ..metrics import depth_metrics, normal_metrics

    sc, out = chain.scene, {}
    if sc.depth_gt is not None and res.depth_in is not None:
        for tag, d in (("input", res.depth_in), ("refined", res.depth)):
            m = depth_metrics(d, sc.depth_gt)
            out[f"depth_{tag}"] = {"abs_rel": float(m.abs_rel), "rmse_m": float(m.rmse), "delta1": float(m.delta1)}
    if sc.normals_gt is not None and res.depth_in is not None:
        for tag, d in (("input", res.depth_in), ("refined", res.depth)):
            m = normal_metrics(normals_from_depth(d, res.intrinsics), sc.normals_gt)
            out[f"normals_{tag}"] = {"rmse_deg": float(m.rmse_deg), "within_11_25": float(m.within_11_25)}
    return out


def export_frame(chain: Chain, params: ChainParams, folder: str | Path, *, nights: int = 1,
                 kinds: tuple[str, ...] = EXPORT_KINDS, mesh_formats: tuple[str, ...] = ("ply", "glb"),
                 cancel: threading.Event | None = None, progress: Callable[[float, str], None] | None = None,
                 inputs: dict | None = None) -> list[Path]:
    """Write ``kinds`` of ``chain``'s frame (and ``nights`` nights) to ``folder``.

    Returns the written paths, the manifest ``<name>_export.json`` last. ``progress(fraction,
    text)`` reports as it goes; ``inputs`` (e.g. the command line's paths) goes into the manifest.
    """
    from ..annotation import save_annotation
    from ..io import depth_to_rgb, normals_to_rgb, write_depth_png, write_image, write_json, write_npy
    from ..io import write_normals_png

    bad = [k for k in kinds if k not in EXPORT_KINDS]
    if bad:
        raise NpsimInputError(f"unknown export kinds {bad}; choose from {EXPORT_KINDS}")
    if nights < 0:
        raise NpsimInputError(f"nights must be >= 0, got {nights}")
    if "mesh" in kinds:
        from ..mesh.export import FORMATS

        badf = [f for f in mesh_formats if f not in FORMATS]
        if badf or not mesh_formats:
            raise NpsimInputError(f"mesh formats: unknown {badf or 'empty'}; choose from {', '.join(FORMATS)}")
    folder = Path(folder)
    if folder.exists() and not folder.is_dir():
        raise NpsimInputError(f"{folder}: exists and is not a folder; choose another output folder")
    folder.mkdir(parents=True, exist_ok=True)
    s, n = chain.scene, chain.scene.name
    written: list[Path] = []
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
    step("writing masks, depth, normals, mesh")

    def put(path: Path, write, data) -> None:
        write(path, data)
        written.append(path)

    if "masks" in kinds:
        put(folder / f"{n}_labelIds.png", write_image, s.labels)
        if res.uncertain is not None:
            put(folder / f"{n}_uncertain.png", write_image, res.uncertain.astype(np.uint8) * 255)
        if chain.annotation is not None:
            written += list(save_annotation(chain.annotation, folder, n).values())
    if "depth" in kinds:
        for tag, d in (("input", res.depth_in), ("refined", res.depth)):
            put(folder / f"{n}_depth_{tag}.npy", write_npy, d.astype(np.float32))
            put(folder / f"{n}_depth_{tag}.png", write_depth_png, d)
            put(folder / f"{n}_depth_{tag}_vis.png", write_image, depth_to_rgb(d))
    if "normals" in kinds:
        nr = normals_from_depth(res.depth, res.intrinsics)
        put(folder / f"{n}_normals_refined.npy", write_npy, nr)
        put(folder / f"{n}_normals_refined.png", write_normals_png, nr)
        put(folder / f"{n}_normals_refined_vis.png", write_image, normals_to_rgb(nr))
    if "mesh" in kinds:
        from ..mesh.export import export_mesh

        out = export_mesh(res.mesh, folder, stem=f"{n}_mesh", formats=tuple(mesh_formats), image=s.image)
        written += list(out.values())
        if "obj" in out:  # its material and texture files beside it
            written += [p for p in (out["obj"].with_suffix(".mtl"), out["obj"].with_name(f"{n}_mesh_texture.png"))
                        if p.exists()]
    nights_info = []
    for k in range(n_nights):
        step(f"rendering night {k + 1}/{n_nights}")
        seed = params.night.seed + k
        frame = chain.night_final(res, params, seed=seed, cancel=cancel)
        stem = f"{n}_night_{k}"
        put(folder / f"{stem}.png", write_image, frame.image)
        put(folder / f"{stem}_linear.npy", write_npy, frame.linear)
        put(folder / f"{stem}_labelIds.png", write_image, s.labels)
        put(folder / f"{stem}_lights.json", write_json, frame.active.to_json())
        on = len(frame.active.on_ids)
        built = chain.night_inputs(params)[0]
        nights_info.append({"night": k, "seed": seed, "spp": frame.spp, "variant": frame.variant,
                            "lights_on": on, "lights": len(frame.active.lights),
                            "lights_without_faces": sorted(int(i) for i in set(frame.active.lights)
                                                           - set(built.area_keys)),
                            "seconds": round(frame.elapsed, 3),
                            "timings": {k2: round(v, 3) for k2, v in frame.timings.items()}})
    # The night stages' times when they ran (their results are cached in the chain).
    timings = dict(res.timings)
    if n_nights:
        run = chain.engine.run(("night_scene", "materials") + (("guides",) if params.night.denoise else ()), params)
        timings.update(run.timings)
    manifest = folder / f"{n}_export.json"
    write_json(manifest, {
        "format": "npsim-export", "scene": n, "size": [s.width, s.height], "inputs": inputs or {},
        "provenance": {k: str(v) for k, v in s.provenance.items() if k != "files"},
        "depth_source": res.depth_source, "params": params.to_json(),
        "timings": {k: round(v, 4) for k, v in timings.items()},
        "mesh": {"faces": int(res.mesh.n_faces), "vertices": int(res.mesh.n_vertices),
                 "reduced": res.mesh_result.reduced},
        "lights_annotated": 0 if chain.annotation is None else len(chain.annotation.instance_ids()),
        "errors": frame_errors(chain, res), "nights": nights_info, "kinds": list(kinds),
        "files": [p.name for p in written], "versions": versions()})
    written.append(manifest)
    if progress is not None:
        progress(1.0, f"exported {len(written)} files")
    return written
