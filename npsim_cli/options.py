"""Options shared by the commands that run the chain, and the progress log."""

from __future__ import annotations

import argparse
import re
import sys
import time
from dataclasses import replace
from pathlib import Path

from npsim_core.chain.names import DEPTH_SOURCES, LIGHT_SOURCES
from npsim_core.errors import NpsimInputError


def log(cmd: str, msg: str) -> None:
    print(f"[npsim {cmd}] {msg}", file=sys.stderr, flush=True)


def clean_leftovers(cmd: str, folder, depth: int = 0) -> None:
    """Remove and report the staging folders a killed run left in the output ``folder``
    (:func:`npsim_core.io.remove_stale_staging`)."""
    from npsim_core.io import remove_stale_staging

    for path, size in remove_stale_staging(folder, depth):
        log(cmd, f"removed {path} ({size / 1e6:.1f} MB): the unfinished output of an interrupted run")


def log_warnings(cmd: str, scene) -> None:
    """Log what loading ``scene`` noticed but did not refuse (:func:`npsim_core.scene.scene_warnings`)."""
    for w in scene.provenance.get("warnings", []):
        log(cmd, f"{scene.name}: WARNING: {w}")


def stage_logger(cmd: str, name: str, every_s: float = 5.0):
    """A chain progress callback that logs each stage's start and, in long stages, a step every
    ``every_s`` seconds."""
    last = [time.perf_counter()]

    def on_stage(info: dict) -> None:
        if info.get("stage") and "done" not in info and "step" not in info:
            log(cmd, f"{name}: {info['stage']}…")
            last[0] = time.perf_counter()
        elif "step" in info and time.perf_counter() - last[0] > every_s:
            last[0] = time.perf_counter()
            log(cmd, f"{name}: {info['stage']} step {info['step']}/{info['of']}")

    return on_stage


def parse_size(text: str) -> tuple[int, int]:
    """``"WxH"`` -> (W, H); raises NpsimInputError with the expected form."""
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text))
    if not m:
        raise NpsimInputError(f"--size {text!r}: expected WIDTHxHEIGHT in pixels, e.g. --size 512x256")
    w, h = int(m.group(1)), int(m.group(2))
    if not (2 <= w <= 16384 and 2 <= h <= 16384):
        raise NpsimInputError(f"--size {text!r}: width and height must be between 2 and 16384 pixels")
    return w, h


def add_param_options(p: argparse.ArgumentParser, *, nights: int | None = 1) -> None:
    """--params, --preset, --set, --seed, --spp, --denoiser, --fov (and --nights when ``nights`` is not None)."""
    p.add_argument("--params", help="JSON file of parameters (a project.json 'params', an export manifest, "
                                    "or the sections themselves)")
    p.add_argument("--preset", choices=["appendix_b", "section_3_4_3"], help="λ preset (default appendix_b)")
    p.add_argument("--set", action="append", default=[], metavar="SECTION.FIELD=VALUE",
                   help="override one parameter (value as JSON), e.g. --set refine.optimizer=adam_faithful "
                        "--set filter.sigma_s=8 --set refine.lambdas=[1,5,1]")
    if nights is not None:
        p.add_argument("--nights", type=int, default=nights, help=f"number of night images (default {nights})")
    p.add_argument("--seed", type=int, default=None, help="seed of the first night (night k uses seed+k)")
    p.add_argument("--spp", type=int, default=None, help="samples per pixel of the nights (default 16)")
    p.add_argument("--denoiser", choices=["oidn", "guided", "none"], default=None,
                   help="Monte Carlo denoiser of the nights: oidn (Intel Open Image Denoise with albedo/normal "
                        "guides, default), guided (the mesh-guided à-trous filter; strengths --set denoise.FIELD=V) "
                        "or none (night.denoiser)")
    p.add_argument("--fov", type=float, default=None, help="horizontal field of view in degrees (overrides intrinsics)")
    p.add_argument("--depth", dest="depth_source", choices=DEPTH_SOURCES, default=None,
                   help="input depth per frame: auto (default: the frame's own depth file, else the dataset's stereo, "
                        "else a network with --checkpoint, else the pop-up prior), files, stereo, network, prior")
    p.add_argument("--full-outputs", action="store_true",
                   help="also write the full mesh, 16-bit depth/normal PNGs, normals .npy and linear nights .npy "
                        "(default: only what a frame needs: about 30 MB at 2048x1024)")
    p.add_argument("--checkpoint", default=None, help="local depth-network checkpoint folder (for --depth network/auto)")
    p.add_argument("--lights", default=None, metavar="auto|annotation|proposed|none|FILE",
                   help="the light sources the nights switch on: auto (default: the frame's hand annotation, else the "
                        "automatic proposals of 'npsim propose'), annotation (hand annotation only), proposed, none, "
                        "or a light annotation FILE (<name>_lights.json or COCO JSON; one frame only)")
    p.add_argument("--min-confidence", type=float, default=None,
                   help="proposals below this confidence are not used (lights.min_confidence, default 0.5)")


def params_from_args(args: argparse.Namespace) -> "ChainParams":  # noqa: F821 (imported here: start-up time)
    from npsim_core.chain.params import ChainParams, changed_fields, set_fields
    from npsim_core.io import read_json

    params = ChainParams()
    touched: list[tuple[str, str, str]] = []  # (section, field, where it was set)
    if args.params:
        doc = read_json(args.params)
        if isinstance(doc, dict) and "params" in doc:
            doc = doc["params"]
        params = ChainParams.from_json(doc, args.params)
        touched += [(sec, name, f"--params {args.params}") for sec, name in changed_fields(params)]
    touched += [(sec, name, f"--set {sec}.{name}") for sec, name in set_fields(args.set)]
    if args.preset:
        params = params.with_preset(args.preset)
    params = params.with_sets(args.set)
    if args.seed is not None:
        params = params.with_value("night", "seed", int(args.seed))
    if args.spp is not None:
        if args.spp < 1:
            raise NpsimInputError(f"--spp must be >= 1, got {args.spp}")
        params = params.with_value("night", "final_spp", int(args.spp))
    if getattr(args, "denoiser", None):
        params = params.with_value("night", "denoiser", args.denoiser)
        if args.denoiser != "none":  # an explicit choice switches denoising on
            params = params.with_value("night", "denoise", True)
    if args.fov is not None:
        if not 0 < args.fov < 180:
            raise NpsimInputError(f"--fov must be a horizontal field of view in (0, 180) degrees, got {args.fov}")
        params = params.with_value("camera", "hfov_deg", float(args.fov))
    if getattr(args, "full_outputs", False):
        params = params.with_value("export", "extras", True).with_value("export", "mesh", "both")
    if getattr(args, "checkpoint", None):
        params = params.with_value("depth", "checkpoint", str(args.checkpoint))
    if getattr(args, "depth_source", None):
        params = params.with_value("depth", "source", args.depth_source)
    lights = getattr(args, "lights", None)
    if lights:
        if lights in LIGHT_SOURCES and lights != "file":
            params = params.with_value("lights", "source", lights)
        else:
            path = Path(lights)
            if not path.is_file():
                raise NpsimInputError(f"--lights {lights}: neither {', '.join(s for s in LIGHT_SOURCES if s != 'file')} "
                                      "nor an existing light annotation file")
            params = replace(params, lights=replace(params.lights, source="file", file=str(path.resolve())))
    if getattr(args, "min_confidence", None) is not None:
        params = params.with_value("lights", "min_confidence", float(args.min_confidence))
    if getattr(args, "nights", 0) is not None and getattr(args, "nights", 0) < 0:
        raise NpsimInputError(f"--nights must be >= 0, got {args.nights}")
    warn_unread(getattr(args, "command", None) or "npsim", params, touched)
    return params


def warn_unread(cmd: str, params, touched: list[tuple[str, str, str]]) -> list[str]:
    """Log a warning for every field set (``touched``: section, field, where) that the chosen
    optimiser, denoiser, source or mode does not read (:func:`npsim_core.chain.params.unread_fields`);
    returns the warnings. Nothing set is ever silently ignored."""
    from npsim_core.chain.params import unread_fields

    unread = unread_fields(params)
    out = []
    for sec, name, where in dict.fromkeys(touched):
        if (sec, name) in unread:
            out.append(f"WARNING: {where} changes nothing: {unread[(sec, name)]}")
            log(cmd, out[-1])
    return out
