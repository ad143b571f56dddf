"""``npsim estimate SCENE --method popup|files|network|stereo``: estimate the input depth and normals.

SCENE is a scene folder (``npsim sample``) or one labelled image from a
dataset (a Cityscapes/ACDC image path is matched to its labels; in a plain
folder, ``x.png`` to ``x_labelIds.png``). The result is written as a scene
folder (``-o DIR``, default: SCENE itself when it is a scene folder) with
``depth_pred.npy`` / ``normals_pred.npy`` replaced -- the previous ones (and ``scene.json``) are kept as
``depth_pred.prev.npy``, ``normals_pred.prev.npy``, ``scene.prev.json`` (``.prev2``... when those exist); the errors against the frame's
reference (ground truth, else its stereo depth) are printed when it has one.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from npsim_core.errors import NpsimInputError


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("estimate", help="estimate depth and normals (pop-up prior, files, or a local network)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="scene folder, or an image file inside a dataset (labels found by name)")
    p.add_argument("--method", choices=("popup", "files", "network", "stereo"), default="popup",
                   help="popup: the semantic pop-up prior; files: --depth FILE; network: --checkpoint DIR; stereo: "
                        "the dataset's disparity (holes from the aligned prior)")
    p.add_argument("-o", "--output", help="output scene folder (default: SCENE when it is a scene folder)")
    p.add_argument("--depth", help="files: depth map (.npy, .pfm, .exr, 16-bit .png metres*256, disparity .png)")
    p.add_argument("--normals", help="files: normal map (.npy or 8/16-bit .png); default: from the depth")
    p.add_argument("--baseline", type=float, help="files: stereo baseline (m) when --depth is a disparity PNG")
    p.add_argument("--focal", type=float, help="files: focal length (px) when --depth is a disparity PNG")
    p.add_argument("--checkpoint", help="network: local transformers checkpoint folder (nothing is downloaded)")
    p.add_argument("--camera-height", type=float, help="camera height above the ground, metres")
    p.add_argument("--pitch", type=float, help="camera pitch, radians (down > 0)")
    p.add_argument("--fov", type=float, help="horizontal field of view (deg) for a dataset image")
    p.add_argument("--trainids", action="store_true", help="dataset label files hold trainIds")
    p.set_defaults(func=run)


def _load(args: argparse.Namespace):
    from npsim_core.chain import load_frame

    path = Path(args.scene)
    if path.is_dir() and args.fov is not None:
        raise NpsimInputError("--fov applies to dataset images; a scene folder has intrinsics.json")
    return load_frame(path, hfov_deg=args.fov, trainids=args.trainids), (path if path.is_dir() else None)


#: What an estimate replaces in a scene folder (kept as ``<stem>.prev[N]<suffix>`` first).
REPLACED = ("depth_pred.npy", "normals_pred.npy", "scene.json")


def keep_previous(folder: Path) -> list[tuple[str, str]]:
    """Copy the prediction files an estimate is about to replace in ``folder`` to the first free
    ``depth_pred.prev.npy``, ``depth_pred.prev2.npy``, ... (likewise the normals and scene.json), so
    a user's earlier prediction is never lost. Returns (old, kept) names."""
    import shutil

    kept = []
    for name in REPLACED:
        src = folder / name
        if not src.is_file():
            continue
        stem, suffix = name.rsplit(".", 1)
        k = 1
        while (folder / f"{stem}.prev{k if k > 1 else ''}.{suffix}").exists():
            k += 1
        dst = folder / f"{stem}.prev{k if k > 1 else ''}.{suffix}"
        shutil.copy2(src, dst)
        kept.append((name, dst.name))
    return kept


def run(args: argparse.Namespace) -> int:
    from npsim_core.chain import check_output_folder
    from npsim_core.geometry import DEPTH_FAR_M, DEPTH_NEAR_M, DepthLimits, estimate_geometry
    from npsim_core.geometry.files import FilesParams
    from npsim_core.geometry.network import NetworkParams
    from npsim_core.geometry.popup import PopupParams
    from npsim_core.scoring import reference_of, score_depth
    from npsim_core.scene import save_scene

    scene, folder = _load(args)
    out = Path(args.output) if args.output else folder
    if out is None:
        raise NpsimInputError("-o DIR is required when SCENE is an image (it names the scene folder to write)")
    check_output_folder(out)
    popup = PopupParams(camera_height=args.camera_height, camera_pitch=args.pitch)
    if args.method == "popup":
        params = popup
    elif args.method == "stereo":
        from npsim_core.geometry.stereo import StereoParams

        params = StereoParams(popup=popup)
    elif args.method == "files":
        if not args.depth:
            raise NpsimInputError("--method files needs --depth FILE")
        params = FilesParams(depth_path=args.depth, normals_path=args.normals, disparity_baseline=args.baseline,
                             disparity_focal=args.focal)
    else:
        if not args.checkpoint:
            raise NpsimInputError("--method network needs --checkpoint DIR (a local transformers checkpoint)")
        params = NetworkParams(checkpoint=args.checkpoint, popup=popup)
    est = estimate_geometry(scene, args.method, params)
    valid = float(((est.depth == est.depth) & (est.depth > 0)).mean())
    if valid == 0:
        raise NpsimInputError(f"{scene.name}: the {args.method} depth has no valid pixel (all NaN, <= 0, nearer than "
                              f"{DEPTH_NEAR_M:g} m, beyond {DEPTH_FAR_M:g} m, or sky); "
                              "nothing written -- check the depth file and its units")
    result = est.apply(scene)
    kept = keep_previous(out)
    save_scene(result, out)
    if kept:
        print(f"{scene.name}: the previous prediction is kept: " + ", ".join(f"{a} -> {b}" for a, b in kept))
    print(f"{scene.name}: {args.method} depth/normals -> {out}/depth_pred.npy, normals_pred.npy "
          f"({100 * float((est.depth == est.depth).mean()):.1f}% valid)")
    lim = DepthLimits(**est.info["depth_limits"])
    if lim.dropped:
        print(f"  {lim.sentence()}")
    # Scored against the stereo itself only on the pixels held out of it.
    ref = reference_of(scene, holdout=float(est.info.get("holdout", 0.0)) if args.method == "stereo" else 0.0)
    if ref is not None:
        sc = score_depth(est.depth, scene.intrinsics, scene.labels, ref)
        cls = ", ".join(f"{k} {v:.3f}" for k, v in sc["classes"].items() if v == v)
        print(f"  depth vs {ref.kind}: AbsRel {sc['abs_rel']:.4f}, RMSE {sc['rmse_m']:.3f} m, delta1 "
              f"{sc['delta1']:.4f}, RMSElog {sc['rmse_log']:.4f}; AbsRel per class: {cls}")
        if "normal_rmse_deg" in sc:
            print(f"  normals vs {ref.kind}: angular RMSE {sc['normal_rmse_deg']:.2f} deg, within 11.25 deg "
                  f"{sc['normal_within_11_25']:.3f}")
    return 0
