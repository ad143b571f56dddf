"""How well the windows' final confidence orders true windows above false ones, and how it reads near
the editor's slider (docs/proposals.md "Seventh pass: confidence", "Ninth pass: window confidence").

    .venv/bin/python -m benchmarks.window_confidence [--sizes 512x256,2048x1024] [--seeds 0,1,2]
                                                     [--variants default,hard,lights]

The windows proposer alone (``ProposalParams(categories=("windows",))``, as the seventh pass measured)
on the synthetic streets; a window is *matched* when it matches a ground-truth light at mask IoU >= 0.5
(``benchmarks.annotation_actions.match_lights``, any class; the editor benchmark's oracle accepts
those) and *clean* at IoU >= 0.7 (no touch-up in the editor benchmark). Per size: the windows kept at
0.5, matched, clean, the area under the ROC curve of the confidence for both, and per confidence bin
the share matched / clean (a false window accepted costs the annotator two actions, a clean one saves
one, one matched below 0.7 saves its draw and costs a touch-up: accepting pays from about 2/3 clean).
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

#: Confidence bins of the calibration table: [lo, hi).
BINS = ((0.5, 0.6), (0.6, 0.7), (0.7, 0.8), (0.8, 0.9), (0.9, 0.95), (0.95, 1.01))


def roc_auc(score: np.ndarray, label: np.ndarray) -> float:
    """Area under the ROC curve: the probability that a random positive scores above a random
    negative, ties counted half (the Mann-Whitney statistic). NaN without both classes."""
    from scipy.stats import rankdata

    score, label = np.asarray(score, float), np.asarray(label, bool)
    n1, n0 = int(label.sum()), int((~label).sum())
    if n1 == 0 or n0 == 0:
        return float("nan")
    r = rankdata(score)
    return float((r[label].sum() - n1 * (n1 + 1) / 2) / (n1 * n0))


def calibration(conf: np.ndarray, label: np.ndarray, bins=BINS) -> list[tuple[int, float]]:
    """Per bin [lo, hi) of ``conf``: (count, share of ``label`` true; NaN when empty)."""
    conf, label = np.asarray(conf, float), np.asarray(label, bool)
    out = []
    for lo, hi in bins:
        m = (conf >= lo) & (conf < hi)
        out.append((int(m.sum()), float(label[m].mean()) if m.any() else float("nan")))
    return out


def window_outcomes(scene) -> tuple[np.ndarray, np.ndarray]:
    """The windows proposed at >= 0.5 on ``scene``: their confidences and the mask IoU of their match
    to a ground-truth light (0 when unmatched)."""
    from benchmarks.annotation_actions import match_lights
    from npsim_core.proposals import ProposalParams, propose_for_scene

    props = propose_for_scene(scene, ProposalParams(categories=("windows",)))
    iou = {b: v for _, (b, v) in match_lights(scene.lights, props.annotation).items()}
    ids = [i for i in props.category_ids("windows") if props.confidence.get(i, 0.0) >= 0.5]
    return (np.array([props.confidence[i] for i in ids], float), np.array([iou.get(i, 0.0) for i in ids], float))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="512x256,2048x1024")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--variants", default="default,hard,lights")
    args = ap.parse_args(argv)
    from npsim_cli.options import parse_size
    from npsim_core.synthetic import street_scene

    seeds = [int(s) for s in args.seeds.split(",") if s]
    variants = [v for v in args.variants.split(",") if v]
    rows = []
    t0 = time.perf_counter()
    for size in [s for s in args.sizes.split(",") if s]:
        w, h = parse_size(size)
        got = [window_outcomes(street_scene(w, h, s, v)) for v in variants for s in seeds]
        conf = np.concatenate([c for c, _ in got])
        iou = np.concatenate([i for _, i in got])
        rows.append((size, conf, iou))
    load = os.getloadavg()[0]
    print(f"# Window confidence, synthetic streets {', '.join(variants)}, seeds {args.seeds} "
          f"({time.perf_counter() - t0:.0f} s, load {load:.1f})\n")
    print("| size | kept at 0.5 / matched / clean | AUC matched | AUC clean | accepted >= 0.9: matched / clean |")
    print("|---|---|---|---|---|")
    for size, conf, iou in rows:
        hi = conf >= 0.9
        print(f"| {size} | {conf.size} / {(iou >= 0.5).sum()} / {(iou >= 0.7).sum()} | "
              f"{roc_auc(conf, iou >= 0.5):.3f} | {roc_auc(conf, iou >= 0.7):.3f} | "
              f"{hi.sum()}: {(iou[hi] >= 0.5).mean() if hi.any() else float('nan'):.2f} / "
              f"{(iou[hi] >= 0.7).mean() if hi.any() else float('nan'):.2f} |")
    print("\nPer confidence bin: windows, share matched / clean\n")
    print("| size | " + " | ".join(f"[{lo:.2f}, {min(hi, 1.0):.2f})" for lo, hi in BINS) + " |")
    print("|---|" + "---|" * len(BINS))
    for size, conf, iou in rows:
        cells = [f"{n}: {a:.2f} / {b:.2f}" if n else "0" for (n, a), (_, b) in
                 zip(calibration(conf, iou >= 0.5), calibration(conf, iou >= 0.7))]
        print(f"| {size} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
