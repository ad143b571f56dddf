"""``npsim propose SCENE -o OUT``: propose a light annotation for a frame (docs/proposals.md).

SCENE is a scene folder (``npsim sample``), a project folder, or one labelled
image of a dataset (Cityscapes instance ids beside its labels are used). Depth
comes from the chain's geometry stage (the frame's own depth, else stereo,
else the pop-up prior). OUT receives the editor's files for the frame:
``<name>_lights_instanceIds.png``, ``<name>_lights_classIds.png``,
``<name>_lights.json`` (groups; the confidence of every proposed light and
group in ``meta.proposal_confidence``) and ``<name>_lights_coco.json``.
Open them with ``npsim annotate`` to review and edit.
"""

from __future__ import annotations

import argparse
from pathlib import Path


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("propose", help="propose light sources (windows, lamps...) for a frame",
                       description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("scene", help="scene folder, project folder, or a labelled image inside a dataset")
    p.add_argument("-o", "--output", required=True, help="folder to write the annotation files into")
    p.add_argument("--min-confidence", type=float, default=None,
                   help="keep proposals at least this confident (0..1; default 0.5)")
    p.add_argument("--fov", type=float, help="horizontal field of view (deg) for a dataset image")
    p.add_argument("--trainids", action="store_true", help="dataset label files hold trainIds")
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from npsim_core.annotation import save_annotation
    from npsim_core.chain import Chain, ChainParams, check_output_folder, load_frame
    from npsim_core.errors import NpsimInputError
    from npsim_core.proposals import ProposalParams, propose_lights, summarize

    params = ProposalParams()
    threshold = params.min_confidence if args.min_confidence is None else float(args.min_confidence)
    if not 0.0 <= threshold <= 1.0:
        raise NpsimInputError(f"--min-confidence must lie in 0..1, got {args.min_confidence}")
    path = Path(args.scene)
    if path.is_dir() and args.fov is not None:
        raise NpsimInputError("--fov applies to dataset images; a scene folder has intrinsics.json")
    out = check_output_folder(args.output)
    scene = load_frame(path, hfov_deg=args.fov, trainids=args.trainids)
    geo = Chain(scene).compute(ChainParams(), until="geometry")
    params = ProposalParams(camera_height_m=float(scene.camera_height), camera_pitch_rad=float(scene.camera_pitch))
    props = propose_lights(scene.image, scene.labels, geo.depth_in, geo.intrinsics, scene.instances, params)
    ann = props.above(threshold)
    ann.meta["source"] = "npsim propose"
    ann.meta["depth_source"] = geo.depth_source
    ann.meta["proposal_min_confidence"] = threshold
    kept = set(ann.instance_ids()) | set(ann.groups)
    ann.meta["proposal_confidence"] = {str(i): round(c, 4) for i, c in sorted(props.confidence.items()) if i in kept}
    paths = save_annotation(ann, out, scene.name, image=scene.image)
    for cat, s in summarize(props, threshold).items():
        rng = f", confidence {s['confidence'][0]:.2f}-{s['confidence'][1]:.2f}" if s["confidence"] else ""
        n, g = s["lights"], s["groups"]
        print(f"{cat}: {n} light{'' if n == 1 else 's'} in {g} group{'' if g == 1 else 's'}{rng}")
    print(f"wrote {paths['json']}")
    return 0
