"""The λ grid search (docs/method.md §3.3; the thesis's appendix B): one refinement per
(λ1, λ2, λ3) cell, in parallel, scored against the frame's reference, with a contact sheet.

The default grid is appendix B's: λ1 = 1 and λ2, λ3 each in {1e-3, 1e-2, ..., 1e3} (49 cells).
Each cell's filter and uncertain map are the same (they do not depend on λ); every worker
computes them once and keeps them cached for all the cells it runs.
"""

from __future__ import annotations

import itertools
import os
import time
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Callable

import cv2
import numpy as np

from ..errors import NpsimInputError
from .params import ChainParams

__all__ = ["APPENDIX_B", "SweepCell", "run_sweep", "contact_sheet", "write_sweep"]

APPENDIX_B = (10.0 ** np.arange(-3, 4)).tolist()


@dataclass
class SweepCell:
    """One λ cell: the weights, the final loss and its unweighted terms, seconds, the scores of the
    refined depth against the frame's reference, and small depth and normal pictures."""

    lambdas: tuple[float, float, float]
    loss: float
    terms: dict
    seconds: float
    scores: dict
    depth_thumb: np.ndarray
    normals_thumb: np.ndarray
    diverged: bool = False

    def row(self) -> dict:
        r = self.scores.get("refined", {})
        return {"l1": self.lambdas[0], "l2": self.lambdas[1], "l3": self.lambdas[2], "loss": self.loss,
                **{f"loss_{k}": v for k, v in self.terms.items()}, "seconds": self.seconds,
                "abs_rel": r.get("abs_rel", float("nan")), "delta1": r.get("delta1", float("nan")),
                "rmse_m": r.get("rmse_m", float("nan")), "normal_rmse_deg": r.get("normal_rmse_deg", float("nan")),
                "normal_median_deg": r.get("normal_median_deg", float("nan")), "diverged": self.diverged}


_CHAINS: dict = {}  # per worker process: the frame's chain, so filter and U are computed once


def _cell(frame_key: tuple, params: ChainParams, lambdas: tuple, thumb_w: int, scene=None) -> SweepCell:
    from ..camera import normals_from_depth
    from ..io import depth_to_rgb, normals_to_rgb
    from .chain import Chain
    from .export import frame_errors
    from .session import load_frame

    if frame_key not in _CHAINS:
        _CHAINS.clear()
        _CHAINS[frame_key] = Chain(scene if scene is not None else load_frame(frame_key[0], hfov_deg=frame_key[1]))
    chain = _CHAINS[frame_key]
    res = chain.compute(params.with_lambdas(*lambdas), until="refine")
    r = res.refine
    h = {k: float(np.asarray(r.history[k])[r.best_step]) for k in ("normal", "continuity", "depth")
         if k in r.history and len(r.history[k])}
    H, W = res.depth.shape
    size = (thumb_w, max(1, round(thumb_w * H / W)))
    vmax = float(np.nanpercentile(res.depth_in, 99)) if np.isfinite(res.depth_in).any() else None
    dthumb = cv2.resize(depth_to_rgb(res.depth, vmax), size, interpolation=cv2.INTER_AREA)
    nthumb = cv2.resize(normals_to_rgb(normals_from_depth(res.depth, res.intrinsics)), size,
                        interpolation=cv2.INTER_AREA)
    return SweepCell(tuple(float(x) for x in lambdas), float(r.final_loss), h, float(res.timings["refine"]),
                     frame_errors(chain, res, params.depth.stereo_max_m), dthumb, nthumb, bool(r.diverged))


def run_sweep(frame: str | Path, params: ChainParams, grid: list[tuple[float, float, float]], *,
              workers: int = 1, hfov_deg: float | None = None, thumb_width: int = 160, scene=None,
              log: Callable[[str], None] = lambda m: None) -> list[SweepCell]:
    """Refine ``frame`` once per λ cell of ``grid`` (``workers`` local processes); cells in grid order.
    ``scene`` (a loaded frame) is used instead of reading ``frame`` when given (in-process only)."""
    if not grid:
        raise NpsimInputError("the λ grid is empty")
    if workers < 1:
        raise NpsimInputError(f"workers must be >= 1, got {workers}")
    key = (str(frame), hfov_deg) if scene is None else (str(frame), hfov_deg, id(scene))
    t0 = time.perf_counter()
    cells: list[SweepCell] = []
    if workers == 1 or scene is not None:
        for i, lam in enumerate(grid):
            cells.append(_cell(key, params, lam, thumb_width, scene))
            log(f"[{i + 1}/{len(grid)}] λ = {lam}: {cells[-1].seconds:.1f} s")
        return cells
    import multiprocessing

    from .batch import _worker_init

    threads = max(1, (os.cpu_count() or 1) // workers)
    with ProcessPoolExecutor(max_workers=workers, mp_context=multiprocessing.get_context("spawn"),
                             initializer=_worker_init, initargs=(threads,)) as pool:
        futures = [pool.submit(_cell, key, params, lam, thumb_width) for lam in grid]
        for i, fut in enumerate(futures):
            cells.append(fut.result())
            log(f"[{i + 1}/{len(grid)}] λ = {grid[i]}: {cells[-1].seconds:.1f} s "
                f"({time.perf_counter() - t0:.0f} s so far)")
    return cells


def contact_sheet(cells: list[SweepCell], *, title: str = "") -> np.ndarray:
    """One tile per cell -- refined depth over its normals, labelled by λ and its error --
    rows by λ2, columns by λ3 (λ1 in the label when it varies). (H, W, 3) uint8."""
    l2s = sorted({c.lambdas[1] for c in cells})
    l3s = sorted({c.lambdas[2] for c in cells})
    l1s = sorted({c.lambdas[0] for c in cells})
    th, tw = cells[0].depth_thumb.shape[:2]
    label_h, pad = 30, 4
    tile_h, tile_w = 2 * th + label_h, tw
    top = 28 if title else 0
    rows, cols = len(l2s) * len(l1s), len(l3s)
    sheet = np.full((top + rows * (tile_h + pad) + pad, cols * (tile_w + pad) + pad, 3), 255, np.uint8)
    if title:  # shrunk to fit the sheet's width
        (tw0, _), _ = cv2.getTextSize(title, cv2.FONT_HERSHEY_SIMPLEX, 0.55, 1)
        scale = min(0.55, 0.55 * (sheet.shape[1] - 2 * pad) / max(tw0, 1))
        cv2.putText(sheet, title, (pad, 20), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    for c in cells:
        r = l1s.index(c.lambdas[0]) * len(l2s) + l2s.index(c.lambdas[1])
        k = l3s.index(c.lambdas[2])
        y, x = top + pad + r * (tile_h + pad), pad + k * (tile_w + pad)
        sheet[y + label_h:y + label_h + th, x:x + tw] = c.depth_thumb
        sheet[y + label_h + th:y + label_h + 2 * th, x:x + tw] = c.normals_thumb
        lam = f"l = {c.lambdas[0]:g}, {c.lambdas[1]:g}, {c.lambdas[2]:g}"
        ref = c.scores.get("refined", {})
        err = f"{ref.get('normal_rmse_deg', float('nan')):.1f}deg {ref.get('abs_rel', float('nan')):.3f}"
        cv2.putText(sheet, lam, (x + 2, y + 12), cv2.FONT_HERSHEY_SIMPLEX, 0.38, (0, 0, 0), 1, cv2.LINE_AA)
        cv2.putText(sheet, err + (" DIV" if c.diverged else ""), (x + 2, y + 26), cv2.FONT_HERSHEY_SIMPLEX, 0.38,
                    (160, 0, 0) if c.diverged else (60, 60, 60), 1, cv2.LINE_AA)
    return sheet


def write_sweep(cells: list[SweepCell], out: str | Path, *, frame: str, params: ChainParams) -> list[Path]:
    """``out/sweep.csv``, ``out/sweep.json`` (rows, reference, parameters) and ``out/contact_sheet.png``."""
    from ..io import atomic_write_text, write_image, write_json
    from .export import check_output_folder, versions

    out = check_output_folder(out)
    rows = [c.row() for c in cells]
    keys = list(rows[0])
    csv = ",".join(keys) + "\n" + "\n".join(",".join(f"{r[k]:.6g}" if isinstance(r[k], float) else str(r[k])
                                                      for k in keys) for r in rows) + "\n"
    atomic_write_text(out / "sweep.csv", csv)
    ref = next((c.scores.get("reference") for c in cells if c.scores), "none (not scored)")
    write_json(out / "sweep.json", {"format": "npsim-sweep", "frame": frame, "reference": ref,
                                    "params": params.to_json(), "cells": rows, "versions": versions()})
    write_image(out / "contact_sheet.png",
                contact_sheet(cells, title=f"{Path(frame).stem}: depth / normals per (l1, l2, l3); normal RMSE, "
                                           f"AbsRel vs {ref}"))
    return [out / "sweep.csv", out / "sweep.json", out / "contact_sheet.png"]


def parse_grid(l1: str, l2: str, l3: str) -> list[tuple[float, float, float]]:
    """The product of three comma-separated lists of finite λ >= 0."""
    def values(text: str, name: str) -> list[float]:
        try:
            vals = [float(x) for x in text.split(",") if x.strip()]
        except ValueError:
            raise NpsimInputError(f"--{name} {text!r}: give comma-separated numbers") from None
        if not vals or not all(0 <= v < float("inf") for v in vals):
            raise NpsimInputError(f"--{name}: need at least one value, all finite and >= 0")
        return vals

    return list(itertools.product(values(l1, "lambda1"), values(l2, "lambda2"), values(l3, "lambda3")))
