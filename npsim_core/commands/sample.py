"""``npsim sample --size WxH -o DIR [--seed S]``: write the synthetic street scene as a scene folder."""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import NpsimInputError


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` -> (W, H); raises NpsimInputError with the expected form."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text))
    if not m:
        raise NpsimInputError(f"--size {text!r}: expected WIDTHxHEIGHT in pixels, e.g. --size 512x256")
    w, h = int(m.group(1)), int(m.group(2))
    if not (2 <= w <= 16384 and 2 <= h <= 16384):
        raise NpsimInputError(f"--size {text!r}: width and height must be between 2 and 16384 pixels")
    return w, h


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("sample", help="write the built-in synthetic street scene (with ground truth) as a scene folder",
                       description="Generate the synthetic street scene: daytime RGB (Mitsuba), Cityscapes labels, "
                                   "exact depth/normals, simulated predicted depth/normals, light annotation.")
    p.add_argument("--size", default="512x256", help="image size WIDTHxHEIGHT in pixels (default 512x256)")
    p.add_argument("-o", "--output", required=True, help="output scene folder (created if missing)")
    p.add_argument("--seed", type=int, default=0, help="layout / prediction-error seed (default 0)")
    p.add_argument("--spp", type=int, default=None, help="Mitsuba samples per pixel (default: 16 up to 512x256 "
                                                         "pixels, 4 above; rounded up to 4, 16, 64, ...)")
    p.add_argument("--preview", metavar="PNG", default=None,
                   help="also write a 2x3 overview (RGB, depth, normals, labels, lights, predicted depth); "
                        "default: <output>/overview.png")
    p.add_argument("--no-preview", action="store_true", help="do not write the overview picture")
    p.set_defaults(func=run)


def overview_image(scene) -> np.ndarray:
    """2x3 panel: RGB | GT depth | GT normals / labels | lights over RGB | predicted depth (uint8 RGB)."""
    from ..io import depth_to_rgb, normals_to_rgb
    from ..labels import cityscapes, light_class

    rgb = scene.image
    vmax = float(np.nanpercentile(scene.depth_gt, 99)) if np.isfinite(scene.depth_gt).any() else None
    lights = rgb.copy() // 3
    if scene.lights is not None:
        inst = scene.lights.instance_map
        cls = inst // 1000
        lut = np.zeros((256, 3), dtype=np.uint8)
        for c in range(1, 13):
            lut[c] = light_class(c).color
        on = inst > 0
        lights[on] = lut[cls[on]]
    panels = [rgb, depth_to_rgb(scene.depth_gt, vmax), normals_to_rgb(scene.normals_gt),
              cityscapes().colorize(scene.labels), lights,
              depth_to_rgb(scene.depth, vmax) if scene.depth is not None else np.zeros_like(rgb)]
    top = np.concatenate(panels[:3], axis=1)
    bottom = np.concatenate(panels[3:], axis=1)
    return np.concatenate([top, bottom], axis=0)


def run(args: argparse.Namespace) -> int:
    from ..io import write_image
    from ..scene import save_scene
    from ..synthetic import auto_spp, make_street_scene

    w, h = parse_size(args.size)
    if args.spp is not None and args.spp < 1:
        raise NpsimInputError(f"--spp {args.spp}: must be at least 1")
    out = Path(args.output)
    if out.exists() and not out.is_dir():
        raise NpsimInputError(f"-o {out}: exists and is not a folder; choose another output path")
    spp = args.spp if args.spp is not None else auto_spp(w, h)
    print(f"npsim sample: generating {w}x{h} street (seed {args.seed}, {spp} spp) ...", file=sys.stderr, flush=True)
    t0 = time.perf_counter()
    scene = make_street_scene(w, h, args.seed, spp=spp)
    t1 = time.perf_counter()
    print(f"npsim sample: generated in {t1 - t0:.1f} s at {scene.provenance.get('spp')} spp "
          f"({scene.provenance.get('timing_s')}); writing {out}",
          file=sys.stderr, flush=True)
    save_scene(scene, out)
    if not args.no_preview:
        preview = Path(args.preview) if args.preview else out / "overview.png"
        write_image(preview, overview_image(scene))
        print(f"npsim sample: overview -> {preview}", file=sys.stderr)
    n_lights = len(scene.lights.instance_ids()) if scene.lights is not None else 0
    print(f"npsim sample: wrote {out} ({n_lights} light instances) in {time.perf_counter() - t0:.1f} s total",
          file=sys.stderr)
    return 0
