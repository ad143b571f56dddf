"""``npsim run`` (one frame), ``npsim batch`` (a dataset) and ``npsim sweep`` (λ grid): the whole
chain -- depth refinement, mesh, nights -- with every output written to disk."""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path

import numpy as np

from npsim_core.chain import (Chain, ChainParams, check_output_folder, export_frame, frame_errors, iter_frames,
                              load_frame, verify_frame)
from npsim_core.errors import NpsimInputError

from ..options import add_param_options, log, params_from_args, stage_logger


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
    b.add_argument("--skip-existing", action="store_true", help="skip frames whose export manifest exists")
    add_param_options(b)
    b.set_defaults(func=run_batch)

    s = sub.add_parser("sweep", help="grid search over λ1, λ2, λ3 (scored against ground truth when present)")
    s.add_argument("scene", help="scene folder (e.g. from 'npsim sample')")
    s.add_argument("--lambda1", default="1", help="comma-separated values (default 1)")
    s.add_argument("--lambda2", default="0.2,1,5,25", help="comma-separated values")
    s.add_argument("--lambda3", default="0.2,1,5", help="comma-separated values")
    s.add_argument("-o", "--out", help="write the table as CSV here")
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
    chain = Chain(scene)
    t0 = time.perf_counter()

    on_stage = stage_logger(cmd, scene.name)

    log(cmd, f"{scene.name}: {scene.width}x{scene.height}")
    if scene.lights is None:
        log(cmd, f"{scene.name}: no light annotation, so only the ego headlights and the night sky light the "
                 "nights (label lights with 'npsim annotate')")
    res = chain.compute(params, progress=on_stage)
    log(cmd, f"{scene.name}: depth from {res.depth_source}; stages "
        + ", ".join(f"{k} {v:.2f} s" for k, v in res.timings.items()) + f"; mesh {res.mesh.n_faces} faces")
    if res.refine is not None and res.refine.diverged:
        log(cmd, f"{scene.name}: WARNING: the refinement diverged: {res.refine.message}")

    def progress(frac: float, text: str) -> None:
        log(cmd, f"{scene.name}: {100 * frac:3.0f}% {text}")

    kw = {"kinds": tuple(kinds)} if kinds else {}
    written = export_frame(chain, params, out, nights=nights, progress=progress, inputs=inputs, **kw)
    log(cmd, f"{scene.name}: total {time.perf_counter() - t0:.1f} s")
    errors = frame_errors(chain, res, params.depth.stereo_max_m)
    log(cmd, f"{scene.name}: {_summary(errors)}")
    if scores is not None and errors:
        scores.append(errors)
    return written


def run_one(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    check_output_folder(args.out)
    scene = load_frame(args.scene, hfov_deg=args.fov, trainids=args.trainids)
    written = process_frame(scene, params, Path(args.out), args.nights, "run", inputs={"scene": str(args.scene)})
    print(f"wrote {len(written)} files to {args.out}")
    return 0


def run_sample_headless(out: str, size: tuple[int, int]) -> int:
    """The main job without a display: sample scene -> refined depth, mesh, nights, all on disk."""
    from npsim_core.synthetic import street_scene

    scene = street_scene(*size)
    out_p = Path(out)
    written = process_frame(scene, ChainParams(), out_p, 3, "start", inputs={"scene": "built-in sample"})
    print(f"npsim start: wrote {len(written)} files to {out_p.resolve()}")
    for p in written:
        if p.name.endswith(("_night_0.png", "_mesh.glb", "_depth_refined_vis.png", "_export.json")):
            print(f"  {p}")
    return 0


def run_batch(args: argparse.Namespace) -> int:
    params = params_from_args(args)
    if args.limit is not None and args.limit < 1:
        raise NpsimInputError(f"--limit must be >= 1, got {args.limit}")
    check_output_folder(args.out)
    sources = iter_frames(args.dataset, trainids=args.trainids, hfov_deg=args.fov)
    if args.limit is not None:
        sources = sources[: args.limit]
    failed, skipped, done, scores = [], 0, [], []
    t0 = time.perf_counter()
    for i, src in enumerate(sources):
        out = Path(args.out) / src.name
        head = f"[{i + 1}/{len(sources)}] {src.name}"
        if args.skip_existing:
            why = verify_frame(out) if out.is_dir() else "no output yet"
            if why is None:
                log("batch", f"{head}: complete (manifest and checksums verified), skipped")
                skipped += 1
                continue
            if why != "no output yet":
                log("batch", f"{head}: previous output incomplete ({why}), recomputing")
        eta = ""
        if done:
            left = (len(sources) - i) * sum(done) / len(done)
            eta = f", about {left / 60:.1f} min left"
        log("batch", f"{head}{eta}")
        t1 = time.perf_counter()
        try:
            process_frame(src.load(), params, out, args.nights, "batch", inputs={"frame": str(src.path)},
                          scores=scores)
            done.append(time.perf_counter() - t1)
        except (NpsimInputError, OSError) as exc:  # one bad frame must not stop a dataset run
            failed.append((src.name, str(exc)))
            log("batch", f"{src.name}: FAILED: {exc}")
        except Exception as exc:  # noqa: BLE001 -- an unforeseen failure is reported, the batch goes on
            failed.append((src.name, f"{type(exc).__name__}: {exc}"))
            log("batch", f"{src.name}: FAILED with an internal error ({type(exc).__name__}: {exc}); "
                         "please report it with this frame")
    ok = len(sources) - len(failed) - skipped
    log("batch", f"{ok} frames done, {skipped} skipped as complete, {len(failed)} failed, of {len(sources)}, "
                 f"in {time.perf_counter() - t0:.1f} s")
    for line in dataset_summary(scores):
        log("batch", line)
    for name, err in failed:
        print(f"failed: {name}: {err}", file=sys.stderr)
    return 1 if failed else 0


def _values(text: str, name: str) -> list[float]:
    try:
        vals = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise NpsimInputError(f"--{name} {text!r}: give comma-separated numbers") from None
    if not vals or not all(0 <= v < float("inf") for v in vals):
        raise NpsimInputError(f"--{name}: need at least one value, all finite and >= 0")
    return vals


def run_sweep(args: argparse.Namespace) -> int:
    from npsim_core.io import atomic_write_text

    params = params_from_args(args)
    if args.out:
        out = Path(args.out)
        if out.is_dir():
            raise NpsimInputError(f"-o {out}: is a folder; give the CSV file to write, e.g. {out / 'sweep.csv'}")
        check_output_folder(out.parent if str(out.parent) else ".")
    grid = list(itertools.product(_values(args.lambda1, "lambda1"), _values(args.lambda2, "lambda2"),
                                  _values(args.lambda3, "lambda3")))
    scene = load_frame(args.scene, hfov_deg=args.fov)
    chain = Chain(scene)
    rows = []
    header = "l1,l2,l3,final_loss,seconds,abs_rel,rmse_m,normal_rmse_deg"
    print(header)
    for l1, l2, l3 in grid:
        res = chain.compute(params.with_lambdas(l1, l2, l3), until="refine")
        r = frame_errors(chain, res, params.depth.stereo_max_m).get("refined", {})
        row = (l1, l2, l3, res.refine.final_loss, res.timings["refine"], r.get("abs_rel", float("nan")),
               r.get("rmse_m", float("nan")), r.get("normal_rmse_deg", float("nan")))
        rows.append(row)
        print(",".join(f"{x:.6g}" for x in row), flush=True)
    scored = [r for r in rows if r[7] == r[7]]
    if scored:
        best = min(scored, key=lambda r: r[7])
        log("sweep", f"lowest normal RMSE: λ = ({best[0]:g}, {best[1]:g}, {best[2]:g}) -> {best[7]:.2f} deg, "
                     f"AbsRel {best[5]:.4f}")
    if args.out:
        atomic_write_text(args.out, header + "\n" + "\n".join(",".join(f"{x:.6g}" for x in r) for r in rows) + "\n")
    return 0
