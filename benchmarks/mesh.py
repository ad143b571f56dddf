"""Scene mesh: the thesis's three variants side by side, and error against face budget for reduction.

    .venv/bin/python benchmarks/mesh.py [--sizes 512x256,2048x1024] [--no-refine] [--no-pymeshlab]
                                        [--rules] [--render docs/img]

Table 1 (per size, synthetic street scene): ``raw`` (Worldsheet grid of the
predicted depth), ``filtered`` (grid of the cross-bilateral-filtered depth) and
``npsim`` (filtered -> U -> normal-guided refinement -> post-processing kernel; ``--no-refine``
skips the refinement).
Columns: faces; stretched faces (visible faces with longest edge > k times the
slant-corrected pixel footprint with k = 0.05 f, GT normals -- see npsim_core/mesh/quality.py);
edge-on faces (the walls closing depth steps: projected area ~0, no camera ray hits them); holes (boundary loops away from image border and sky); reprojection: fraction
of non-sky pixels whose ray-cast mesh depth is within 1 % of the depth the mesh
came from, and within 1 % of the ground-truth depth; face-normal error against
GT normals (mean angle of the face seen at each pixel, and fraction <= 11.25°);
meshing time (untraced run) and peak memory (tracemalloc, numpy buffers, second run).

Table 2: the quadtree reduction of the npsim mesh to face budgets (fraction of
its faces) against pymeshlab's quadric edge collapse at 10 %: faces, whether the
depth steps kept their fans and walls or were bridged to meet the budget, build
time, and the depth error each adds (ray-cast against the unreduced npsim mesh:
fraction of pixels within 1 %, mean relative error), holes.

``--rules`` adds table 3: the kernel's two choices side by side -- what U does
to *visible* vertices (the thesis replaces every U vertex by completed depth; the
default keeps visible depth) and what happens to depth steps left inside a sheet
(bridged by stretched faces, or cut and closed by edge-on walls, the default).

``--render DIR`` writes ``DIR/mesh_<variant>.png`` (label-coloured pyvista
off-screen renders of the 512x256 variants from a viewpoint beside the camera),
in a separate process under ``xvfb-run``.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:  # run as a script from the checkout
    sys.path.insert(0, str(ROOT))


def _size(s: str) -> tuple[int, int]:
    w, h = s.lower().split("x")
    return int(w), int(h)


def _load() -> str:
    try:
        return "load %.2f %.2f %.2f" % os.getloadavg()
    except OSError:
        return "load ?"


@dataclass
class DepthStages:
    """The depth maps along the chain (input, filtered, U, refined) and their times."""

    predicted: np.ndarray
    filtered: np.ndarray
    uncertain: np.ndarray
    refined: np.ndarray
    timings: dict


@dataclass
class MeshVariant:
    name: str
    mesh: object
    source_depth: np.ndarray
    seconds: float
    peak_mb: float
    result: object = None


def depth_stages(scene, refine: bool) -> DepthStages:
    """The chain's depth stages of ``scene`` (refinement skipped when ``refine`` is False)."""
    from npsim_core.chain import Chain, ChainParams

    res = Chain(scene).compute(ChainParams(), until="refine" if refine else "uncertain")
    refined = res.refine.depth if refine else res.filtered
    return DepthStages(res.depth_in, res.filtered, res.uncertain, refined,
                       {k: v for k, v in res.timings.items() if k != "geometry"})


def _timed(fn, track_memory: bool):
    """(result, seconds, peak MB). The time comes from an untraced run; with ``track_memory``
    a second run under tracemalloc (which slows numpy allocations) gives the peak."""
    import tracemalloc

    t = time.perf_counter()
    out = fn()
    sec = time.perf_counter() - t
    peak = 0.0
    if track_memory:
        tracemalloc.start()
        fn()
        peak = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    return out, sec, peak


def _light_ids(scene):
    return None if scene.lights is None else scene.lights.instance_map


def build_variants(scene, stages: DepthStages, *, track_memory: bool = False) -> dict:
    """The thesis's ``raw`` (grid of the input depth) and ``filtered`` baselines and the ``npsim`` mesh.
    ``seconds``/``peak_mb`` cover the meshing only."""
    from npsim_core.chain import ChainParams
    from npsim_core.mesh.grid import grid_mesh
    from npsim_core.mesh.postprocess import postprocess_mesh

    intr, labels, lights = scene.intrinsics, scene.labels, _light_ids(scene)
    pp = ChainParams().postprocess
    out = {}
    for name, d in (("raw", stages.predicted), ("filtered", stages.filtered)):
        m, sec, peak = _timed(lambda: grid_mesh(d, intr, labels, lights, far_limit=pp.far_limit), track_memory)
        out[name] = MeshVariant(name, m, d, sec, peak)
    r, sec, peak = _timed(lambda: postprocess_mesh(stages.refined, intr, labels, stages.uncertain, lights,
                                                   params=pp, normals=scene.normals), track_memory)
    out["npsim"] = MeshVariant("npsim", r.mesh, stages.refined, sec, peak, r)
    return out


def variants_table(scene, stages, refine: bool) -> tuple[list[str], dict]:
    from npsim_core.mesh.quality import mesh_quality, rasterize, reprojection_error

    intr = scene.intrinsics
    vs = build_variants(scene, stages, track_memory=True)
    rows = []
    for name, v in vs.items():
        ras = rasterize(v.mesh, intr)
        q = mesh_quality(v.mesh, intr, v.source_depth, scene.labels, scene.normals_gt, raster=ras)
        gt = reprojection_error(ras, scene.depth_gt, scene.labels)
        # The reprojection error's mean against the GT depth is the mesh's AbsRel (misses count 1).
        rows.append(f"| {name} | {q.faces:,} | {q.stretched:,} | {q.edge_on:,} | {q.holes} | "
                    f"{100 * q.reproj_within_1pct:.2f} % | "
                    f"{gt['mean']:.4f} | {q.normal_mean_deg:.2f}° | {100 * q.normal_within_11_25:.1f} % | "
                    f"{v.seconds:.2f} s | {v.peak_mb:,.0f} MB |")
    return rows, vs


def reduction_table(scene, npsim_variant, fractions, pymeshlab: bool) -> list[str]:
    from npsim_core.mesh.quality import count_holes, open_mask, rasterize, reprojection_error
    from npsim_core.mesh.reduce import ReduceParams, decimate_pymeshlab, reduce_mesh

    intr = scene.intrinsics
    full = npsim_variant.mesh
    ref = rasterize(full, intr).depth
    op = open_mask(scene.labels)
    rows = []
    for frac in fractions:
        budget = int(round(frac * full.n_faces))
        t = time.perf_counter()
        red = reduce_mesh(npsim_variant.result.layers, intr, ReduceParams(budget=budget))
        sec = time.perf_counter() - t
        rep = reprojection_error(rasterize(red.mesh, intr), ref, scene.labels)
        holes = sum(count_holes(p, intr, op) for p in red.mesh.parts)
        rows.append(f"| quadtree | {100 * frac:g} % | {red.mesh.n_faces:,} | {red.steps} | {sec:.2f} s | "
                    f"{100 * rep['within_tol']:.2f} % | {100 * rep['mean']:.3f} % | {holes} |")
        if pymeshlab and abs(frac - 0.1) < 1e-9:
            pm, psec = decimate_pymeshlab(full, budget)
            rep = reprojection_error(rasterize(pm, intr), ref, scene.labels)
            holes = sum(count_holes(p, intr, op) for p in pm.parts)
            rows.append(f"| pymeshlab QEC | {100 * frac:g} % | {pm.n_faces:,} | collapsed | {psec:.2f} s | "
                        f"{100 * rep['within_tol']:.2f} % | {100 * rep['mean']:.3f} % | {holes} |")
    return rows


def rules_table(scene, stages) -> list[str]:
    """Table 3: what U does to visible vertices (thesis rule / keep) x depth steps (bridged / cut + walls)."""
    from npsim_core.mesh.postprocess import PostprocessParams, postprocess_mesh
    from npsim_core.mesh.quality import mesh_quality, rasterize

    intr = scene.intrinsics
    rows = []
    for name, kc in (("thesis rule: U vertices replaced", None), ("visible vertices keep depth (default)", np.inf)):
        for cut in (None, PostprocessParams().step_cut):
            t = time.perf_counter()
            r = postprocess_mesh(stages.refined, intr, scene.labels, stages.uncertain, _light_ids(scene),
                                 params=PostprocessParams(keep_consistent=kc, step_cut=cut), normals=scene.normals)
            sec = time.perf_counter() - t
            q = mesh_quality(r.mesh, intr, stages.refined, scene.labels, scene.normals_gt,
                             raster=rasterize(r.mesh, intr))
            steps = "cut + walls" if cut else "bridged"
            rows.append(f"| {name} | {steps} | {q.faces:,} | {q.stretched:,} | {q.edge_on:,} | {q.holes} | "
                        f"{100 * q.reproj_within_1pct:.2f} % | {q.normal_mean_deg:.2f}° | {sec:.2f} s |")
    return rows


def render_variants(vs: dict, labels_shape, out_dir: Path) -> None:
    """Export the variants as PLY and render them in a child process under xvfb-run."""
    from npsim_core.mesh.export import export_ply

    tmp = Path(tempfile.mkdtemp(prefix="npsim_mesh_render_"))
    try:
        for name, v in vs.items():
            export_ply(v.mesh, tmp / f"{name}.ply")
        cmd = [sys.executable, str(Path(__file__).resolve()), "--render-child", str(tmp), str(out_dir)]
        if shutil.which("xvfb-run") and not os.environ.get("DISPLAY"):
            cmd = ["xvfb-run", "-a", "-s", "-screen 0 1280x1024x24"] + cmd
        subprocess.run(cmd, check=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def _render_child(src: Path, out_dir: Path) -> None:
    """Runs in its own process: pyvista off-screen render of each PLY, faces coloured by label."""
    import pyvista as pv
    import trimesh

    from npsim_core.labels import cityscapes

    lut = cityscapes().color_lut()
    out_dir.mkdir(parents=True, exist_ok=True)
    for ply in sorted(src.glob("*.ply")):
        t = trimesh.load(ply, process=False)
        face = t.metadata["_ply_raw"]["face"]["data"]
        lab = np.asarray(face["label"]).ravel()
        part = np.asarray(face["part"]).ravel()
        f = np.asarray(t.faces)
        cells = np.hstack([np.full((len(f), 1), 3), f]).ravel()
        mesh = pv.PolyData(np.asarray(t.vertices), cells)
        rgb = lut[lab].astype(np.float32)
        # Shade foreground objects a little lighter so separate sheets are visible.
        rgb[part > 0] = np.minimum(rgb[part > 0] * 1.15 + 20, 255)
        mesh.cell_data["rgb"] = rgb.astype(np.uint8)
        pl = pv.Plotter(off_screen=True, window_size=(1200, 700))
        pl.set_background("white")
        pl.add_mesh(mesh, scalars="rgb", rgb=True, show_edges=False, lighting=True)
        # Camera frame is OpenCV (y down): look from beside and above the camera toward the street.
        pl.camera.position = (-7.0, -3.5, 2.0)
        pl.camera.focal_point = (0.0, 0.0, 18.0)
        pl.camera.up = (0.0, -1.0, 0.0)
        pl.camera.view_angle = 60
        pl.add_text(ply.stem, font_size=14, color="black")
        pl.screenshot(str(out_dir / f"mesh_{ply.stem}.png"))
        pl.close()


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", default="512x256,2048x1024")
    ap.add_argument("--fractions", default="0.25,0.1,0.05", help="face budgets as fractions of the npsim mesh")
    ap.add_argument("--no-refine", action="store_true",
                    help="skip the normal-guided refinement in the npsim variant (~40 s at 2048x1024 here)")
    ap.add_argument("--no-pymeshlab", action="store_true")
    ap.add_argument("--rules", action="store_true",
                    help="add table 3: thesis rule vs keeping visible depth, steps bridged vs cut + walls")
    ap.add_argument("--render", default=None, help="write mesh_<variant>.png pictures of the first size here")
    ap.add_argument("--render-child", nargs=2, default=None, help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.render_child:
        _render_child(Path(args.render_child[0]), Path(args.render_child[1]))
        return 0

    from npsim_core.synthetic import street_scene

    fractions = [float(x) for x in args.fractions.split(",") if x.strip()]
    print(f"# mesh benchmark ({_load()}, {os.cpu_count()} cores)")
    for k, size in enumerate(args.sizes.split(",")):
        W, H = _size(size)
        scene = street_scene(W, H)
        refine = not args.no_refine
        t = time.perf_counter()
        stages = depth_stages(scene, refine)
        st = ", ".join(f"{a} {b:.2f} s" for a, b in stages.timings.items())
        print(f"\n## {W}x{H}  (depth stages: {st}{'' if refine else '; refinement skipped'})\n")
        print("| variant | faces | stretched | edge-on | holes | reproj ≤1 % (source) | AbsRel vs GT | "
              "normal err | ≤11.25° | mesh time | peak mem |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        rows, vs = variants_table(scene, stages, refine)
        print("\n".join(rows), flush=True)
        if args.rules:
            print(f"\nThe kernel's choices at {W}x{H} (npsim mesh, {_load()}):\n")
            print("| visible U vertices | depth steps in a sheet | faces | stretched | edge-on | holes | "
                  "reproj ≤1 % (source) | normal err | kernel time |")
            print("|---|---|---|---|---|---|---|---|---|")
            print("\n".join(rules_table(scene, stages)), flush=True)
        if args.render and k == 0:
            render_variants(vs, scene.labels.shape, Path(args.render))
            print(f"\nrendered {', '.join(f'mesh_{n}.png' for n in vs)} to {args.render}")
        if not fractions:
            continue
        print(f"\nReduction of the npsim mesh ({vs['npsim'].mesh.n_faces:,} faces) at {W}x{H}, {_load()}:\n")
        print("| method | budget | faces | depth steps | build time | ≤1 % of full mesh depth | mean depth error | "
              "holes |")
        print("|---|---|---|---|---|---|---|---|")
        print("\n".join(reduction_table(scene, vs["npsim"], fractions, not args.no_pymeshlab)), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
