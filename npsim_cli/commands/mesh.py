"""``npsim mesh SCENE -o DIR``: input depth -> refinement -> mesh -> PLY/OBJ/GLB, with timings per stage."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..options import add_param_options, clean_leftovers, log, log_warnings, params_from_args, stage_logger


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("mesh", help="build the scene mesh (grid + post-processing) and export it",
                       description="Frame -> input depth -> cross-bilateral filter -> uncertain map -> "
                                   "normal-guided refinement -> Worldsheet grid + post-processing kernel "
                                   "(-> reduced mesh) -> PLY/OBJ/GLB, plus a manifest.")
    p.add_argument("scene", help="scene folder, project folder, or a dataset image with its labels")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--format", default="ply,obj,glb", help="comma-separated subset of ply,obj,glb (default all)")
    p.add_argument("--stride", type=int, default=None, help="vertex spacing in pixels (>1: a strided grid "
                                                            "without post-processing, for previews)")
    p.add_argument("--budget", type=int, default=None, help="reduce to about this many faces (quadtree)")
    p.add_argument("--far", type=float, default=None, help="no geometry beyond this depth (metres; default 300)")
    p.add_argument("--no-refine", action="store_true", help="mesh the filtered depth (skip the refinement)")
    p.add_argument("--no-filter", action="store_true",
                   help="mesh the input depth (skip filter and refinement; U still comes from the filtered depth)")
    p.add_argument("--variant", choices=("npsim", "raw", "filtered"), default="npsim",
                   help="npsim (default), or one of the thesis's baselines: the grid of the input depth (raw) "
                        "or of the filtered depth")
    add_param_options(p, nights=None)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from npsim_core.chain import Chain, check_output_folder, export_frame, load_frame
    from npsim_core.chain.export import check_mesh_formats

    params = params_from_args(args)
    for name, value in (("stride", args.stride), ("face_budget", args.budget), ("far_limit", args.far)):
        if value is not None:
            params = params.with_value("mesh", name, value)
    if args.no_refine or args.no_filter:
        params = params.with_value("mesh", "depth", "input" if args.no_filter else "filtered")
    if args.variant != "npsim":
        params = params.with_value("mesh", "depth", "input" if args.variant == "raw" else "filtered") \
                       .with_value("mesh", "postprocess", False)
    params = params.with_value("export", "mesh", "full")  # the mesh tool writes the chain's mesh itself
    formats = tuple(f.strip().lower() for f in args.format.split(",") if f.strip())
    check_mesh_formats(formats)
    check_output_folder(args.out)
    clean_leftovers("mesh", args.out)
    scene = load_frame(args.scene, hfov_deg=args.fov, with_ground_truth=False)
    chain = Chain(scene)
    log("mesh", f"{scene.name}: {scene.width}x{scene.height}")
    log_warnings("mesh", scene)
    res = chain.compute(params, progress=stage_logger("mesh", scene.name))
    written = export_frame(chain, params, Path(args.out), kinds=("mesh",), mesh_formats=formats,
                           inputs={"scene": str(args.scene), "variant": args.variant})
    mesh = res.mesh
    fg = [p for p in mesh.parts if p.foreground and p.n_faces]
    print(f"mesh {scene.name} ({args.variant}): {mesh.n_faces} faces, {mesh.n_vertices} vertices, "
          f"{len(fg)} foreground objects, {scene.width}x{scene.height} frame, depth from {res.depth_source}")
    for k, v in res.timings.items():
        print(f"  {k:<18} {v:7.2f} s")
    if res.mesh_result.reduced == "bridged":
        print("  note: depth steps bridged by grid quads to meet the budget (their walls need more faces)")
    if args.budget and mesh.n_faces > 1.05 * args.budget:
        print(f"  note: {mesh.n_faces} faces, above the budget of {args.budget}: label, light and "
              "silhouette borders and depth steps stay at pixel resolution and need that many")
    if mesh.n_faces == 0:
        print("  warning: the mesh is empty (all sky, or no valid depth within the far limit)")
    for pth in written:
        print(f"  wrote {pth}")
    return 0
