"""Night-render benchmark: time and noise error of preview and final renders (results: docs/relight.md).

Usage::

    python benchmarks/render.py [--quick] [--variants scalar_rgb,llvm_ad_rgb] [--out FILE.md]
    python -m benchmarks.render --frontier [--sizes 512x256,2048x1024] [--spp 4,8,16,64]
        [--denoisers none,guided,oidn] [--depths 2,3] [--samplers independent,multijitter]
        [--meshes full,reduced] [--cache DIR] [--out FILE.md] [--plot PNG]
    python -m benchmarks.render --replot FILE.json --plot docs/img/render_frontier.png
    python -m benchmarks.render --defaults [--legacy] [--cache DIR]
    python -m benchmarks.render --crops-figure docs/img/denoiser_crops.png [--cache DIR]
    npsim bench render [...]

``--frontier`` measures the speed-error frontier of the nights (:func:`frontier`: RMSE and SSIM
against a 4096-spp reference over spp x denoiser x mesh x path depth); ``--defaults`` times the
chain's defaults end to end (:func:`defaults`); ``--crops-figure`` shows the frontier's crops
(:func:`crops_figure`). Results: docs/relight.md. The older tables (no option):

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
    ap.add_argument("--ref-spp", type=int, default=256,
                    help="spp of the reference renders (default 256; 4096 with --frontier)")
    ap.add_argument("--triptych", default=None, metavar="PNG",
                    help="only write the day + three nights picture to PNG (e.g. docs/img/night_triptych.png)")
    ap.add_argument("--fast-final", metavar="BUDGET", type=int, default=0,
                    help="only time 2048x1024 finals at 64 spp (scalar_rgb) on a quadtree mesh of about BUDGET "
                         "faces, with one bounce and with direct light only (npsim night --face-budget/--max-depth)")
    ap.add_argument("--frontier", action="store_true",
                    help="the speed-error frontier: spp x denoiser x mesh (full, reduced) x path depth (see --sizes)")
    ap.add_argument("--sizes", default="512x256,2048x1024", help="frontier sizes (default 512x256,2048x1024)")
    ap.add_argument("--spp", default="4,8,16,64", help="frontier spp (default 4,8,16,64)")
    ap.add_argument("--denoisers", default="none,guided,oidn",
                    help="frontier denoisers: none, guided, oidn (default quality), oidn-balanced, oidn-high, "
                         "oidn-meshguides (OIDN with the rasterised mesh as guides), oidn-noguides")
    ap.add_argument("--replot", default=None, metavar="JSON",
                    help="only redraw --plot from the JSON of an earlier --frontier --out run")
    ap.add_argument("--depths", default="2,3", help="frontier path depths (default 2,3)")
    ap.add_argument("--samplers", default="independent",
                    help="frontier Mitsuba samplers: independent (default), multijitter, stratified, ldsampler")
    ap.add_argument("--meshes", default="full,reduced", help="frontier meshes: full, reduced (default both)")
    ap.add_argument("--cache", default=None, help="folder for the frontier's reference renders (reused when present)")
    ap.add_argument("--plot", default=None, metavar="PNG", help="frontier plot, e.g. docs/img/render_frontier.png")
    ap.add_argument("--defaults", action="store_true",
                    help="time the chain's defaults end to end (final 2048x1024 night, app preview at 512x256)")
    ap.add_argument("--legacy", action="store_true", help="with --defaults: also the settings before session 3")
    ap.add_argument("--crops-figure", default=None, metavar="PNG",
                    help="the 2048x1024 crops raw / before / now / reference, e.g. docs/img/denoiser_crops.png")
    args = ap.parse_args(argv)
    if args.crops_figure:
        return crops_figure(args.crops_figure, cache=args.cache)
    if args.replot:
        return replot(args.replot, args.plot or "docs/img/render_frontier.png")
    if args.frontier:
        return frontier(args.sizes, [int(v) for v in args.spp.split(",")], args.denoisers.split(","),
                        [int(v) for v in args.depths.split(",")], 4096 if args.ref_spp == 256 else args.ref_spp,
                        args.cache, args.out, args.plot, samplers=args.samplers.split(","),
                        meshes=args.meshes.split(","))
    if args.defaults:
        return defaults(legacy=args.legacy, cache=args.cache)
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


# --------------------------------------------------------------------------- the speed-error frontier
#: Fixed crops (x, y, w, h as fractions of the frame) where errors are measured on frames larger
#: than :data:`FULL_FRAME_MAX` pixels: the street centre (far cars and their lamps, lit windows,
#: the road), a façade with windows on the left, parked cars with lamps on the right.
CROPS = ((0.4375, 0.33, 0.125, 0.125), (0.03, 0.26, 0.125, 0.125), (0.72, 0.40, 0.125, 0.125))
FULL_FRAME_MAX = 512 * 256
#: Samples per pixel per Mitsuba call (bounds the wavefront's memory), as the chain's finals do.
PASS_SPP = 16


def _srgb(img: np.ndarray) -> np.ndarray:
    from npsim_core.render.camera_post import linear_to_srgb

    return linear_to_srgb(img) * 255.0


def ssim(a: np.ndarray, b: np.ndarray) -> float:
    """Mean SSIM (Wang et al. 2004: 11x11 Gaussian window, σ 1.5, K = 0.01, 0.03) of two linear
    renders seen as 8-bit sRGB (exposure 0, no camera noise), averaged over the three channels."""
    import cv2

    x, y = _srgb(a).astype(np.float64), _srgb(b).astype(np.float64)
    c1, c2 = (0.01 * 255) ** 2, (0.03 * 255) ** 2

    def g(z):
        return cv2.GaussianBlur(z, (11, 11), 1.5)

    mx, my = g(x), g(y)
    vx, vy, cxy = g(x * x) - mx * mx, g(y * y) - my * my, g(x * y) - mx * my
    m = ((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))
    return float(m[5:-5, 5:-5].mean())


def _crops(W: int, H: int) -> list[tuple[int, int, int, int]] | None:
    if W * H <= FULL_FRAME_MAX:
        return None
    return [(int(fx * W), int(fy * H), int(fw * W), int(fh * H)) for fx, fy, fw, fh in CROPS]


def _cut(img: np.ndarray, crops) -> list[np.ndarray]:
    return [img] if crops is None else [img[y:y + h, x:x + w] for x, y, w, h in crops]


def _render(built, spp: int, seed: int, max_depth: int, crop=None, sampler: str | None = None) -> np.ndarray:
    """Mean of ``spp`` samples in calls of at most :data:`PASS_SPP` (distinct seeds); ``sampler``
    (default: the scene's, ``scene_builder.RENDER_SAMPLER``)."""
    from npsim_core.render.render import render_linear

    per = PASS_SPP if crop is None else 8 * PASS_SPP
    acc, done, k = None, 0, 0
    while done < spp:
        n = min(per, spp - done)
        img = render_linear(built, spp=n, seed=seed * 100003 + k, max_depth=max_depth, crop=crop,
                            sampler=sampler) * n
        acc = img if acc is None else acc + img
        done, k = done + n, k + 1
    return acc / spp


def _reference(built, W: int, H: int, crops, ref_spp: int, cache: Path | None, log):
    """Two independent one-bounce renders of ``ref_spp / 2`` samples each on the full mesh (the
    frame, or each crop), with the independent sampler (as before the sampler became a setting).
    Their mean is the reference; a quarter of their mean squared sRGB difference estimates the
    reference's own error variance. Cached in ``cache`` (npz) when given."""
    name = f"ref_{W}x{H}_{ref_spp}spp_{'full' if crops is None else 'crops'}.npz"
    if cache is not None and (cache / name).exists():
        z = np.load(cache / name)
        log(f"  reference from {cache / name}")
        return [z[f"a{i}"] for i in range(len(z.files) // 2)], [z[f"b{i}"] for i in range(len(z.files) // 2)], 0.0
    t0 = time.perf_counter()
    a, b = [], []
    for crop in (crops or [None]):
        a.append(_render(built, ref_spp // 2, 9001, 3, crop, "independent"))
        b.append(_render(built, ref_spp // 2, 9002, 3, crop, "independent"))
        log(f"  reference part {len(a)}: {time.perf_counter() - t0:.0f} s")
    if cache is not None:
        cache.mkdir(parents=True, exist_ok=True)
        np.savez(cache / name, **{f"a{i}": x for i, x in enumerate(a)}, **{f"b{i}": x for i, x in enumerate(b)})
    return a, b, time.perf_counter() - t0


def _errors(img: np.ndarray, crops, ref: list[np.ndarray], ref_var: float) -> tuple[float, float, float]:
    """(RMSE in sRGB levels, the same with the reference's own variance taken out, mean SSIM)."""
    parts = _cut(img, crops)
    mse = float(np.mean(np.concatenate([((_srgb(p) - _srgb(r)) ** 2).ravel() for p, r in zip(parts, ref)])))
    return (float(np.sqrt(mse)), float(np.sqrt(max(mse - ref_var, 0.0))),
            float(np.mean([ssim(p, r) for p, r in zip(parts, ref)])))


#: Denoiser specs of the frontier: the chain's three, OIDN's other presets, and OIDN fed with the
#: mesh rasterised through pixel centres instead of Mitsuba's AOVs, or with no guides at all.
DENOISER_SPECS = ("none", "guided", "oidn", "oidn-balanced", "oidn-high", "oidn-meshguides", "oidn-noguides")


def _denoise_params(spec: str):
    """A spec of :data:`DENOISER_SPECS` -> (denoiser, DenoiseParams, which guides: aov, mesh or none)."""
    from dataclasses import replace

    from npsim_core.chain import ChainParams

    if spec not in DENOISER_SPECS:
        raise SystemExit(f"unknown denoiser {spec!r}; choose from {', '.join(DENOISER_SPECS)}")
    base = ChainParams().denoise
    if spec in ("oidn-meshguides", "oidn-noguides"):
        return "oidn", base, "mesh" if spec == "oidn-meshguides" else "none"
    if spec.startswith("oidn-"):
        return "oidn", replace(base, oidn_quality=spec.split("-", 1)[1]), "aov"
    return spec, base, {"oidn": "aov", "guided": "mesh", "none": "none"}[spec]


def frontier_size(W: int, H: int, spps, denoisers, depths, ref_spp: int, cache: Path | None, log,
                  tolerance: float = 0.01, samplers=("independent",),
                  meshes=("full", "reduced")) -> tuple[list[dict], dict]:
    """The frontier at one size on the synthetic street (see :func:`frontier`); returns rows and facts.
    ``samplers``: Mitsuba samplers of the renders (``scene_builder.SAMPLERS``); ``meshes``: ``full``
    and/or ``reduced``."""
    from npsim_core.chain import Chain, ChainParams
    from npsim_core.chain.stages import light_table, lit_mesh
    from npsim_core.render.denoise import denoise_guides, denoise_night
    from npsim_core.render.render import render_guides, render_linear
    from npsim_core.render.scene_builder import BuildParams, build_scene
    from npsim_core.synthetic import street_scene

    s = street_scene(W, H)
    chain = Chain(s)
    params = ChainParams().with_value("night", "seed", 1)
    res, t_chain, _ = _timed(lambda: chain.compute(params))
    mats = chain.engine.run("materials", params).results["materials"]
    prot = mats.light_classes > 0
    table = light_table(params.night)
    active = chain.activate(params)
    bp = BuildParams(camera_height=s.camera_height, camera_pitch=s.camera_pitch)
    (reduced, what), t_red, _ = _timed(lambda: lit_mesh(res.mesh_result, chain.annotation, tolerance))
    facts = {"size": f"{W}x{H}", "mesh_s": t_chain, "reduce_s": t_red, "faces": {}, "build_s": {}, "guides_s": {},
             "load_start": os.getloadavg()[0]}
    log(f"{W}x{H}: chain {t_chain:.1f} s, full mesh {res.mesh.n_faces} faces, reduced {reduced.n_faces} "
        f"({what}, {t_red:.1f} s)")
    built, aov = {}, {}
    for name, mesh in (("full", lit_mesh(res.mesh_result, chain.annotation)[0]), ("reduced", reduced)):
        if name not in meshes and name != "full":  # the reference is rendered on the full mesh
            facts["faces"][name], facts["build_s"][name] = mesh.n_faces, float("nan")
            continue
        b, t, _ = _timed(lambda: build_scene(mesh, res.intrinsics, mats.materials, table, chain.annotation, active,
                                             bp))
        for d in depths:  # compile the kernels before timing
            render_linear(b, spp=1, max_depth=d)
        g, tg, _ = _timed(lambda: render_guides(b, s.labels, prot))
        built[name], aov[name] = b, g
        facts["faces"][name], facts["build_s"][name], facts["guides_s"][f"aov {name}"] = mesh.n_faces, t, tg
        log(f"  {name}: build {t:.1f} s, AOV guides {tg:.2f} s, variant {b.variant}")
    raster, tg, _ = _timed(lambda: denoise_guides(res.mesh, res.intrinsics, mats.materials.albedo, s.labels, prot))
    facts["guides_s"]["mesh raster"] = tg
    facts["variant"] = built["full"].variant
    crops = _crops(W, H)
    a, b, t_ref = _reference(built["full"], W, H, crops, ref_spp, cache, log)
    ref = [(x + y) / 2 for x, y in zip(a, b)]
    ref_var = float(np.mean(np.concatenate([((_srgb(x) - _srgb(y)) ** 2).ravel() for x, y in zip(a, b)]))) / 4
    facts.update(ref_spp=ref_spp, ref_s=t_ref, ref_rmse=float(np.sqrt(ref_var)), crops=crops)
    log(f"  reference {ref_spp} spp: own RMSE about {np.sqrt(ref_var):.2f} levels")
    rows = []
    for name, depth, sampler, spp in ((n, d, sm, sp) for n in meshes for d in depths for sm in samplers for sp in spps):
        img, t_r, c_r = _timed(lambda: _render(built[name], spp, 17 * spp + depth, depth, sampler=sampler))
        for spec in denoisers:
            dn, dp, kind = _denoise_params(spec)
            g = {"none": None, "mesh": raster, "aov": aov[name]}[kind]
            out, t_d, _ = _timed(lambda: denoise_night(img, g, dp, prot, denoiser=dn))
            rmse, rmse_c, ss = _errors(out, crops, ref, ref_var)
            rows.append({"size": f"{W}x{H}", "mesh": name, "faces": facts["faces"][name], "depth": depth,
                         "sampler": sampler, "spp": spp, "denoiser": spec, "render": t_r, "render_cpu": c_r,
                         "denoise": t_d, "total": t_r + t_d,
                         "rmse": rmse, "rmse_c": rmse_c, "ssim": ss, "load": os.getloadavg()[0]})
            log(f"  {name} depth {depth} {sampler} {spp:3d} spp {spec:13s} render {t_r:6.1f} s "
                f"({c_r:.1f} CPU s) + {t_d:5.2f} s  "
                f"RMSE {rmse:6.2f} ({rmse_c:6.2f})  SSIM {ss:.3f}  load {rows[-1]['load']:.1f}")
    facts["load_end"] = os.getloadavg()[0]
    return rows, facts


def format_frontier(rows: list[dict], facts: list[dict]) -> str:
    out = []
    for f in facts:
        out.append(f"{f['size']} ({f['variant']}): full mesh {f['faces']['full']} faces, reduced "
                   f"{f['faces']['reduced']} (reduction {f['reduce_s']:.1f} s); scene build "
                   f"{f['build_s']['full']:.1f} s full / {f['build_s']['reduced']:.1f} s reduced; guides "
                   + ", ".join(f"{k} {v:.2f} s" for k, v in f["guides_s"].items())
                   + f"; reference {f['ref_spp']} spp on the full mesh, one bounce"
                   + ("" if f["crops"] is None else f", on the crops {f['crops']}")
                   + f" (its own RMSE about {f['ref_rmse']:.2f} levels); load {f['load_start']:.1f} at the "
                   f"start, {f['load_end']:.1f} at the end")
    out += ["", "| size | mesh | depth | sampler | spp | denoiser | render s | render CPU s | denoise s | total s | RMSE | "
                "RMSE* | SSIM | load |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['size']} | {r['mesh']} | {r['depth']} | {r.get('sampler', 'independent')} | {r['spp']} | "
                   f"{r['denoiser']} | {r['render']:.2f} | {r.get('render_cpu', float('nan')):.1f} | "
                   f"{r['denoise']:.2f} | {r['total']:.2f} | {r['rmse']:.2f} | {r['rmse_c']:.2f} | {r['ssim']:.3f} | "
                   f"{r['load']:.1f} |")
    out += ["", "RMSE in 8-bit sRGB levels (exposure 0, no camera noise); RMSE* the same with the reference's own "
                "noise variance subtracted; total = render + denoise (scene build and guides are per scene, above)."]
    return "\n".join(out)


def format_pivot(rows: list[dict]) -> str:
    """The frontier as one line per (size, mesh, path depth, sampler, spp): the render time (and its
    CPU seconds), then RMSE / SSIM of each denoiser (with its denoising time when not negligible)."""
    specs = list(dict.fromkeys(r["denoiser"] for r in rows))
    out = ["| size | mesh | depth | sampler | spp | render s (CPU s) | " + " | ".join(f"{d}: RMSE / SSIM" for d in specs)
           + " | load |", "|---" * (7 + len(specs)) + "|"]

    def key(r):
        return r["size"], r["mesh"], r["depth"], r.get("sampler", "independent"), r["spp"]

    for k in dict.fromkeys(key(r) for r in rows):
        sub = {r["denoiser"]: r for r in rows if key(r) == k}
        first = next(iter(sub.values()))
        cells = []
        for d in specs:
            r = sub.get(d)
            cells.append("-" if r is None else f"{r['rmse']:.1f} / {r['ssim']:.3f}"
                         + (f" (+{r['denoise']:.1f} s)" if r["denoise"] >= 0.05 else ""))
        cpu = first.get("render_cpu")
        out.append(f"| {k[0]} | {k[1]} | {'one bounce' if k[2] == 3 else 'direct' if k[2] == 2 else k[2]} | {k[3]} | "
                   f"{k[4]} | {first['render']:.1f}" + ("" if cpu is None else f" ({cpu:.1f})") + " | "
                   + " | ".join(cells) + f" | {first['load']:.1f} |")
    return "\n".join(out)


def plot_frontier(rows: list[dict], facts: list[dict], path: str, baseline=("full", 3, 64, "guided"),
                  chosen=("full", 3, 16, "oidn")) -> None:
    """Error against time, one panel per size: colour = denoiser, marker = mesh, line = path depth;
    the settings before session 3 (``baseline``) as a dotted line, the chosen defaults as a star."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sizes = list(dict.fromkeys(r["size"] for r in rows))
    fig, axes = plt.subplots(1, len(sizes), figsize=(6.5 * len(sizes), 6.0), squeeze=False)
    colours = {"none": "tab:grey", "guided": "tab:blue", "oidn": "tab:red", "oidn-balanced": "tab:orange",
               "oidn-high": "tab:purple", "oidn-meshguides": "tab:green", "oidn-noguides": "tab:brown"}
    for ax, size, f in zip(axes[0], sizes, facts):
        sub = [r for r in rows if r["size"] == size]
        for key in dict.fromkeys((r["denoiser"], r["mesh"], r["depth"]) for r in sub):
            pts = sorted((r for r in sub if (r["denoiser"], r["mesh"], r["depth"]) == key), key=lambda r: r["spp"])
            ax.plot([r["total"] for r in pts], [r["rmse"] for r in pts], marker="o" if key[1] == "full" else "s",
                    linestyle="-" if key[2] == 3 else "--", color=colours.get(key[0], "k"),
                    mfc="none" if key[1] == "reduced" else None,
                    label=f"{key[0]}, {key[1]} mesh, {'one bounce' if key[2] == 3 else 'direct'}")
            for r in pts:
                if key == ("oidn", "full", 3):
                    ax.annotate(f"{r['spp']} spp", (r["total"], r["rmse"]), textcoords="offset points",
                                xytext=(3, -10), fontsize=7)
        base = [r for r in sub if (r["mesh"], r["depth"], r["spp"], r["denoiser"]) == baseline]
        if base:
            ax.axhline(base[0]["rmse"], color="tab:blue", linestyle=":", linewidth=1)
            ax.text(0.01, base[0]["rmse"], " before: 64 spp, full mesh, one bounce, guided filter", fontsize=7,
                    color="tab:blue", va="bottom", transform=ax.get_yaxis_transform())
        star = [r for r in sub if (r["mesh"], r["depth"], r["spp"], r["denoiser"]) == chosen]
        if star:
            ax.plot([star[0]["total"]], [star[0]["rmse"]], marker="*", markersize=16, color="gold", mec="k",
                    linestyle="none", zorder=5, label="chosen default")
        ax.set_xscale("log")
        ax.set_xlabel("render + denoise, s (log)")
        ax.set_ylabel("RMSE, 8-bit sRGB levels" + ("" if f["crops"] is None else " (3 fixed crops)"))
        ax.set_title(f"{size}, {f['variant']}, load {f['load_start']:.1f}-{f['load_end']:.1f}", fontsize=10)
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0][0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="lower center", ncol=4, fontsize=7, frameon=False)
    fig.suptitle("Night renders: error against a 4096-spp reference vs render + denoise time "
                 "(labels: spp of OIDN, full mesh, one bounce)", fontsize=10)
    fig.tight_layout(rect=(0, 0.16, 1, 1))
    Path(path).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def frontier(argv_sizes: str, spps, denoisers, depths, ref_spp: int, cache: str | None, out: str | None,
             plot: str | None, samplers=("independent",), meshes=("full", "reduced")) -> int:
    """RMSE and SSIM against a high-spp one-bounce reference on the full mesh, over spp x denoiser x
    mesh (full, error-bounded reduction) x path depth (direct light, one bounce) (docs/relight.md)."""
    log = lambda m: print(m, file=sys.stderr, flush=True)  # noqa: E731
    rows, facts = [], []
    for size in argv_sizes.split(","):
        W, H = (int(v) for v in size.lower().split("x"))
        r, f = frontier_size(W, H, spps, denoisers, depths, ref_spp, Path(cache) if cache else None, log,
                             samplers=samplers, meshes=meshes)
        rows += r
        facts.append(f)
        if plot:
            plot_frontier(rows, facts, plot)
    head = f"Night speed-error frontier ({time.strftime('%Y-%m-%d %H:%M')}, {os.cpu_count()} cores)"
    text = head + "\n\n" + format_frontier(rows, facts) + "\n\n" + format_pivot(rows)
    print(text)
    if out:
        import json

        Path(out).write_text(text + "\n")
        Path(out).with_suffix(".json").write_text(json.dumps({"rows": rows, "facts": facts}, indent=1))
    return 0


def crops_figure(path: str, size: tuple[int, int] = (2048, 1024), cache: str | None = None) -> int:
    """The frontier's three crops side by side: 16 spp raw, before (64 spp + guided filter), now
    (16 spp + OIDN, the defaults) and the 4096-spp reference (from ``cache`` when there, else
    1024 spp) -- exposure 0, no camera noise, 2x nearest zoom."""
    import cv2

    from npsim_core.chain import Chain, ChainParams
    from npsim_core.render.denoise import denoise_night
    from npsim_core.synthetic import street_scene

    W, H = size
    s = street_scene(W, H)
    chain = Chain(s)
    params = ChainParams().with_value("night", "seed", 1)
    res = chain.compute(params)
    built, aov, mats, _ = chain.night_inputs(params)
    guided_guides = chain.night_inputs(params.with_value("night", "denoiser", "guided"))[1]
    built.apply_lights(chain.activate(params))
    prot = mats.light_classes > 0
    crops = _crops(W, H) or [(0, 0, W, H)]
    raw16, raw64 = _render(built, 16, 17 * 16 + 3, 3), _render(built, 64, 17 * 64 + 3, 3)
    now = denoise_night(raw16, aov, params.denoise, prot, denoiser="oidn")
    before = denoise_night(raw64, guided_guides, params.denoise, prot, denoiser="guided")
    name = Path(cache or ".") / f"ref_{W}x{H}_4096spp_crops.npz"
    if cache and name.exists():
        z = np.load(name)
        ref = [(z[f"a{i}"] + z[f"b{i}"]) / 2 for i in range(len(crops))]
    else:
        ref = [_render(built, 1024, 9001, 3, c) for c in crops]
    cols = [("16 spp, no denoiser", _cut(raw16, crops)), ("before: 64 spp + guided", _cut(before, crops)),
            ("now: 16 spp + OIDN", _cut(now, crops)), ("reference 4096 spp", ref)]
    tiles = []
    for r in range(len(crops)):
        row = []
        for title, imgs in cols:
            t = cv2.resize(_srgb(imgs[r]).astype(np.uint8), None, fx=2, fy=2, interpolation=cv2.INTER_NEAREST)
            if r == 0:
                (tw, th), _ = cv2.getTextSize(title, cv2.FONT_HERSHEY_SIMPLEX, 0.6, 1)
                cv2.rectangle(t, (0, 0), (tw + 12, th + 14), (0, 0, 0), -1)
                cv2.putText(t, title, (6, th + 6), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (255, 255, 255), 1, cv2.LINE_AA)
            row += [t, np.full((t.shape[0], 4, 3), 255, np.uint8)]
        tiles += [np.concatenate(row[:-1], axis=1)]
        tiles += [np.full((4, tiles[-1].shape[1], 3), 255, np.uint8)]
    from npsim_core.io import write_image

    write_image(path, np.concatenate(tiles[:-1], axis=0))
    print(f"wrote {path}", file=sys.stderr)
    return 0


def replot(json_path: str, plot: str) -> int:
    """Redraw the frontier plot (and print the table) from the JSON a ``--frontier --out FILE.md`` run
    wrote next to FILE.md."""
    import json

    doc = json.loads(Path(json_path).read_text())
    plot_frontier(doc["rows"], doc["facts"], plot)
    print(format_pivot(doc["rows"]))
    return 0


def defaults(size: tuple[int, int] = (2048, 1024), preview: tuple[int, int] = (512, 256), legacy: bool = False,
             cache: str | None = None) -> int:
    """Time the chain's defaults end to end on the synthetic street: a final night at ``size`` (scene
    build, guides, render, denoise, camera; the mesh before it is not counted) and the app's preview
    of a ``preview``-sized frame at preview scale 1 (first denoised frame, cold after the mesh and
    warm after a new seed). ``legacy`` also times the settings before session 3 (64 spp, full
    mesh, guided filter). With ``cache`` and a cached reference of that size, errors are printed."""
    from npsim_core.chain import Chain, ChainParams
    from npsim_core.render.denoise import denoise_night
    from npsim_core.synthetic import street_scene

    def report(label, chain, res, params):
        load0 = os.getloadavg()[0]
        frame = chain.night_final(res, params, seed=1)
        second = chain.night_final(res, params, seed=2)
        t = frame.timings
        print(f"| {label} | {frame.faces} | {params.night.final_spp} | {params.night.final_max_depth} | "
              f"{frame.denoiser} | {t['night_inputs']:.1f} | {t['render']:.1f} | {t['denoise']:.2f} | "
              f"{t['camera']:.2f} | {frame.elapsed:.1f} | {second.elapsed:.1f} | {load0:.1f} |", flush=True)
        W, H = size
        name = Path(cache or ".") / f"ref_{W}x{H}_4096spp_{'full' if _crops(W, H) is None else 'crops'}.npz"
        if cache and name.exists():
            z = np.load(name)
            n = len(z.files) // 2
            a, b = [z[f"a{i}"] for i in range(n)], [z[f"b{i}"] for i in range(n)]
            ref = [(x + y) / 2 for x, y in zip(a, b)]
            var = float(np.mean(np.concatenate([((_srgb(x) - _srgb(y)) ** 2).ravel() for x, y in zip(a, b)]))) / 4
            _, guides, mats, _ = chain.night_inputs(params)
            clean = denoise_night(frame.linear, guides, params.denoise, mats.light_classes > 0,
                                  denoiser=frame.denoiser)
            e = _errors(clean, _crops(W, H), ref, var)
            print(f"|   error of that night | RMSE {e[0]:.2f} (RMSE* {e[1]:.2f}), SSIM {e[2]:.3f} |", flush=True)

    s = street_scene(*size)
    chain = Chain(s)
    params = ChainParams()
    res, t, _ = _timed(lambda: chain.compute(params))
    print(f"final night at {size[0]}x{size[1]} (synthetic street; mesh {t:.1f} s before, not counted)")
    print("| settings | faces rendered | spp | depth | denoiser | build + guides s | render s | denoise s | camera s "
          "| night s | next night s | load |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    report("defaults", chain, res, params)
    if legacy:
        old = params.with_sets(["mesh.render_tolerance=0", "night.denoiser=guided", "night.final_spp=64",
                                "night.final_max_depth=3"])
        report("before (64 spp, full mesh, guided)", chain, res, old)
    s = street_scene(*preview)
    chain = Chain(s)
    params = ChainParams().with_value("night", "preview_scale", 1.0)
    res = chain.compute(params)
    print(f"\napp preview of a {preview[0]}x{preview[1]} frame at scale 1 (film {preview[0]}x{preview[1]})")
    print("| run | first frame spp | first denoised frame s | last frame spp | last frame s | load |")
    print("|---|---|---|---|---|---|")
    for label, p in (("cold (scene build + guides)", params), ("warm (new seed)", params.with_value("night", "seed", 7)),
                     ("warm (another seed)", params.with_value("night", "seed", 8))):
        load0 = os.getloadavg()[0]
        frames = []
        t0 = time.perf_counter()
        for f in chain.night_preview(res, p):
            frames.append((f.spp, time.perf_counter() - t0))
        print(f"| {label} | {frames[0][0]} | {frames[0][1]:.2f} | {frames[-1][0]} | {frames[-1][1]:.2f} | "
              f"{load0:.1f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
