"""``npsim info PATH``: describe a scene folder."""

from __future__ import annotations

import argparse


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("info", help="describe a frame (scene folder, project, dataset image)")
    p.add_argument("path", help="scene folder, project folder, or a dataset image with its labels")
    p.set_defaults(func=run)


def describe_scene(scene) -> str:
    import numpy as np

    from npsim_core.labels import cityscapes, light_class

    table = cityscapes()
    lines = [f"scene {scene.name}: {scene.width}x{scene.height}",
             f"  intrinsics fx={scene.intrinsics.fx:.2f} fy={scene.intrinsics.fy:.2f} cx={scene.intrinsics.cx:.2f} "
             f"cy={scene.intrinsics.cy:.2f} (hfov {scene.intrinsics.hfov_deg:.1f} deg)",
             f"  camera height {scene.camera_height:.2f} m, pitch {scene.camera_pitch:.3f} rad"]
    ids, counts = np.unique(scene.labels, return_counts=True)
    order = np.argsort(-counts)
    lines.append("  labels: " + ", ".join(f"{table.by_id(int(ids[i])).name} {100 * counts[i] / counts.sum():.1f}%"
                                          for i in order[:8]) + (" ..." if len(ids) > 8 else ""))
    for attr in ("depth", "normals", "depth_gt", "normals_gt", "albedo", "roughness"):
        a = getattr(scene, attr)
        if a is None:
            lines.append(f"  {attr}: -")
            continue
        fin = np.isfinite(a) if a.ndim == 2 else np.isfinite(a).all(axis=-1)
        desc = f"  {attr}: {a.shape} {a.dtype}, {100 * fin.mean():.1f}% valid"
        if a.ndim == 2 and fin.any():
            desc += f", {np.nanmin(a):.2f}..{np.nanmax(a):.2f}"
        lines.append(desc)
    if scene.lights is not None:
        ids = scene.lights.instance_ids()
        by_class: dict[str, int] = {}
        for i in ids:
            by_class[light_class(i // 1000).name] = by_class.get(light_class(i // 1000).name, 0) + 1
        lines.append(f"  lights: {len(ids)} instances ({', '.join(f'{k} {v}' for k, v in sorted(by_class.items()))}), "
                     f"{len(scene.lights.groups)} groups")
    else:
        lines.append("  lights: -")
    if scene.provenance:
        lines.append(f"  provenance: {', '.join(f'{k}={v}' for k, v in scene.provenance.items() if k != 'files')}")
    return "\n".join(lines)


def run(args: argparse.Namespace) -> int:
    from npsim_core.chain import load_frame

    print(describe_scene(load_frame(args.path)))
    return 0
