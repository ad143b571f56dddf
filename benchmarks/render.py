"""Night-render benchmark: time and noise error of preview and final renders (results: docs/relight.md).

Usage::

    python benchmarks/render.py [--quick] [--variants scalar_rgb,llvm_ad_rgb] [--out FILE.md]
    npsim bench render [...]

Scene: the synthetic street (ground-truth depth -> Worldsheet grid mesh), one
fixed night (seed 1). For each Mitsuba variant and resolution it measures

* ``build``   mesh -> Mitsuba scene (meshes, BSDFs, emitters) incl. the mesh itself,
* ``toggle``  switching to another night's lights in place (geometry reused),
* ``preview`` progressive preview, 4 passes x 4 spp, direct light only (max_depth 2),
  *including* the scene build (the target: 512x256 at 16 spp <= 2 s),
* ``final``   one-bounce path tracing (max_depth 3) at several spp, each also after the
  guided denoiser (``npsim_core.render.denoise``; the time is the filter's alone),

and the error against a high-spp (``--ref-spp``, default 256) one-bounce
reference: RMSE in 8-bit sRGB levels (0..255) of the noise-free picture at
exposure 0. The preview's error includes its bias (no indirect bounce); the
reference's own noise inflates errors by ~sqrt(1 + spp/ref_spp). For 2048x1024
the reference is a 256x128 crop (centre of the street), and errors are measured
on that crop. Wall times on a shared
machine are noisy: the table also lists the process CPU time and the load.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def _srgb_rmse(img: np.ndarray, ref: np.ndarray) -> float:
    """RMSE in 8-bit sRGB levels (exposure 0, no camera noise) -- what the night picture shows."""
    from npsim_core.render.camera_post import linear_to_srgb

    return float(np.sqrt(np.mean((linear_to_srgb(img) * 255.0 - linear_to_srgb(ref) * 255.0) ** 2)))


def _timed(fn):
    t, c = time.perf_counter(), time.process_time()
    out = fn()
    return out, time.perf_counter() - t, time.process_time() - c


def bench_resolution(W: int, H: int, variant: str, final_spp: list[int], ref_spp: int, crop_ref: bool,
                     preview: bool, log) -> list[dict]:
    from npsim_core.mesh.grid import grid_mesh
    from npsim_core.render.lights import activate_lights, load_light_table
    from npsim_core.render.materials import estimate_materials
    from npsim_core.render.render import PreviewParams, render_linear, render_preview
    from npsim_core.render.scene_builder import BuildParams, build_scene
    from npsim_core.synthetic import street_scene

    s = street_scene(W, H)
    table = load_light_table()
    mats = estimate_materials(s.image, s.labels, albedo=s.albedo, roughness=s.roughness,
                              light_classes=s.lights.class_map())
    night = activate_lights(s.lights, table, 1, image=s.image)
    other = activate_lights(s.lights, table, 2, image=s.image)
    rows = []

    def build():
        mesh = grid_mesh(s.depth_gt, s.intrinsics, s.labels, s.lights.instance_map)
        return build_scene(mesh, s.intrinsics, mats, table, s.lights, night, BuildParams(), variant=variant)

    # Warm-up (imports, LLVM kernel compilation) so timings show steady state.
    warm = build()
    render_linear(warm, spp=1, max_depth=2, scale=0.25)
    render_linear(warm, spp=1, scale=0.25)
    del warm

    built, t_build, c_build = _timed(build)
    rows.append({"variant": variant, "size": f"{W}x{H}", "what": "build scene", "spp": "-",
                 "time": t_build, "cpu": c_build, "err": None, "faces": built.n_faces})
    log(f"  {variant} {W}x{H} build {t_build:.2f} s")
    t_tog = built.apply_lights(other)
    t_back = built.apply_lights(night)
    rows.append({"variant": variant, "size": f"{W}x{H}", "what": "light toggle (in place)", "spp": "-",
                 "time": min(t_tog, t_back), "cpu": None, "err": None})

    crop = None
    if crop_ref:
        cw, ch = 256, 128
        crop = ((W - cw) // 2, int(H * 0.45), cw, ch)
    ref, t, _ = _timed(lambda: render_linear(built, spp=ref_spp, seed=998, crop=crop))
    log(f"  reference (one bounce) {ref_spp} spp {t:.1f} s")

    if preview:
        def prev():
            b = build()
            last = None
            for f in render_preview(b, PreviewParams(scale=1.0, spp_per_pass=4, passes=4, seed=5)):
                last = f
            return last.image

        img, t, c = _timed(prev)
        err = _srgb_rmse(img if crop is None else img[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]], ref)
        rows.append({"variant": variant, "size": f"{W}x{H}", "what": "preview 4x4 spp incl. build", "spp": 16,
                     "time": t, "cpu": c, "err": err})

        def prev_app():  # the app's schedule: a 4-spp first frame, then the other 12 in one pass
            last = None
            for f in render_preview(build(), PreviewParams(scale=1.0, schedule=(4, 12), seed=5)):
                last = f
            return last.image

        img, t, c = _timed(prev_app)
        err = _srgb_rmse(img if crop is None else img[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]], ref)
        rows.append({"variant": variant, "size": f"{W}x{H}", "what": "preview 4+12 spp incl. build (app)",
                     "spp": 16, "time": t, "cpu": c, "err": err})
        log(f"  preview {t:.2f} s err {err:.3f}")
    from npsim_core.render.denoise import denoise, denoise_guides

    guides = denoise_guides(grid_mesh(s.depth_gt, s.intrinsics, s.labels), s.intrinsics, mats.albedo, s.labels,
                            s.lights.class_map() > 0)
    for spp in final_spp:
        img, t, c = _timed(lambda: render_linear(built, spp=spp, seed=spp, crop=None))
        part = img if crop is None else img[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]]
        err = _srgb_rmse(part, ref)
        rows.append({"variant": variant, "size": f"{W}x{H}", "what": "final (render only)", "spp": spp,
                     "time": t, "cpu": c, "err": err})
        log(f"  final {spp} spp {t:.2f} s err {err:.3f}")
        den, t, c = _timed(lambda: denoise(img, guides))
        part = den if crop is None else den[crop[1]:crop[1] + crop[3], crop[0]:crop[0] + crop[2]]
        err = _srgb_rmse(part, ref)
        rows.append({"variant": variant, "size": f"{W}x{H}", "what": "  + denoise (time of the filter)", "spp": spp,
                     "time": t, "cpu": c, "err": err})
        log(f"  denoise {t:.2f} s err {err:.3f}")
    return rows


def make_triptych(path: str, W: int = 512, H: int = 256, spp: int = 64, seeds=(0, 1, 2)) -> None:
    """Day image + three nights of the synthetic street side by side (docs/img/night_triptych.png).

    Uses the same path as ``npsim night`` with its defaults: the scene's *estimated* depth
    through the best available mesh pipeline, default light table, 64 spp, the guided
    denoiser, camera post-processing at ISO 1600.
    """
    import cv2

    from npsim_core.chain import Chain, ChainParams
    from npsim_core.io import write_image
    from npsim_core.synthetic import street_scene

    s = street_scene(W, H)
    chain = Chain(s)
    params = ChainParams().with_value("night", "final_spp", int(spp))
    res = chain.compute(params)
    src = f"{res.mesh.n_faces} faces from the refined depth"
    tiles = [s.image]
    for seed in seeds:
        frame = chain.night_final(res, params, seed=seed)
        tiles.append(frame.image)
        write_image(Path(path).with_name(f"night_{seed}.png"), frame.image)
    variant = frame.variant
    gap = np.full((H, 4, 3), 255, np.uint8)
    row = np.concatenate(sum(([t, gap] for t in tiles), [])[:-1], axis=1)
    labels = ["day (input)"] + [f"night seed {k}" for k in seeds]
    for i, text in enumerate(labels):
        cv2.putText(row, text, (i * (W + 4) + 6, 18), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (255, 255, 255), 1, cv2.LINE_AA)
    write_image(path, row)
    print(f"wrote {path} (mesh: {src}, variant {variant}, {spp} spp)", file=sys.stderr)


def format_table(rows: list[dict]) -> str:
    lines = ["| variant | size | what | spp | time s | cpu s | RMSE (sRGB levels) |", "|---|---|---|---|---|---|---|"]
    for r in rows:
        cpu = "-" if r["cpu"] is None else f"{r['cpu']:.1f}"
        err = "-" if r["err"] is None else f"{r['err']:.3f}"
        lines.append(f"| {r['variant']} | {r['size']} | {r['what']} | {r['spp']} | {r['time']:.2f} | {cpu} | {err} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="npsim bench render", description=__doc__.split("\n\n")[0])
    ap.add_argument("--quick", action="store_true", help="512x256 only")
    ap.add_argument("--variants", default=None, help="comma list (default: scalar_rgb plus llvm_ad_rgb if usable)")
    ap.add_argument("--out", default=None, help="also write the table (markdown) to this file")
    ap.add_argument("--ref-spp", type=int, default=256, help="spp of the reference renders (default 256)")
    ap.add_argument("--triptych", default=None, metavar="PNG",
                    help="only write the day + three nights picture to PNG (e.g. docs/img/night_triptych.png)")
    ap.add_argument("--fast-final", metavar="BUDGET", type=int, default=0,
                    help="only time 2048x1024 finals at 64 spp (scalar_rgb) on a quadtree mesh of about BUDGET "
                         "faces, with one bounce and with direct light only (npsim night --face-budget/--max-depth)")
    args = ap.parse_args(argv)
    if args.fast_final:
        return fast_final(args.fast_final)
    if args.triptych:
        make_triptych(args.triptych)
        return 0

    from npsim_core.render.variant import choose_variant

    if args.variants:
        variants = [v.strip() for v in args.variants.split(",") if v.strip()]
    else:
        variants = ["scalar_rgb"]
        ch = choose_variant()
        if ch.name == "llvm_ad_rgb":
            variants.append("llvm_ad_rgb")
        print(f"llvm_ad_rgb: {ch.reason}", file=sys.stderr)
    log = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    load0 = os.getloadavg()
    rows: list[dict] = []
    for v in variants:
        rows += bench_resolution(512, 256, v, [4, 16, 64], args.ref_spp, False, True, log)
        if not args.quick:
            rows += bench_resolution(2048, 1024, v, [16, 64], args.ref_spp, True, False, log)
    load1 = os.getloadavg()
    table = format_table(rows)
    head = (f"Mitsuba render benchmark ({time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores, "
            f"load average {load0[0]:.1f} at start, {load1[0]:.1f} at end)")
    print(head)
    print(table)
    if args.out:
        Path(args.out).write_text(head + "\n\n" + table + "\n")
    return 0


def fast_final(budget: int, size: tuple[int, int] = (2048, 1024), spp: int = 64) -> int:
    """Time full-resolution finals on a reduced mesh, as ``npsim night --face-budget B --max-depth D``."""
    os.environ["NPSIM_MITSUBA_VARIANT"] = "scalar_rgb"
    from npsim_core.render.render import render_final
    from npsim_core.synthetic import street_scene
    from npsim_core.chain import Chain, ChainParams

    scene = street_scene(*size)
    chain = Chain(scene)
    params = ChainParams().with_value("mesh", "face_budget", int(budget))
    load0 = os.getloadavg()[0]
    res = chain.compute(params)
    (built, t_build, _) = _timed(lambda: chain.night_inputs(params)[0])
    built.apply_lights(chain.activate(params))
    print(f"fast finals, {size[0]}x{size[1]}, {spp} spp, {built.variant}, mesh {res.mesh.n_faces} faces "
          f"(budget {budget}), scene build {t_build:.1f} s, load {load0:.1f}")
    print("| path length | time s | cpu s |")
    print("|---|---|---|")
    for depth in (3, 2):
        _, t, c = _timed(lambda: render_final(built, spp=spp, seed=1, max_depth=depth))
        print(f"| {'one bounce' if depth == 3 else 'direct light only'} (max_depth {depth}) | {t:.1f} | {c:.1f} |",
              flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
