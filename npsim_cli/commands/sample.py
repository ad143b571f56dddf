"""``npsim sample --size WxH -o DIR [--seed S] [--variant NAME]``: write the synthetic street scene as a scene folder."""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from npsim_core.errors import NpsimInputError

from ..options import parse_size


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sample", help="write the built-in synthetic street scene (with ground truth) as a scene folder",
                       description="Generate the synthetic street scene: daytime RGB (Mitsuba), Cityscapes labels, "
                                   "exact depth/normals, simulated predicted depth/normals, light annotation.")
    p.add_argument("--size", default="512x256", help="image size WIDTHxHEIGHT in pixels (default 512x256)")
    p.add_argument("-o", "--output", required=True, help="output scene folder (created if missing)")
    p.add_argument("--seed", type=int, default=0, help="layout / prediction-error seed (default 0)")
    # The variants are checked in run(): importing npsim_core.synthetic here cost every command's
    # start 0.15 s and numpy + OpenCV (benchmarks/cli_start.py).
    p.add_argument("--variant", default="default",
                   help="street variant (docs/synthetic.md; default: default; an unknown name lists them)")
    p.add_argument("--spp", type=int, default=None, help="Mitsuba samples per pixel (default: 16 up to 512x256 "
                                                         "pixels, 4 above; rounded up to 4, 16, 64, ...)")
    p.add_argument("--preview", metavar="PNG", default=None,
                   help="also write a 2x3 overview (RGB, depth, normals, labels, lights, predicted depth); "
                        "default: <output>/overview.png")
    p.add_argument("--no-preview", action="store_true", help="do not write the overview picture")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from npsim_core.chain import check_output_folder
    from npsim_core.io import write_image
    from npsim_core.scene import save_scene
    from npsim_core.synthetic import auto_spp, make_street_scene
    from npsim_core.views import scene_overview

    w, h = parse_size(args.size)
    if args.spp is not None and args.spp < 1:
        raise NpsimInputError(f"--spp {args.spp}: must be at least 1")
    out = check_output_folder(args.output)
    spp = args.spp if args.spp is not None else auto_spp(w, h)
    variant = getattr(args, "variant", "default")
    from npsim_core.synthetic.street import VARIANTS

    if variant not in VARIANTS:
        raise NpsimInputError(f"--variant {variant!r}: unknown street variant; choose one of {', '.join(VARIANTS)}")
    print(f"npsim sample: generating {w}x{h} street (variant {variant}, seed {args.seed}, {spp} spp) ...",
          file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    scene = make_street_scene(w, h, args.seed, spp=spp, variant=variant)
    t1 = time.perf_counter()
    print(f"npsim sample: generated in {t1 - t0:.1f} s at {scene.provenance.get('spp')} spp "
          f"({scene.provenance.get('timing_s')}); writing {out}",
          file=sys.stderr, flush=True)
    save_scene(scene, out)
    if not args.no_preview:
        preview = Path(args.preview) if args.preview else out / "overview.png"
        write_image(preview, scene_overview(scene))
        print(f"npsim sample: overview -> {preview}", file=sys.stderr)
    n_lights = len(scene.lights.instance_ids()) if scene.lights is not None else 0
    print(f"npsim sample: wrote {out} ({n_lights} light instances) in {time.perf_counter() - t0:.1f} s total",
          file=sys.stderr)
    return 0
