"""``npsim night SCENE -o DIR --variants K --seed S``: render K labelled nights of a scene folder.

Per night k (seed S + k) it writes, into DIR:

* ``<name>_night_<k>.png``           8-bit sRGB night (camera post-processing applied)
* ``<name>_night_<k>_linear.npy``    float32 HxWx3 linear render (before exposure/noise)
* ``<name>_night_<k>_labelIds.png``  the day labels, copied unchanged
* ``<name>_night_<k>_lights.json``   every light's state (on/off, strength, radiance)
* ``<name>_night_<k>_params.json``   all parameters used (mesh source, variant, spp, camera, seed)

The Mitsuba scene is built once; each night only switches lights in place.
Progress goes to stderr.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import cv2
import numpy as np


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("night", help="render labelled nighttime variants of a scene folder")
    p.add_argument("scene", help="scene folder (as written by 'npsim sample' / 'npsim estimate')")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--variants", type=int, default=3, help="number of nights (default 3)")
    p.add_argument("--seed", type=int, default=0, help="seed of the first night (night k uses seed+k)")
    p.add_argument("--spp", type=int, default=64, help="samples per pixel (default 64)")
    p.add_argument("--scale", type=float, default=1.0, help="render at this fraction of the scene resolution")
    p.add_argument("--iso", type=int, default=1600, help="camera noise preset ISO (0 = no noise; default 1600)")
    p.add_argument("--exposure", type=float, default=0.0, help="exposure in stops (default 0)")
    p.add_argument("--no-ego-lights", action="store_true", help="switch off the ego vehicle's headlights")
    p.add_argument("--group-all-together", action="store_true", help="each light group switches as one")
    p.add_argument("--motion-blur", type=int, default=0, help="horizontal blur (px) of moving vehicles")
    p.add_argument("--no-denoise", action="store_true",
                   help="keep the Monte Carlo noise (default: filtered, guided by the mesh's depth, normals and labels)")
    p.add_argument("--light-table", default=None, help="user light table JSON merged over the default")
    p.add_argument("--mesh", choices=["auto", "grid"], default="auto",
                   help="auto: refined depth + post-processed mesh (full chain); grid: plain grid mesh (fast)")
    p.add_argument("--variant", choices=["scalar_rgb", "llvm_ad_rgb"], default=None,
                   help="Mitsuba variant (default: probed, llvm_ad_rgb when usable)")
    p.add_argument("--max-depth", type=int, default=3, choices=[2, 3, 4],
                   help="path length: 2 = direct light only (fast), 3 = one bounce (default), 4 = two")
    p.add_argument("--face-budget", type=int, default=0,
                   help="render a quadtree-reduced mesh of about this many faces (0 = full mesh; --mesh auto)")
    p.set_defaults(func=run)


def _log(msg: str) -> None:
    print(f"[npsim night] {msg}", file=sys.stderr, flush=True)


def scaled_scene(scene, scale: float):
    """The scene resampled to ``scale`` (image INTER_AREA; labels, depth, lights nearest)."""
    from ..errors import NpsimInputError

    if scale == 1.0:
        return scene
    if not (0.05 <= scale <= 1.0):
        raise NpsimInputError(f"--scale must be in [0.05, 1], got {scale}")
    W, H = max(2, round(scene.width * scale)), max(2, round(scene.height * scale))
    near = lambda a: None if a is None else cv2.resize(a, (W, H), interpolation=cv2.INTER_NEAREST)  # noqa: E731
    lights = None
    if scene.lights is not None:
        from ..annotation import LightAnnotation

        lights = LightAnnotation(near(scene.lights.instance_map.astype(np.int32)), dict(scene.lights.groups))
        present = set(lights.instance_ids())
        lights.groups = {gid: type(g)(g.id, tuple(m for m in g.members if m in present))
                         for gid, g in lights.groups.items() if any(m in present for m in g.members)}
    return scene.with_(image=cv2.resize(scene.image, (W, H), interpolation=cv2.INTER_AREA),
                       labels=near(scene.labels), intrinsics=scene.intrinsics.resized(W, H),
                       depth=near(scene.depth), normals=near(scene.normals), depth_gt=near(scene.depth_gt),
                       normals_gt=near(scene.normals_gt), lights=lights, albedo=near(scene.albedo),
                       roughness=near(scene.roughness))


def build_night_mesh(scene, mode: str = "auto", face_budget: int = 0):
    """Scene mesh for relighting; returns (SceneMesh, Intrinsics, description).

    ``auto``: the full NPSim chain of :mod:`npsim_core.workflow` (cross-bilateral
    filter -> uncertain map -> normal-guided refinement -> grid mesh + post-processing
    kernel) on the scene's *estimated* depth (or the pop-up prior when it has none);
    falls back to ``grid`` when that chain is unavailable. ``grid``: the plain
    Worldsheet grid mesh of the estimated depth (fast). Ground truth is never used.
    """
    from ..errors import NpsimInputError
    from ..mesh.grid import grid_mesh

    if mode not in ("auto", "grid"):
        raise NpsimInputError(f"--mesh must be 'auto' or 'grid', got {mode!r}")
    if mode == "auto":
        try:
            from ..workflow import Workflow, WorkflowParams
        except ImportError as exc:  # pragma: no cover - chain modules missing in a partial install
            _log(f"full mesh chain unavailable ({exc}); using the grid mesh")
        else:
            t0 = time.perf_counter()
            params = WorkflowParams().with_value("mesh", "face_budget", int(face_budget))
            res = Workflow(scene).compute(params, until="mesh")
            reduced = f", reduced to {res.mesh.n_faces} faces" if face_budget else ""
            return (res.mesh, res.intrinsics,
                    f"workflow: filter -> uncertain -> refine -> grid + post-processing{reduced} "
                    f"({time.perf_counter() - t0:.1f} s)")
    if scene.depth is None:
        raise NpsimInputError(f"scene {scene.name!r} has no estimated depth (depth_pred.npy); "
                              "create one with 'npsim estimate', or use --mesh auto (pop-up prior)")
    light_ids = scene.lights.instance_map if scene.lights is not None else None
    mesh = grid_mesh(scene.depth, scene.intrinsics, scene.labels, light_ids)
    return mesh, scene.intrinsics, "grid_mesh(estimated depth)"


def run(args: argparse.Namespace) -> int:
    from ..errors import NpsimInputError
    from ..io import write_image, write_json, write_npy
    from ..render.camera_post import CameraParams, apply_camera
    from ..render.lights import activate_lights, load_light_table
    from ..render.materials import estimate_materials
    from ..render.render import render_final
    from ..render.scene_builder import BuildParams, build_scene
    from ..render.variant import resolve_variant
    from ..scene import load_scene

    if args.variants < 1:
        raise NpsimInputError(f"--variants must be >= 1, got {args.variants}")
    if args.spp < 1:
        raise NpsimInputError(f"--spp must be >= 1, got {args.spp}")
    t0 = time.perf_counter()
    scene = scaled_scene(load_scene(args.scene, with_ground_truth=False), args.scale)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    choice = resolve_variant(args.variant)
    _log(f"scene {scene.name} {scene.width}x{scene.height}; Mitsuba variant {choice.name} ({choice.reason})")
    if args.face_budget < 0:
        raise NpsimInputError(f"--face-budget must be >= 0 (0 = full mesh), got {args.face_budget}")
    mesh, intr, mesh_src = build_night_mesh(scene, args.mesh, args.face_budget)
    _log(f"mesh: {mesh_src}, {mesh.n_faces} faces")
    table = load_light_table(args.light_table)
    light_cls = scene.lights.class_map() if scene.lights is not None else np.zeros(scene.labels.shape, np.uint8)
    mats = estimate_materials(scene.image, scene.labels, albedo=scene.albedo, roughness=scene.roughness,
                              light_classes=light_cls)
    bparams = BuildParams(ego_headlights=not args.no_ego_lights, camera_height=scene.camera_height,
                          camera_pitch=scene.camera_pitch, max_depth=args.max_depth)
    built = build_scene(mesh, intr, mats, table, scene.lights, None, bparams, variant=choice.name)
    _log(f"scene built in {built.build_seconds:.2f} s ({built.info['shapes']} shapes, {built.info['lights']} lights)")
    guides = None
    if not args.no_denoise:
        from ..render.denoise import denoise_guides

        t1 = time.perf_counter()
        guides = denoise_guides(mesh, intr, mats.albedo, scene.labels, light_cls > 0)
        _log(f"denoising guides (mesh seen through each pixel) in {time.perf_counter() - t1:.2f} s")
    for k in range(args.variants):
        seed = args.seed + k
        t1 = time.perf_counter()
        active = activate_lights(scene.lights, table, seed, group_all_together=args.group_all_together,
                                 image=scene.image)
        toggle_s = built.apply_lights(active)
        linear = render_final(built, spp=args.spp, seed=seed)
        cam = CameraParams(exposure_ev=args.exposure, iso=args.iso or None, motion_blur_px=args.motion_blur, seed=seed,
                           denoise=not args.no_denoise)
        srgb, _ = apply_camera(linear, cam, labels=scene.labels, light_classes=light_cls, guides=guides)
        stem = f"{scene.name}_night_{k}"
        write_image(out / f"{stem}.png", srgb)
        write_npy(out / f"{stem}_linear.npy", linear)
        write_image(out / f"{stem}_labelIds.png", scene.labels)
        write_json(out / f"{stem}_lights.json", active.to_json())
        write_json(out / f"{stem}_params.json", {
            "scene": str(args.scene), "name": scene.name, "night": k, "seed": seed, "width": scene.width,
            "height": scene.height, "scale": args.scale, "mesh": mesh_src, "faces": mesh.n_faces,
            "variant": choice.name, "variant_reason": choice.reason, "spp": args.spp, "denoise": not args.no_denoise,
            "max_depth": bparams.max_depth, "ego_headlights": bparams.ego_headlights,
            "group_all_together": args.group_all_together, "light_table": table.source,
            "unit_scale": table.unit_scale, "materials": mats.source,
            "camera": {"exposure_ev": cam.exposure_ev, "iso": cam.iso, "beta1": cam.betas()[0],
                       "beta2": cam.betas()[1], "white_balance": list(cam.white_balance),
                       "motion_blur_px": cam.motion_blur_px},
            "lights_without_faces": sorted(set(active.lights) - set(built.area_keys)),
            "toggle_seconds": toggle_s, "render_seconds": time.perf_counter() - t1})
        _log(f"night {k + 1}/{args.variants}: {len(active.on_ids)}/{len(active.lights)} lights on, "
             f"{time.perf_counter() - t1:.1f} s -> {out / (stem + '.png')}")
    _log(f"done in {time.perf_counter() - t0:.1f} s")
    return 0
