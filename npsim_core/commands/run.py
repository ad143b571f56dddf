"""``npsim run`` (one scene), ``npsim batch`` (a dataset) and ``npsim sweep`` (λ grid): the whole
chain -- depth refinement, mesh, nights -- with every output written to disk."""

from __future__ import annotations

import argparse
import itertools
import sys
import time
from pathlib import Path



def _log(cmd: str, msg: str) -> None:
    print(f"[npsim {cmd}] {msg}", file=sys.stderr, flush=True)


def add_param_options(p: argparse.ArgumentParser) -> None:
    p.add_argument("--params", help="JSON file of parameters (as in a project.json 'params' or an export manifest)")
    p.add_argument("--preset", choices=["appendix_b", "section_3_4_3"], help="λ preset (default appendix_b)")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                   help="override one parameter, e.g. --set refine.optimizer=adam_faithful --set filter.sigma_s=8")
    p.add_argument("--nights", type=int, default=1, help="number of night images (default 1)")
    p.add_argument("--seed", type=int, default=None, help="seed of the first night")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel of the nights (default 64)")
    p.add_argument("--fov", type=float, default=None, help="horizontal field of view in degrees (overrides intrinsics)")


def params_from_args(args: argparse.Namespace):
    from ..errors import NpsimInputError
    from ..io import read_json
    from ..workflow import WorkflowParams

    params = WorkflowParams()
    if args.params:
        doc = read_json(args.params)
        params = WorkflowParams.from_json(doc.get("params", doc), args.params)
    if args.preset:
        params = params.with_preset(args.preset)
    for item in args.set:
        if "=" not in item or "." not in item.split("=", 1)[0]:
            raise NpsimInputError(f"--set {item!r}: use SECTION.FIELD=VALUE, e.g. refine.steps=200")
        key, raw = item.split("=", 1)
        section, field = key.split(".", 1)
        params = params.with_value(section, field, _parse_value(raw))
    if args.seed is not None:
        params = params.with_value("night", "seed", int(args.seed))
    if args.spp is not None:
        if args.spp < 1:
            raise NpsimInputError(f"--spp must be >= 1, got {args.spp}")
        params = params.with_value("night", "final_spp", int(args.spp))
    if args.fov is not None:
        params = params.with_value("camera", "hfov_deg", float(args.fov))
    if args.nights < 0:
        raise NpsimInputError(f"--nights must be >= 0, got {args.nights}")
    return params


def _parse_value(raw: str):
    low = raw.lower()
    if low in ("true", "false"):
        return low == "true"
    if low in ("null", "none"):
        return None
    for cast in (int, float):
        try:
            return cast(raw)
        except ValueError:
            pass
    return raw


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("run", help="run the whole chain on one scene and write every output")
    p.add_argument("scene", help="scene folder, project folder, or a dataset image with its labels")
    p.add_argument("-o", "--out", required=True, help="output folder")
    add_param_options(p)
    p.set_defaults(func=run_one)

    b = sub.add_parser("batch", help="run the whole chain on every scene of a dataset folder")
    b.add_argument("dataset", help="Cityscapes / ACDC / plain folder (images + *_labelIds.png) or scene folders")
    b.add_argument("-o", "--out", required=True, help="output folder (one sub-folder per scene)")
    b.add_argument("--limit", type=int, default=None, help="at most this many scenes")
    b.add_argument("--trainids", action="store_true", help="label files hold trainIds")
    b.add_argument("--skip-existing", action="store_true", help="skip scenes whose export manifest exists")
    add_param_options(b)
    b.set_defaults(func=run_batch)

    s = sub.add_parser("sweep", help="grid search over λ1, λ2, λ3 (scored against ground truth when present)")
    s.add_argument("scene", help="scene folder (e.g. from 'npsim sample')")
    s.add_argument("--lambda1", default="1", help="comma-separated values (default 1)")
    s.add_argument("--lambda2", default="0.2,1,5,25", help="comma-separated values")
    s.add_argument("--lambda3", default="0.2,1,5", help="comma-separated values")
    s.add_argument("-o", "--out", help="write the table as CSV here")
    add_param_options(s)
    s.set_defaults(func=run_sweep)


def _summary(wf, res) -> str:
    from ..metrics import depth_metrics, normal_metrics

    sc = wf.scene
    if sc.depth_gt is None:
        return ""
    d_in = depth_metrics(res.depth_in, sc.depth_gt)
    d_out = depth_metrics(res.depth, sc.depth_gt)
    from ..camera import normals_from_depth

    n_in = normal_metrics(normals_from_depth(res.depth_in, res.intrinsics), sc.normals_gt)
    n_out = normal_metrics(normals_from_depth(res.depth, res.intrinsics), sc.normals_gt)
    return (f"vs ground truth: depth AbsRel {d_in.abs_rel:.4f} -> {d_out.abs_rel:.4f}, "
            f"normal RMSE {n_in.rmse_deg:.1f} -> {n_out.rmse_deg:.1f} deg")


def process_scene(scene, params, out: Path, nights: int, cmd: str) -> list[Path]:
    """Run the chain on ``scene`` and export everything to ``out`` (progress on stderr)."""
    from ..workflow import Workflow, export_scene

    wf = Workflow(scene)
    t0 = time.perf_counter()
    stage = [""]

    def on_stage(info: dict) -> None:
        if info.get("stage") and info["stage"] != stage[0]:
            stage[0] = info["stage"]
            _log(cmd, f"{scene.name}: {stage[0]}…")

    src = "the scene's estimated depth" if scene.depth is not None else \
        "the semantic pop-up prior (the scene has no depth; see 'npsim estimate')"
    _log(cmd, f"{scene.name}: {scene.width}x{scene.height}, depth from {src}")
    if scene.lights is None:
        _log(cmd, f"{scene.name}: no light annotation, so only the ego headlights and the night sky light the "
                  "nights (label lights with 'npsim annotate')")
    res = wf.compute(params, progress=on_stage)
    _log(cmd, f"{scene.name}: stages " + ", ".join(f"{k} {v:.2f} s" for k, v in res.timings.items())
         + f"; mesh {res.mesh.n_faces} faces")

    def progress(frac: float, text: str) -> None:
        _log(cmd, f"{scene.name}: {100 * frac:3.0f}% {text}")

    written = export_scene(wf, params, out, nights=nights, progress=progress)
    _log(cmd, f"{scene.name}: total {time.perf_counter() - t0:.1f} s")
    summ = _summary(wf, res)
    if summ:
        _log(cmd, f"{scene.name}: {summ}")
    return written


def run_one(args: argparse.Namespace) -> int:
    from ..workflow import load_any_scene

    params = params_from_args(args)
    scene = load_any_scene(args.scene, hfov_deg=args.fov)
    written = process_scene(scene, params, Path(args.out), args.nights, "run")
    print(f"wrote {len(written)} files to {args.out}")
    return 0


def run_sample_headless(out: str, size: str) -> int:
    """The main job without a display: sample scene -> refined depth, mesh, nights, all on disk."""
    from ..synthetic import street_scene
    from ..workflow import WorkflowParams
    from .sample import parse_size

    w, h = parse_size(size)
    scene = street_scene(w, h)
    params = WorkflowParams()
    out_p = Path(out)
    written = process_scene(scene, params, out_p, 3, "start")
    print(f"npsim start: wrote {len(written)} files to {out_p.resolve()}")
    for p in written:
        if p.name.endswith(("_night_0.png", "_mesh.glb", "_depth_refined_vis.png", "_export.json")):
            print(f"  {p}")
    return 0


def run_batch(args: argparse.Namespace) -> int:
    from ..datasets import open_dataset
    from ..errors import NpsimInputError
    from ..scene import load_scene

    params = params_from_args(args)
    root = Path(args.dataset)
    if not root.is_dir():
        raise NpsimInputError(f"{root}: dataset folder not found")
    scene_dirs = sorted(p.parent for p in root.glob("*/scene.json"))
    if scene_dirs:
        sources = [(d.name, lambda d=d: load_scene(d)) for d in scene_dirs]
    else:
        sources = [(s.name, s.load) for s in open_dataset(root, trainids=args.trainids, hfov_deg=args.fov)]
    if args.limit is not None:
        sources = sources[: args.limit]
    if not sources:
        raise NpsimInputError(f"{root}: no scenes found (Cityscapes/ACDC layout, image + *_labelIds.png pairs, "
                              "or scene folders)")
    failed = []
    t0 = time.perf_counter()
    for i, (name, load) in enumerate(sources):
        out = Path(args.out) / name
        if args.skip_existing and list(out.glob("*_export.json")):
            _log("batch", f"[{i + 1}/{len(sources)}] {name}: exists, skipped")
            continue
        _log("batch", f"[{i + 1}/{len(sources)}] {name}")
        try:
            process_scene(load(), params, out, args.nights, "batch")
        except NpsimInputError as exc:  # one bad scene must not stop a dataset run
            failed.append((name, str(exc)))
            _log("batch", f"{name}: FAILED: {exc}")
    _log("batch", f"{len(sources) - len(failed)}/{len(sources)} scenes done in {time.perf_counter() - t0:.1f} s")
    for name, err in failed:
        print(f"failed: {name}: {err}", file=sys.stderr)
    return 1 if failed else 0


def run_sweep(args: argparse.Namespace) -> int:
    from ..camera import normals_from_depth
    from ..errors import NpsimInputError
    from ..io import atomic_write_text
    from ..metrics import depth_metrics, normal_metrics
    from ..workflow import Workflow, load_any_scene

    params = params_from_args(args)

    def values(text: str, name: str) -> list[float]:
        try:
            vals = [float(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise NpsimInputError(f"--{name} {text!r}: give comma-separated numbers") from None
        if not vals or any(v < 0 for v in vals):
            raise NpsimInputError(f"--{name}: need at least one value, all >= 0")
        return vals

    grid = list(itertools.product(values(args.lambda1, "lambda1"), values(args.lambda2, "lambda2"),
                                  values(args.lambda3, "lambda3")))
    scene = load_any_scene(args.scene, hfov_deg=args.fov)
    wf = Workflow(scene)
    rows = []
    header = "l1,l2,l3,final_loss,seconds,abs_rel,rmse_m,normal_rmse_deg"
    print(header)
    for l1, l2, l3 in grid:
        p = params.with_value("refine", "lambda1", l1).with_value("refine", "lambda2", l2) \
                  .with_value("refine", "lambda3", l3)
        res = wf.compute(p, until="refine")
        r = res.refine
        if scene.depth_gt is not None:
            dm = depth_metrics(r.depth, scene.depth_gt)
            nm = normal_metrics(normals_from_depth(r.depth, res.intrinsics), scene.normals_gt)
            err = (dm.abs_rel, dm.rmse, nm.rmse_deg)
        else:
            err = (float("nan"),) * 3
        row = (l1, l2, l3, r.final_loss, res.timings["refine"], *err)
        rows.append(row)
        print(",".join(f"{x:.6g}" for x in row), flush=True)
    if scene.depth_gt is not None:
        best = min(rows, key=lambda r: r[7])
        _log("sweep", f"lowest normal RMSE: λ = ({best[0]:g}, {best[1]:g}, {best[2]:g}) -> {best[7]:.2f} deg, "
                      f"AbsRel {best[5]:.4f}")
    if args.out:
        atomic_write_text(args.out, header + "\n" + "\n".join(",".join(f"{x:.6g}" for x in r) for r in rows) + "\n")
    return 0
