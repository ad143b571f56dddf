"""Whether a change to the proposers changed any proposal: dump, then compare, bit for bit.

    .venv/bin/python -m benchmarks.proposals_same dump REF.pkl [--quick | --textured]
    .venv/bin/python -m benchmarks.proposals_same check REF.pkl [--quick | --textured]

For work meant to change no output (speed passes, refactors; docs/proposals.md "Seventeenth pass"):
``dump`` runs :func:`npsim_core.proposals.propose_lights` on the benchmark frames and saves every
frame's proposals -- the instance map, the groups, the class meta and the confidences; ``check`` runs
them again and compares each with the dump exactly (exit status 1 and the frames that differ). Both
print the process (CPU) time per frame: the median at 2048x1024 and 512x256, and the load.

Frames: the synthetic street (``benchmarks.proposals.frame``: the scene's depth and Cityscapes instance
ids) at 512x256 seeds 0-5 and 2048x1024 seeds 0-2, default / hard / lights (27 frames); ``--quick``
512x256 seeds 0-2 and 2048x1024 seed 0; ``--textured`` the brick-textured street of
``benchmarks.proposals_textured`` at three sizes, with and without depth (6 frames). The frames are
cached as pickles in ``$NPSIM_CACHE/proposals_same`` (default ``~/.cache/npsim``), so a check of an
older tree (run from its own checkout) reads the same inputs.
"""

from __future__ import annotations

import argparse
import os
import pickle
import sys
import time
from pathlib import Path

import numpy as np


def frames(quick: bool = False, textured: bool = False) -> list[tuple[int, int, int, str]]:
    """The (W, H, seed, variant) keys of the frames checked; variant ``textured-none|scene``."""
    if textured:
        return [(W, H, 0, f"textured-{d}") for W, H in ((512, 256), (1024, 512), (2048, 1024))
                for d in ("none", "scene")]
    keys = [(512, 256, s, v) for s in range(6) for v in ("default", "hard", "lights")] + \
        [(2048, 1024, s, v) for s in range(3) for v in ("default", "hard", "lights")]
    if quick:
        keys = [k for k in keys if (k[0] == 512 and k[2] < 3) or (k[0] == 2048 and k[2] == 0)]
    return keys


def load(key: tuple[int, int, int, str], cache: Path) -> dict:
    """The inputs of ``propose_lights`` for a frame, made once and cached."""
    W, H, seed, variant = key
    f = cache / f"{W}x{H}_{seed}_{variant}.pkl"
    if not f.exists():
        if variant.startswith("textured-"):
            from benchmarks.proposals_textured import textured

            sc, img = textured(W, H, seed)
            d = dict(image=img, labels=sc.labels, depth=sc.depth if variant.endswith("scene") else None,
                     intrinsics=sc.intrinsics, instances=None)
        else:
            from benchmarks.proposals import frame

            sc, inst = frame(W, H, seed, variant)
            d = dict(image=sc.image, labels=sc.labels, depth=sc.depth, intrinsics=sc.intrinsics, instances=inst)
        cache.mkdir(parents=True, exist_ok=True)
        tmp = f.with_suffix(".tmp")
        with open(tmp, "wb") as fh:
            pickle.dump(d, fh)
        os.replace(tmp, f)
    with open(f, "rb") as fh:
        return pickle.load(fh)


def run(keys, cache: Path) -> tuple[dict, dict]:
    """Per frame its proposals (instance map, groups, meta, confidences) and the CPU seconds they took."""
    from npsim_core.proposals import propose_lights

    out, secs = {}, {}
    for key in keys:
        d = load(key, cache)
        t = time.process_time()
        p = propose_lights(d["image"], d["labels"], d["depth"], d["intrinsics"], d["instances"])
        secs[key] = time.process_time() - t
        a = p.annotation
        out[key] = dict(mask=np.asarray(a.instance_map), groups={k: tuple(g.members) for k, g in a.groups.items()},
                        meta=a.meta, conf=dict(p.confidence))
    return out, secs


def differences(got: dict, ref: dict) -> list[str]:
    """What differs between a frame's proposals and its reference (empty: identical)."""
    diffs = [n for n in ("groups", "meta", "conf") if got[n] != ref[n]]
    if got["mask"].shape != ref["mask"].shape:
        diffs.append(f"mask shape {got['mask'].shape} != {ref['mask'].shape}")
    elif not np.array_equal(got["mask"], ref["mask"]):
        diffs.append(f"mask ({int((got['mask'] != ref['mask']).sum())} px)")
    return diffs


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m benchmarks.proposals_same", description=__doc__.split("\n")[0])
    ap.add_argument("mode", choices=("dump", "check"))
    ap.add_argument("ref", type=Path, help="the reference file (written by dump, read by check)")
    g = ap.add_mutually_exclusive_group()
    g.add_argument("--quick", action="store_true", help="512x256 seeds 0-2 and 2048x1024 seed 0 only")
    g.add_argument("--textured", action="store_true", help="the brick-textured street, with and without depth")
    a = ap.parse_args(argv)
    if a.mode == "check" and not a.ref.is_file():
        print(f"proposals_same: {a.ref}: no such reference; write one first with 'dump {a.ref}'", file=sys.stderr)
        return 2
    cache = Path(os.environ.get("NPSIM_CACHE", Path.home() / ".cache" / "npsim")) / "proposals_same"
    keys = frames(a.quick, a.textured)
    out, secs = run(keys, cache)
    for size in sorted({k[:2] for k in keys}, reverse=True):
        t = [s for k, s in secs.items() if k[:2] == size]
        print(f"{size[0]}x{size[1]}: CPU median {np.median(t):.2f} s, max {max(t):.2f} s over {len(t)} frames")
    print(f"load {os.getloadavg()[0]:.2f}")
    if a.mode == "dump":
        with open(a.ref, "wb") as fh:
            pickle.dump(out, fh)
        print(f"wrote {a.ref} ({len(out)} frames)")
        return 0
    with open(a.ref, "rb") as fh:
        ref = pickle.load(fh)
    missing = [k for k in out if k not in ref]
    if missing:
        print(f"proposals_same: {a.ref} lacks {len(missing)} of these frames (dumped with other options?)",
              file=sys.stderr)
        return 2
    bad = [(k, d) for k in out if (d := differences(out[k], ref[k]))]
    for k, d in bad:
        print("differs:", "x".join(map(str, k[:2])), f"seed {k[2]}", k[3], "--", ", ".join(d))
    print("identical" if not bad else f"{len(bad)} of {len(out)} frames differ")
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
