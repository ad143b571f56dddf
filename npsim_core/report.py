"""HTML reports of a batch or a sweep output folder (``npsim report OUT``).

A batch folder (``batch.json``): the run's summary, a table of every frame (status, time,
depth source, scores against its reference, nights) with thumbnails of its first night and
refined depth, failed frames with their reasons, and the light statistics -- instances and
pixels per light class on a log scale, as the thesis's Figure 3.2. A sweep folder
(``sweep.json``): the table of λ cells and the contact sheet. Pictures are linked, not
copied: the page lives in the folder it describes.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path

import numpy as np

from .errors import NpsimInputError

__all__ = ["write_report", "light_statistics"]

_CSS = """body{font-family:sans-serif;margin:24px;color:#222}table{border-collapse:collapse;font-size:13px}
td,th{border:1px solid #ccc;padding:3px 6px;text-align:right}th{background:#f0f0f0}td.l{text-align:left}
.failed{color:#b00}img.t{width:192px}h2{margin-top:28px}"""


def _f(x, fmt: str = "{:.3f}") -> str:
    return "–" if x is None or (isinstance(x, float) and not math.isfinite(x)) else fmt.format(x)


def light_statistics(frame_folders: list[Path]) -> dict[str, dict[str, int]]:
    """Instances and pixels per light class over the ``*_lights_instanceIds.png`` of the folders."""
    from .io import imread
    from .labels import light_class

    inst: dict[int, int] = {}
    pix: dict[int, int] = {}
    for folder in frame_folders:
        for p in folder.glob("*_lights_instanceIds.png"):
            try:
                ids = imread(p)
            except NpsimInputError:  # a damaged file: the frame's verification reports it
                ids = None
            if ids is None:
                continue
            ids = ids.astype(np.int64)
            vals, counts = np.unique(ids[ids > 0], return_counts=True)
            for v, c in zip(vals, counts):
                cls = int(v) // 1000
                inst[cls] = inst.get(cls, 0) + 1
                pix[cls] = pix.get(cls, 0) + int(c)
    return {light_class(c).name: {"instances": inst[c], "pixels": pix[c]} for c in sorted(inst)}


def _bars_svg(stats: dict[str, dict[str, int]]) -> str:
    """Two horizontal bar series per class (instances, pixels) on a log10 axis, as SVG."""
    names = list(stats)
    top = max(max(v["pixels"] for v in stats.values()), 10)
    decades = max(1, math.ceil(math.log10(top)))
    w, left, row = 560, 150, 26
    height = row * len(names) + 40
    x = lambda v: left + (w - left - 10) * (math.log10(max(v, 1)) / decades)  # noqa: E731
    out = [f'<svg width="{w}" height="{height}" xmlns="http://www.w3.org/2000/svg" font-size="11">']
    for d in range(decades + 1):
        xx = x(10 ** d)
        out.append(f'<line x1="{xx:.0f}" y1="0" x2="{xx:.0f}" y2="{height - 20}" stroke="#ddd"/>'
                   f'<text x="{xx:.0f}" y="{height - 6}" text-anchor="middle">1e{d}</text>')
    for i, n in enumerate(names):
        y = i * row + 4
        out.append(f'<text x="{left - 6}" y="{y + 13}" text-anchor="end">{html.escape(n)}</text>')
        out.append(f'<rect x="{left}" y="{y}" width="{x(stats[n]["instances"]) - left:.1f}" height="9" '
                   f'fill="#4a7bd0"><title>{stats[n]["instances"]} instances</title></rect>')
        out.append(f'<rect x="{left}" y="{y + 10}" width="{x(stats[n]["pixels"]) - left:.1f}" height="9" '
                   f'fill="#e0a030"><title>{stats[n]["pixels"]} pixels</title></rect>')
    out.append("</svg>")
    return "".join(out)


def frame_check(folder: Path) -> tuple[str, str, dict]:
    """Verify one frame's output folder as ``npsim batch --skip-existing`` does (manifest, every file
    it lists, checksums; :func:`npsim_core.chain.export.verify_frame`): (status, reason, manifest).
    Status is ``done`` (complete), ``missing`` (no folder or no manifest) or ``corrupt`` (a listed
    file gone or changed)."""
    from .chain.export import verify_frame

    if not folder.is_dir():
        return "missing", "the frame's folder is gone", {}
    why = verify_frame(folder)
    man: dict = {}
    for p in sorted(folder.glob("*_export.json"))[:1]:
        try:
            man = json.loads(p.read_text())
        except (OSError, ValueError):
            man = {}
    if why is None:
        return "done", "", man
    return ("missing" if why == "no manifest" else "corrupt"), why, man


def lit_by(manifest: dict) -> str:
    """What lit a frame's nights, from its export manifest: proposals, hand annotation, a file or none."""
    lights = manifest.get("lights") or {}
    src, n = lights.get("source"), lights.get("count", 0)
    names = {"proposed": "proposals", "annotation": "hand annotation", "file": "annotation file"}
    if src in names:
        return f"{names[src]} ({n} light{'s' if n != 1 else ''})"
    if src == "none":
        return "none (ego headlights and sky)"
    return "–"


def realism_table(manifests: dict[str, dict]) -> list[str]:
    """HTML rows of night 0's realism per frame (structure ratio, global statistics; docs/relight.md
    "Realism"), with real night photos' statistics for comparison; [] when no manifest has them."""
    from .realism import CLASSES, REAL_NIGHT

    rows = []
    for name, man in manifests.items():
        r = ((man.get("nights") or [{}])[0] or {}).get("realism") or {}
        if not r:
            continue
        st, sr = r.get("stats") or {}, r.get("structure") or {}
        cls = sr.get("classes") or {}
        rows.append(f"<tr><td class=l>{html.escape(name)}</td><td>{_f(sr.get('whole'), '{:.2f}')}</td>"
                    + "".join(f"<td>{_f(cls.get(c), '{:.2f}')}</td>" for c in CLASSES)
                    + "".join(f"<td>{_f(st.get(k), '{:.2f}')}</td>" for k in REAL_NIGHT) + "</tr>")
    if not rows:
        return []
    head = ("<h2>Realism of night 0</h2><p>Structure ratio: mid-frequency structure of the night over the day's "
            "(published day-to-night methods 0.75-1.45; streaks and speckle raise it). Global statistics: grey "
            "levels at 1024 px wide; real night photos in the last row.</p><table><tr><th>frame</th><th>whole</th>"
            + "".join(f"<th>{html.escape(c)}</th>" for c in CLASSES)
            + "<th>mean</th><th>median</th><th>p99</th><th>% &gt; 240</th><th>R/B lit</th></tr>")
    real = ("<tr><td class=l>real night photos</td>" + "<td></td>" * (1 + len(CLASSES))
            + "".join(f"<td>{v:.2f}</td>" for v in REAL_NIGHT.values()) + "</tr>")
    return [head] + rows + [real, "</table>"]


def _batch_page(folder: Path, doc: dict) -> str:
    frames = doc.get("frames", {})
    checks = {k: frame_check(folder / k) for k, v in frames.items() if v.get("status") in ("done", "skipped")}
    done = [k for k, c in checks.items() if c[0] == "done"]
    lost = {k: c for k, c in checks.items() if c[0] != "done"}
    failed = {k: v for k, v in frames.items() if v.get("status") == "failed"}
    lit = {k: lit_by(c[2]) for k, c in checks.items() if c[0] == "done"}
    parts = [f"<h1>NPSim batch: {html.escape(str(doc.get('inputs', {}).get('dataset', folder)))}</h1>",
             f"<p>{len(frames)} frames recorded: {len(done)} done (files and checksums verified), "
             f"{sum(c[0] == 'missing' for c in lost.values())} missing, "
             f"{sum(c[0] == 'corrupt' for c in lost.values())} corrupt, {len(failed)} failed; {doc.get('nights')} "
             f"night(s) each; {doc.get('workers')} worker(s){' on Ray ' + html.escape(doc['ray']) if doc.get('ray') else ''};"
             f" updated {html.escape(str(doc.get('updated', '')))}.</p>",
             "<h2>Frames</h2><table><tr><th>frame</th><th>status</th><th>s</th><th>depth source</th><th>lit by</th>"
             "<th>reference</th>"
             "<th>AbsRel in</th><th>AbsRel refined</th><th>δ1</th><th>normal RMSE °</th><th>nights</th>"
             "<th>night 0</th><th>refined depth</th></tr>"]
    for name, f in frames.items():
        sc = f.get("scores") or {}
        ref, inp, refd = sc.get("reference", "–"), sc.get("input", {}), sc.get("refined", {})
        sub = folder / name
        night = next(iter(sorted(sub.glob("*_night_0.png"))), None) if sub.is_dir() else None
        depth = next(iter(sorted(sub.glob("*_depth_refined_vis.png"))), None) if sub.is_dir() else None
        img = lambda p: f'<img class="t" src="{html.escape(str(p.relative_to(folder)))}">' if p else ""  # noqa: E731
        status = lost[name][0] if name in lost else f.get("status", "")
        cls = ' class="failed"' if status in ("failed", "missing", "corrupt") else ""
        parts.append(f"<tr{cls}><td class=l>{html.escape(name)}</td><td>{html.escape(status)}</td>"
                     f"<td>{_f(f.get('seconds'), '{:.1f}')}</td><td class=l>{html.escape(f.get('depth_source', ''))}</td>"
                     f"<td class=l>{html.escape(lit.get(name, '–'))}</td>"
                     f"<td class=l>{html.escape(ref)}</td><td>{_f(inp.get('abs_rel'), '{:.4f}')}</td>"
                     f"<td>{_f(refd.get('abs_rel'), '{:.4f}')}</td><td>{_f(refd.get('delta1'))}</td>"
                     f"<td>{_f(refd.get('normal_rmse_deg'), '{:.1f}')}</td><td>{len(f.get('nights', []))}</td>"
                     f"<td>{img(night)}</td><td>{img(depth)}</td></tr>")
    parts.append("</table>")
    parts += realism_table({k: c[2] for k, c in checks.items() if c[0] == "done"})
    if failed:
        parts.append("<h2>Failed frames</h2><ul>" + "".join(
            f"<li class=failed><b>{html.escape(k)}</b>: {html.escape(v.get('error', ''))}</li>"
            for k, v in failed.items()) + "</ul>")
    if lost:
        parts.append("<h2>Missing or corrupt frames</h2><p>Recorded as done, but their outputs do not verify "
                     "(rerun the batch: these frames are recomputed).</p><ul>" + "".join(
                         f"<li class=failed><b>{html.escape(k)}</b>: {c[0]}: {html.escape(c[1])}</li>"
                         for k, c in lost.items()) + "</ul>")
    times = [v.get("seconds", 0.0) for k, v in frames.items() if k in done]
    if times:
        parts.append(f"<p>Time per frame: mean {np.mean(times):.1f} s, min {min(times):.1f} s, max {max(times):.1f} s."
                     "</p>")
    stats = light_statistics([folder / k for k in done if (folder / k).is_dir()])
    parts.append("<h2>Light sources</h2>")
    if stats:
        parts.append("<p>Instances (blue) and pixels (orange) per light class, log scale.</p>" + _bars_svg(stats))
        parts.append("<table><tr><th>class</th><th>instances</th><th>pixels</th></tr>" + "".join(
            f"<tr><td class=l>{html.escape(k)}</td><td>{v['instances']}</td><td>{v['pixels']}</td></tr>"
            for k, v in stats.items()) + "</table>")
    kinds: dict[str, int] = {}
    for v in lit.values():
        kinds[v.split(" (")[0]] = kinds.get(v.split(" (")[0], 0) + 1
    said = ", ".join(f"{n} frame{'s' if n != 1 else ''} by {k}" for k, n in sorted(kinds.items()))
    if not stats:
        if set(kinds) <= {"none"}:
            parts.append("<p>No light sources in these frames: the nights are lit by the ego headlights and the sky "
                         "only.</p>")
        else:  # proposals are not written as annotation files: the statistics above cover only those
            parts.append(f"<p>No light annotation files in these frames; the nights were lit by: {html.escape(said)}."
                         "</p>")
    elif said:
        parts.append(f"<p>Lit by: {html.escape(said)}.</p>")
    return "".join(parts)


def _sweep_page(folder: Path, doc: dict) -> str:
    cells = doc.get("cells", [])
    parts = [f"<h1>NPSim λ sweep: {html.escape(str(doc.get('frame', folder)))}</h1>",
             f"<p>{len(cells)} cells, scored against {html.escape(str(doc.get('reference')))}.</p>"]
    if (folder / "contact_sheet.png").exists():
        parts.append('<h2>Contact sheet</h2><img src="contact_sheet.png" style="max-width:100%">')
    cols = ["l1", "l2", "l3", "loss", "loss_normal", "loss_continuity", "loss_depth", "seconds", "abs_rel",
            "delta1", "normal_rmse_deg", "normal_median_deg"]
    parts.append("<h2>Cells</h2><table><tr>" + "".join(f"<th>{c}</th>" for c in cols) + "</tr>")
    scored = [c for c in cells if isinstance(c.get("normal_rmse_deg"), float) and math.isfinite(c["normal_rmse_deg"])]
    best = min(scored, key=lambda c: c["normal_rmse_deg"]) if scored else None
    for c in cells:
        style = ' style="background:#e8f4e0"' if c is best else ""
        parts.append(f"<tr{style}>" + "".join(f"<td>{_f(c.get(k), '{:.4g}')}</td>" for k in cols) + "</tr>")
    parts.append("</table>")
    return "".join(parts)


def write_report(folder: str | Path) -> Path:
    """Write ``folder/report.html`` for a batch or sweep output folder; returns its path."""
    from .io import atomic_write_text

    folder = Path(folder)
    if not folder.is_dir():
        raise NpsimInputError(f"{folder}: not a folder; give the output folder of 'npsim batch' or 'npsim sweep'")
    for name, page in (("batch.json", _batch_page), ("sweep.json", _sweep_page)):
        p = folder / name
        if p.is_file():
            try:
                doc = json.loads(p.read_text())
            except (OSError, ValueError) as exc:
                raise NpsimInputError(f"{p}: unreadable ({exc})") from None
            body = page(folder, doc)
            break
    else:
        raise NpsimInputError(f"{folder}: holds neither batch.json nor sweep.json; give the output folder of "
                              "'npsim batch' or 'npsim sweep'")
    out = folder / "report.html"
    atomic_write_text(out, f"<!doctype html><html><head><meta charset='utf-8'><title>NPSim report</title>"
                           f"<style>{_CSS}</style></head><body>{body}</body></html>\n")
    return out
