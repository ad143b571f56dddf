"""``npsim run`` (one frame), ``npsim batch`` (a dataset) and ``npsim sweep`` (λ grid): the whole
chain -- depth refinement, mesh, nights -- with every output written to disk."""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

from npsim_core.errors import NpsimInputError

from ..options import add_param_options, clean_leftovers, log, log_warnings, params_from_args, stage_logger


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the whole chain on one frame and write every output")
    p.add_argument("scene", help="scene folder, project folder, or a dataset image with its labels")
    p.add_argument("-o", "--out", required=True, help="output folder")
    p.add_argument("--trainids", action="store_true", help="a dataset image's label file holds trainIds")
    add_param_options(p)
    p.set_defaults(func=run_one)

    b = sub.add_parser("batch", help="run the whole chain on every frame of a dataset folder")
    b.add_argument("dataset", help="Cityscapes / ACDC / plain folder (images + *_labelIds.png) or scene folders")
    b.add_argument("-o", "--out", required=True, help="output folder (one sub-folder per frame)")
    b.add_argument("--limit", type=int, default=None, help="at most this many frames")
    b.add_argument("--trainids", action="store_true", help="label files hold trainIds")
    b.add_argument("--skip-existing", action="store_true",
                   help="(the default) skip frames whose outputs are complete: manifest, files and checksums verified, "
                        "same parameters")
    b.add_argument("--force", action="store_true", help="recompute every frame, even complete ones")
    b.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default: one per two cores, at most 4)")
    b.add_argument("--ray", metavar="ADDRESS", default=None,
                   help="run the frames as Ray tasks: 'local' starts a local Ray instance, else the address of a "
                        "running cluster (its workers must see the dataset and output paths)")
    b.add_argument("--layout", choices=("npsim", "cityscapes"), default="npsim",
                   help="cityscapes: also copy nights and labels into OUT/cityscapes/{leftImg8bit,gtFine}/<split>/<city>")
    add_param_options(b)
    b.set_defaults(func=run_batch)

    s = sub.add_parser("sweep", help="grid search over λ1, λ2, λ3 (scored against ground truth when present)")
    s.add_argument("scene", help="scene folder (e.g. from 'npsim sample')")
    grid = "0.001,0.01,0.1,1,10,100,1000"
    s.add_argument("--lambda1", default="1", help="comma-separated values (default 1)")
    s.add_argument("--lambda2", default=grid, help=f"comma-separated values (default the thesis's appendix B: {grid})")
    s.add_argument("--lambda3", default=grid, help="comma-separated values (default as --lambda2)")
    s.add_argument("-o", "--out", help="folder for contact_sheet.png, sweep.csv and sweep.json (or a .csv file for "
                                       "the table alone)")
    s.add_argument("--workers", type=int, default=None,
                   help="local worker processes (default: one per two cores, at most 4)")
    add_param_options(s, nights=None)
    s.set_defaults(func=run_sweep)


def _summary(errors: dict) -> str:
    """One line: the refined depth's scores against the frame's reference (input -> refined)."""
    if not errors:
        return "no reference (no ground truth, no stereo): not scored"
    i, r = errors["input"], errors["refined"]
    cls = ", ".join(f"{k} {v:.3f}" for k, v in r["classes"].items() if v == v)
    line = (f"vs {errors['reference']}: AbsRel {i['abs_rel']:.4f} -> {r['abs_rel']:.4f}, δ1 {r['delta1']:.3f}, "
            f"RMSElog {r['rmse_log']:.3f}; per class {cls}")
    if "normal_rmse_deg" in r:
        line += f"; normal RMSE {i['normal_rmse_deg']:.1f} -> {r['normal_rmse_deg']:.1f} deg"
    return line


def dataset_summary(scores: list[dict]) -> list[str]:
    """Mean scores over the frames, per reference kind (lines for the log)."""
    import numpy as np

    lines = []
    for kind in sorted({e["reference"] for e in scores}):
        rows = [e for e in scores if e["reference"] == kind]
        mean = lambda key, stage="refined": float(np.nanmean([e[stage][key] for e in rows]))  # noqa: E731
        cls = {c: float(np.nanmean([e["refined"]["classes"][c] for e in rows])) for c in rows[0]["refined"]["classes"]}
        lines.append(f"{len(rows)} frames vs {kind}: mean AbsRel {mean('abs_rel', 'input'):.4f} -> "
                     f"{mean('abs_rel'):.4f}, δ1 {mean('delta1'):.3f}, RMSElog {mean('rmse_log'):.3f}; per class "
                     + ", ".join(f"{c} {v:.3f}" for c, v in cls.items() if v == v))
    return lines


def process_frame(scene, params: ChainParams, out: Path, nights: int, cmd: str, *, kinds=None,
                  inputs: dict | None = None, scores: list | None = None) -> list[Path]:
    """Run the chain on ``scene`` and export to ``out`` (progress on stderr); its scores are
    appended to ``scores`` when given."""
    from npsim_core.chain import Chain, export_frame, frame_errors

    chain = Chain(scene)
    t0 = time.perf_counter()

    on_stage = stage_logger(cmd, scene.name)

    log(cmd, f"{scene.name}: {scene.width}x{scene.height}")
    log_warnings(cmd, scene)
    res = chain.compute(params, progress=on_stage)
    log(cmd, f"{scene.name}: lights: {res.lights.note}" if res.lights is not None else f"{scene.name}: no lights")
    log(cmd, f"{scene.name}: depth from {res.depth_source}; stages "
        + ", ".join(f"{k} {v:.2f} s" for k, v in res.timings.items()) + f"; mesh {res.mesh.n_faces} faces")
    if res.refine is not None and res.refine.diverged:
        log(cmd, f"{scene.name}: WARNING: the refinement diverged: {res.refine.message}")

    def progress(frac: float, text: str) -> None:
        log(cmd, f"{scene.name}: {100 * frac:3.0f}% {text}")

    kw = {"kinds": tuple(kinds)} if kinds else {}
    written = export_frame(chain, params, out, nights=nights, progress=progress, inputs=inputs, **kw)
    log(cmd, f"{scene.name}: total {time.perf_counter() - t0:.1f} s")
    errors = frame_errors(chain, res, params.depth.stereo_max_m, params.depth.stereo_holdout)
    log(cmd, f"{scene.name}: {_summary(errors)}")
    if scores is not None and errors:
        scores.append(errors)
    return written


def run_one(args: argparse.Namespace) -> int:
    from npsim_core.chain import check_output_folder, load_frame

    params = params_from_args(args)
    check_output_folder(args.out)
    clean_leftovers("run", args.out)
    scene = load_frame(args.scene, hfov_deg=args.fov, trainids=args.trainids)
    written = process_frame(scene, params, Path(args.out), args.nights, "run", inputs={"scene": str(args.scene)})
    print(f"wrote {len(written)} files to {args.out}")
    return 0


def run_sample_headless(out: str, size: tuple[int, int]) -> int:
    """The main job without a display: sample scene -> refined depth, mesh, nights, all on disk."""
    from npsim_core.chain import ChainParams
    from npsim_core.synthetic import street_scene

    scene = street_scene(*size)
    out_p = Path(out)
    clean_leftovers("start", out_p)
    written = process_frame(scene, ChainParams(), out_p, 3, "start", inputs={"scene": "built-in sample"})
    print(f"npsim start: wrote {len(written)} files to {out_p.resolve()}")
    for p in written:
        if p.name.endswith(("_night_0.png", "_mesh.glb", "_depth_refined_vis.png", "_export.json")):
            print(f"  {p}")
    return 0


def run_batch(args: argparse.Namespace) -> int:
    from npsim_core.chain import check_output_folder, iter_frames
    from npsim_core.chain.batch import run_batch as run_frames

    params = params_from_args(args)
    if params.lights.source == "file":
        raise NpsimInputError(f"--lights {params.lights.file}: one annotation file cannot light every frame of a "
                              "batch; save each frame's annotation beside its image ('npsim annotate DATASET') and "
                              "use --lights auto or annotation")
    if args.limit is not None and args.limit < 1:
        raise NpsimInputError(f"--limit must be >= 1, got {args.limit}")
    if args.workers is not None and args.workers < 1:
        raise NpsimInputError(f"--workers must be >= 1, got {args.workers}")
    check_output_folder(args.out)
    clean_leftovers("batch", args.out, depth=1)
    sources = iter_frames(args.dataset, trainids=args.trainids, hfov_deg=args.fov)
    if args.limit is not None:
        sources = sources[: args.limit]
    workers = args.workers or default_workers()
    where = f"Ray ({args.ray})" if args.ray else f"{workers} local worker{'s' if workers > 1 else ''}"
    log("batch", f"{len(sources)} frames from {args.dataset} -> {args.out}, {where}")
    res = run_frames(sources, params, args.out, nights=args.nights, workers=workers, ray_address=args.ray,
                     skip_existing=not args.force, layout=args.layout, inputs={"dataset": str(args.dataset)},
                     log=lambda m: log("batch", m))
    failed = [o for o in res.outcomes if o.status == "failed"]
    log("batch", f"{res.count('done')} frames done, {res.count('skipped')} skipped as complete, {len(failed)} failed, "
                 f"of {len(sources)}, in {res.seconds:.1f} s; manifest {res.manifest}")
    for line in dataset_summary([o.scores for o in res.outcomes if o.status == "done" and o.scores]):
        log("batch", line)
    for o in failed:
        print(f"failed: {o.name}: {o.error}", file=sys.stderr)
    return 1 if failed else 0


def default_workers() -> int:
    """Local workers by default: one per two cores (each frame's stages use several threads), at
    least 1, at most 4 (memory: about 3 GB a worker at 2048x1024)."""
    return max(1, min(4, (os.cpu_count() or 1) // 2))


def run_sweep(args: argparse.Namespace) -> int:
    from npsim_core.chain import check_output_folder, load_frame
    from npsim_core.chain.sweep import parse_grid, run_sweep as sweep, write_sweep

    params = params_from_args(args)
    grid = parse_grid(args.lambda1, args.lambda2, args.lambda3)
    if args.workers is not None and args.workers < 1:
        raise NpsimInputError(f"--workers must be >= 1, got {args.workers}")
    out = Path(args.out) if args.out else None
    csv_only = out is not None and out.suffix.lower() == ".csv"
    if out is not None:
        if csv_only and out.is_dir():
            raise NpsimInputError(f"-o {out}: is a folder; give a folder for the sweep, or a .csv file")
        check_output_folder(out.parent if csv_only else out)
    load_frame(args.scene, hfov_deg=args.fov)  # a bad frame is reported before any worker starts
    workers = args.workers or default_workers()
    log("sweep", f"{len(grid)} λ cells on {args.scene}, {workers} worker{'s' if workers > 1 else ''}")
    cells = sweep(args.scene, params, grid, workers=workers, hfov_deg=args.fov, log=lambda m: log("sweep", m))
    header = "l1,l2,l3,final_loss,seconds,abs_rel,rmse_m,normal_rmse_deg"
    print(header)
    rows = []
    for c in cells:
        r = c.row()
        rows.append((r["l1"], r["l2"], r["l3"], r["loss"], r["seconds"], r["abs_rel"], r["rmse_m"], r["normal_rmse_deg"]))
        print(",".join(f"{x:.6g}" for x in rows[-1]), flush=True)
    scored = [r for r in rows if r[7] == r[7]]
    if scored:
        best = min(scored, key=lambda r: r[7])
        log("sweep", f"lowest normal RMSE: λ = ({best[0]:g}, {best[1]:g}, {best[2]:g}) -> {best[7]:.2f} deg, "
                     f"AbsRel {best[5]:.4f} (vs {cells[0].scores.get('reference', '?')})")
    if csv_only:
        from npsim_core.io import atomic_write_text

        atomic_write_text(out, header + "\n" + "\n".join(",".join(f"{x:.6g}" for x in r) for r in rows) + "\n")
    elif out is not None:
        for p in write_sweep(cells, out, frame=str(args.scene), params=params):
            log("sweep", f"wrote {p}")
    return 0
