"""``npsim mesh SCENE -o DIR``: depth -> refinement -> mesh -> export, with timings per stage."""

from __future__ import annotations

import argparse
import time


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mesh", help="build the scene mesh (grid + post-processing) and export it",
                       description="Scene folder -> predicted depth -> cross-bilateral filter -> uncertain map -> "
                                   "normal-guided refinement -> Worldsheet grid + post-processing kernel "
                                   "(-> reduced mesh) -> PLY/OBJ/GLB.")
    p.add_argument("scene", help="scene folder (as written by 'npsim sample' / save_scene)")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--format", default="ply,obj,glb", help="comma-separated subset of ply,obj,glb (default all)")
    p.add_argument("--stride", type=int, default=1, help="vertex spacing in pixels (>1 for previews)")
    p.add_argument("--budget", type=int, default=None, help="reduce to about this many faces (quadtree)")
    p.add_argument("--far", type=float, default=None, help="no geometry beyond this depth (metres)")
    p.add_argument("--no-filter", action="store_true", help="skip the cross-bilateral filter")
    p.add_argument("--no-refine", action="store_true", help="skip the normal-guided refinement")
    p.add_argument("--variant", choices=("npsim", "raw", "filtered"), default="npsim",
                   help="npsim (default) or one of the thesis's baselines")
    p.set_defaults(func=run)


def _subsample(scene, stages, n: int):
    """Every n-th pixel of the scene and depth stages, with the matching intrinsics."""
    import numpy as np

    from ..camera import Intrinsics

    intr = scene.intrinsics
    sl = (slice(None, None, n), slice(None, None, n))
    h, w = scene.labels[sl].shape
    # Pixel u' of the subsampled image is pixel n*u' of the original: fx' = fx/n, cx' = cx/n.
    small = Intrinsics(intr.fx / n, intr.fy / n, intr.cx / n, intr.cy / n, w, h)
    lights = None if scene.lights is None else np.ascontiguousarray(scene.lights.instance_map[sl])
    normals = None if scene.normals is None else np.ascontiguousarray(scene.normals[sl])
    return (small, np.ascontiguousarray(scene.labels[sl]), lights, normals, np.ascontiguousarray(scene.image[sl]),
            {k: np.ascontiguousarray(getattr(stages, k)[sl]) for k in ("predicted", "filtered", "uncertain",
                                                                         "refined")})


def run(args: argparse.Namespace) -> int:
    from ..errors import NpsimInputError
    from ..mesh.export import FORMATS, export_mesh
    from ..mesh.grid import grid_mesh
    from ..mesh.pipeline import PipelineParams, depth_stages
    from ..mesh.postprocess import PostprocessParams, postprocess_mesh
    from ..mesh.reduce import ReduceParams, reduce_mesh
    from ..scene import load_scene

    formats = [f.strip().lower() for f in args.format.split(",") if f.strip()]
    bad = [f for f in formats if f not in FORMATS]
    if bad or not formats:
        raise NpsimInputError(f"--format: unknown {bad or 'empty'}; choose from {','.join(FORMATS)}")
    if args.stride < 1:
        raise NpsimInputError(f"--stride must be >= 1, got {args.stride}")
    t0 = time.perf_counter()
    scene = load_scene(args.scene, with_ground_truth=False)
    times = {"load": time.perf_counter() - t0}
    pp = PostprocessParams(far_limit=args.far)
    params = PipelineParams(filter=not args.no_filter, refine=not args.no_refine, postprocess=pp)
    stages = depth_stages(scene, params)
    times.update(stages.timings)
    for k, why in stages.skipped.items():
        print(f"  {k}: skipped ({why})")
    intr, labels, lights, normals, image, maps = _subsample(scene, stages, args.stride)
    t = time.perf_counter()
    result = None
    if args.variant == "npsim":
        result = postprocess_mesh(maps["refined"], intr, labels, maps["uncertain"], lights, params=pp,
                                  normals=normals)
        mesh = result.mesh
        times["mesh+postprocess"] = time.perf_counter() - t
    else:
        mesh = grid_mesh(maps["predicted" if args.variant == "raw" else "filtered"], intr, labels, lights,
                         far_limit=args.far)
        times["grid mesh"] = time.perf_counter() - t
    if args.budget is not None:
        if result is None:
            raise NpsimInputError("--budget works on the npsim variant (it reduces the post-processed sheets)")
        t = time.perf_counter()
        red = reduce_mesh(result.layers, intr, ReduceParams(budget=args.budget))
        mesh = red.mesh
        times["reduce"] = time.perf_counter() - t
        if red.steps == "bridged":
            print("  note: depth steps bridged by grid quads to meet the budget (their walls need more faces)")
        if mesh.n_faces > 1.05 * args.budget:
            print(f"  note: {mesh.n_faces} faces, above the budget of {args.budget}: label, light and "
                  "silhouette borders and depth steps stay at pixel resolution and need that many")
    t = time.perf_counter()
    paths = export_mesh(mesh, args.out, stem=f"{scene.name}_{args.variant}", formats=formats, image=image)
    times["export"] = time.perf_counter() - t
    times["total"] = time.perf_counter() - t0
    fg = [p for p in mesh.parts if p.foreground and p.n_faces]
    print(f"mesh {scene.name} ({args.variant}): {mesh.n_faces} faces, {mesh.n_vertices} vertices, "
          f"{len(fg)} foreground objects, {intr.width}x{intr.height} grid")
    for k, v in times.items():
        print(f"  {k:<18} {v:7.2f} s")
    for f, pth in paths.items():
        print(f"  wrote {pth}")
    return 0
