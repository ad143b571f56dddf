"""How well the windows' final confidence orders true windows above false ones, and how it reads near
the editor's slider (docs/proposals.md "Seventh pass: confidence", "Ninth pass: window confidence").

    .venv/bin/python -m benchmarks.window_confidence [--sizes 512x256,2048x1024] [--seeds 0,1,2]
                                                     [--variants default,hard,lights]
                                                     [--fit [--held-out 3,4,5] [--target 0.7] [--raise 1.0]]

The windows proposer alone (``ProposalParams(categories=("windows",))``, as the seventh pass measured)
on the synthetic streets; a window is *matched* when it matches a ground-truth light at mask IoU >= 0.5
(``benchmarks.annotation_actions.match_lights``, any class; the editor benchmark's oracle accepts
those) and *clean* at IoU >= 0.7 (no touch-up in the editor benchmark). Per size: the windows kept at
0.5, matched, clean, the area under the ROC curve of the confidence for both, and per confidence bin
the share matched / clean (a false window accepted costs the annotator two actions, a clean one saves
one, one matched below 0.7 saves its draw and costs a touch-up: accepting pays from about 2/3 clean).

``--fit`` refits the weights of ``window_confidence.window_confidence`` (docs/proposals.md "Tenth pass"):
every window's features (``window_confidence.window_features``, logged from ``rescore_windows``) on the
``--seeds`` of all sizes, a logistic regression (Newton) for "matched at IoU >= ``--target``" over the
windows at least 0.5 confident, its bias then raised by ``--raise`` (the slider's break-even: a false
window accepted costs two actions, a clean one saves one); it prints the weights for ``ProposalParams``
and the AUC of the rule's confidences with the committed weights ("now") and with the fitted ones
("fit", :func:`rule_confidences`: the same rule, tiny windows' cap included) on the fitting and the
``--held-out`` seeds, per size.
"""

from __future__ import annotations

import argparse
import os
import time
from dataclasses import replace

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


def window_records(scene) -> list[dict]:
    """Every window the proposer kept (any confidence) on ``scene``: its features
    (``window_confidence.window_features``), first confidence ``conf0``, final ``conf`` and ``iou`` of its
    match to a ground-truth light (0 when unmatched). Windows a later one painted over entirely are left out."""
    from benchmarks.annotation_actions import match_lights
    from npsim_core.proposals import ProposalParams, propose_for_scene
    from npsim_core.proposals import window_confidence as wc

    logged: list[tuple[object, dict]] = []
    orig = wc.rescore_windows

    def logging_rescore(ctx, groups, feat, B):
        xs = wc.window_features(ctx, groups, feat, B)
        for g, gx in zip(groups, xs):
            for li, x in zip(g.members, gx):
                x["conf0"] = li.confidence
                logged.append((li, x))
        out = orig(ctx, groups, feat, B)
        for li, x in logged:
            x["conf"] = li.confidence
        return out

    wc.rescore_windows = logging_rescore
    try:
        props = propose_for_scene(scene, ProposalParams(categories=("windows",)))
    finally:
        wc.rescore_windows = orig
    iou = {b: v for _, (b, v) in match_lights(scene.lights, props.annotation).items()}
    ann = props.annotation
    out = []
    for li, x in logged:  # the proposal id of a logged light: the id painted over most of its mask
        h, w = li.mask.shape
        sub = ann.instance_map[max(li.y0, 0):li.y0 + h, max(li.x0, 0):li.x0 + w]
        m = li.mask[max(-li.y0, 0):max(-li.y0, 0) + sub.shape[0], max(-li.x0, 0):max(-li.x0, 0) + sub.shape[1]]
        ids, n = np.unique(sub[m], return_counts=True)
        n, ids = n[ids > 0], ids[ids > 0]
        if ids.size == 0:
            continue
        lid = int(ids[np.argmax(n)])
        out.append({**x, "iou": iou.get(lid, 0.0), "id": lid})
    return out


def design(recs: list[dict]) -> np.ndarray:
    """The terms of ``window_confidence.window_confidence`` (without the bias), one row per record:
    ``window_confidence.score_terms``, so the fit and the rule read the same terms."""
    from npsim_core.proposals import ProposalParams
    from npsim_core.proposals.window_confidence import first_confidence, score_terms

    p = ProposalParams()
    rows = [score_terms(first_confidence(p, x["conf0"], x), x) for x in recs]
    return np.asarray(rows, float).reshape(len(rows), -1) if rows else np.zeros((0, 14))


def rule_confidences(recs: list[dict], p) -> np.ndarray:
    """The rule's own final confidences of logged windows (``window_confidence.window_confidence`` with the
    params ``p``: the first confidence read as the rule reads it, the logistic score, the tiny windows'
    cap). ``--fit`` compares the fitted weights with the rule's through this, like with like: the linear
    score alone leaves out the cap, which at 512x256 holds a tenth of the windows kept at 0.5 to at most
    0.6 and lowers the rule's AUC by 0.006-0.017 (docs/proposals.md "Fourteenth pass")."""
    from npsim_core.proposals.window_confidence import window_confidence

    return np.array([window_confidence(p, r["conf0"], r) for r in recs], float)


def fit_logistic(X: np.ndarray, y: np.ndarray, l2: float = 1e-3, iters: int = 30) -> np.ndarray:
    """Weights (bias first) of a logistic regression of ``y`` on ``X`` by Newton's method, a small ridge ``l2``."""
    A = np.column_stack([np.ones(len(X)), X])
    w = np.zeros(A.shape[1])
    for _ in range(iters):
        q = 1.0 / (1.0 + np.exp(-A @ w))
        w -= np.linalg.solve((A.T * (q * (1 - q))) @ A + l2 * np.eye(len(w)), A.T @ (q - y) + l2 * w)
    return w


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="512x256,2048x1024")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--variants", default="default,hard,lights")
    ap.add_argument("--fit", action="store_true", help="refit the window score's weights (module doc)")
    ap.add_argument("--held-out", default="3,4,5", help="with --fit: seeds the fit is checked on")
    ap.add_argument("--target", type=float, default=0.7, help="with --fit: IoU a window must reach")
    ap.add_argument("--raise", dest="raise_", type=float, default=1.0, help="with --fit: added to the bias")
    args = ap.parse_args(argv)
    if args.fit:
        return _fit(args)
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


def _fit(args) -> int:
    from npsim_cli.options import parse_size
    from npsim_core.proposals import ProposalParams
    from npsim_core.proposals.window_confidence import first_confidence
    from npsim_core.synthetic import street_scene

    p = ProposalParams()
    t0 = time.perf_counter()
    sizes = [s for s in args.sizes.split(",") if s]
    variants = [v for v in args.variants.split(",") if v]
    recs = {}
    for part, seeds in (("fit", args.seeds), ("held out", args.held_out)):
        for size in sizes:
            w, h = parse_size(size)
            got = [r for v in variants for s in (int(x) for x in seeds.split(",") if x)
                   for r in window_records(street_scene(w, h, s, v))]
            recs[part, size] = [r for r in got if first_confidence(p, r["conf0"], r) >= 0.5]
    train = [r for size in sizes for r in recs["fit", size]]
    wts = fit_logistic(design(train), np.array([r["iou"] >= args.target for r in train], float))
    bias = float(wts[0]) + args.raise_
    print(f"# Window score fit, {', '.join(variants)}, sizes {args.sizes}, seeds {args.seeds} (held out "
          f"{args.held_out}), target IoU >= {args.target}, bias raised by {args.raise_} "
          f"({time.perf_counter() - t0:.0f} s, load {os.getloadavg()[0]:.1f})\n")
    print(f"window_conf_bias = {bias:.2f}")
    print(f"window_conf_weights = ({', '.join(f'{v:.2f}' for v in wts[1:])})\n")
    print("| seeds | size | windows | AUC matched: now / fit | AUC clean: now / fit |")
    print("|---|---|---|---|---|")
    fitted = replace(p, window_conf_bias=bias, window_conf_weights=tuple(float(v) for v in wts[1:]))
    for (part, size), rs in recs.items():
        if not rs:
            continue
        s = rule_confidences(rs, fitted)  # the rule with the fitted weights, tiny cap and all
        now = np.array([r["conf"] for r in rs])
        iou = np.array([r["iou"] for r in rs])
        print(f"| {part} | {size} | {len(rs)} | {roc_auc(now, iou >= 0.5):.3f} / {roc_auc(s, iou >= 0.5):.3f} | "
              f"{roc_auc(now, iou >= 0.7):.3f} / {roc_auc(s, iou >= 0.7):.3f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
