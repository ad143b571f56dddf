"""``npsim estimate SCENE --method popup|files|network``: estimate the input depth and normals.

SCENE is a scene folder (``npsim sample``) or one labelled image from a
dataset (a Cityscapes/ACDC image path is matched to its labels; in a plain
folder, ``x.png`` to ``x_labelIds.png``). The result is written as a scene
folder (``-o DIR``, default: SCENE itself when it is a scene folder) with
``depth_pred.npy`` / ``normals_pred.npy`` replaced; the errors against ground
truth are printed when the scene has it.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("estimate", help="estimate depth and normals (pop-up prior, files, or a local network)",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="scene folder, or an image file inside a dataset (labels found by name)")
    p.add_argument("--method", choices=("popup", "files", "network"), default="popup")
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
    from ..datasets import iter_dataset
    from ..errors import NpsimInputError
    from ..scene import load_scene

    path = Path(args.scene)
    if path.is_dir():
        if args.fov is not None:
            raise NpsimInputError("--fov applies to dataset images; a scene folder has intrinsics.json")
        return load_scene(path), path
    if not path.exists():
        raise NpsimInputError(f"{path}: not found; give a scene folder or a labelled image")
    # An image inside a dataset: list its folder with the dataset readers and pick it.
    for src in iter_dataset(path.parent, trainids=args.trainids, hfov_deg=args.fov):
        if src.image_path.resolve() == path.resolve():
            return src.load(), None
    raise NpsimInputError(f"{path}: no label file found for this image (expected e.g. "
                          f"{path.stem}_labelIds.png next to it, or the Cityscapes/ACDC gtFine/gt file)")


def run(args: argparse.Namespace) -> int:
    from ..errors import NpsimInputError
    from ..geometry import estimate_geometry
    from ..geometry.files import FilesParams
    from ..geometry.network import NetworkParams
    from ..geometry.popup import PopupParams
    from ..metrics import depth_metrics, normal_metrics
    from ..scene import save_scene

    scene, folder = _load(args)
    out = Path(args.output) if args.output else folder
    if out is None:
        raise NpsimInputError("-o DIR is required when SCENE is an image (it names the scene folder to write)")
    popup = PopupParams(camera_height=args.camera_height, camera_pitch=args.pitch)
    if args.method == "popup":
        params = popup
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
    result = est.apply(scene)
    save_scene(result, out)
    print(f"{scene.name}: {args.method} depth/normals -> {out}/depth_pred.npy, normals_pred.npy "
          f"({100 * float((est.depth == est.depth).mean()):.1f}% valid)")
    if scene.depth_gt is not None:
        dm = depth_metrics(est.depth, scene.depth_gt)
        print(f"  depth vs ground truth: AbsRel {dm.abs_rel:.4f}, RMSE {dm.rmse:.3f} m, delta1 {dm.delta1:.4f}")
    if scene.normals_gt is not None:
        nm = normal_metrics(est.normals, scene.normals_gt)
        print(f"  normals vs ground truth: angular RMSE {nm.rmse_deg:.2f} deg, within 11.25 deg "
              f"{nm.within_11_25:.3f}")
    return 0
