"""``npsim night SCENE -o DIR --variants K --seed S``: render K labelled nights of a frame.

Per night k (seed S + k) it writes, into DIR, exactly what ``npsim run`` writes for its
nights (the same writer, :func:`npsim_core.chain.export_frame`):

* ``<name>_night_<k>.png``           8-bit sRGB night (denoised, camera post-processing applied)
* ``<name>_night_<k>_linear.npy``    float32 HxWx3 linear render (before denoising and camera)
* ``<name>_night_<k>_labelIds.png``  the day labels, copied unchanged
* ``<name>_night_<k>_lights.json``   every light's state (on/off, strength, radiance)
* ``<name>_export.json``             the manifest: parameters, depth source, timings, per-night seeds

The Mitsuba scene is built once; each night only switches lights in place.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from npsim_core.errors import NpsimInputError

from ..options import add_param_options, clean_leftovers, params_from_args


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("night", help="render labelled nighttime variants of a frame",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="scene folder, project folder, or a dataset image with its labels")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--variants", type=int, default=3, help="number of nights (default 3)")
    p.add_argument("--scale", type=float, default=1.0, help="render at this fraction of the frame's resolution")
    p.add_argument("--iso", type=int, default=None, help="camera noise preset ISO (0 = no noise; default 1600)")
    p.add_argument("--exposure", type=float, default=None,
                   help="exposure in stops: a compensation added to the metered exposure with --exposure-mode auto "
                        "(default), the whole exposure with manual (default 0)")
    p.add_argument("--exposure-mode", choices=["auto", "manual"], default=None,
                   help="auto (default): the camera meters the lit pixels and sets the exposure, bounded "
                        "(night.exposure_target/min/max); manual: --exposure alone")
    p.add_argument("--no-ego-lights", action="store_true", help="switch off the ego vehicle's headlights")
    p.add_argument("--group-all-together", action="store_true", help="each light group switches as one")
    p.add_argument("--motion-blur", type=int, default=None, help="horizontal blur (px) of moving vehicles")
    p.add_argument("--no-denoise", action="store_true",
                   help="keep the Monte Carlo noise (same as --denoiser none; default: --denoiser oidn)")
    p.add_argument("--light-table", default=None, help="user light table JSON merged over the default")
    p.add_argument("--mesh", choices=["auto", "grid"], default="auto",
                   help="auto: refined depth + post-processed mesh (full chain); grid: plain grid mesh of the "
                        "input depth (fast)")
    p.add_argument("--variant", choices=["scalar_rgb", "llvm_ad_rgb"], default=None,
                   help="Mitsuba variant (default: probed, llvm_ad_rgb when usable)")
    p.add_argument("--max-depth", type=int, default=None, choices=[2, 3, 4],
                   help="path length: 2 = direct light only (fast), 3 = one bounce (default), 4 = two")
    p.add_argument("--face-budget", type=int, default=None,
                   help="reduce the chain's mesh to about this many faces (0 = the full mesh, default; "
                        "--set mesh.render_tolerance=0.01 renders an error-bounded reduction instead)")
    add_param_options(p, nights=None)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from npsim_core.chain import check_output_folder, load_frame

    from .run import process_frame

    if args.variants < 1:
        raise NpsimInputError(f"--variants must be >= 1, got {args.variants}")
    params = params_from_args(args)
    check_output_folder(args.out)
    clean_leftovers("night", args.out)
    night = {"iso": args.iso, "exposure": args.exposure, "exposure_mode": args.exposure_mode, "motion_blur_px": args.motion_blur,
             "light_table": args.light_table, "variant": args.variant, "final_max_depth": args.max_depth}
    for name, value in night.items():
        if value is not None:
            params = params.with_value("night", name, value)
    for flag, name in ((args.no_ego_lights, "ego_headlights"), (args.no_denoise, "denoise")):
        if flag:
            params = params.with_value("night", name, False)
    if args.group_all_together:
        params = params.with_value("night", "group_all_together", True)
    if args.face_budget is not None:
        params = params.with_value("mesh", "face_budget", int(args.face_budget))
    if args.mesh == "grid":
        params = params.with_value("mesh", "depth", "input").with_value("mesh", "postprocess", False)
    scene = load_frame(args.scene, hfov_deg=args.fov, scale=args.scale, with_ground_truth=False)
    written = process_frame(scene, params, Path(args.out), args.variants, "night", kinds=("nights",),
                            inputs={"scene": str(args.scene), "scale": args.scale})
    print(f"wrote {len(written)} files to {args.out}")
    return 0
