"""GUI latency: from a slider change to the updated views, and event-loop stalls.

Run under Xvfb (the 3D view needs a display)::

    xvfb-run -a -s "-screen 0 1920x1080x24" .venv/bin/python benchmarks/gui_latency.py [--size 512x256]

Measures, on the synthetic scene:
* λ change  -> pipeline result shown (canvas + 3D mesh) and -> first night-preview frame;
* σs change -> the same;
* the longest gap between 10 ms heartbeat timers while a full-resolution (2048x1024)
  recompute runs in the worker (the event loop must never block for > 100 ms).
Targets (the app-latency goals in the README): λ change <= 0.5 s, filter change <= 1 s at 512x256; stalls <= 100 ms.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--size", default="512x256")
    ap.add_argument("--full-size", default="2048x1024", help="size of the stall measurement ('' to skip)")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args(argv)
    from PySide6.QtCore import QElapsedTimer, QTimer
    from PySide6.QtWidgets import QApplication

    from npsim_cli.options import parse_size
    from npsim_core.synthetic import street_scene
    from npsim_core.chain import ChainParams
    from npsim_gui.main_window import MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    w, h = parse_size(args.size)
    scene = street_scene(w, h)
    win = MainWindow()
    win.ask = lambda *a: "Discard"
    win.show()

    def wait(cond, timeout=600.0) -> float:
        t0 = time.perf_counter()
        while not cond():
            app.processEvents()
            time.sleep(0.002)
            if time.perf_counter() - t0 > timeout:
                raise TimeoutError("timed out")
        return time.perf_counter() - t0

    win.set_scene(scene, ChainParams())
    t_first = wait(lambda: win.results is not None and win.render_panel.night is not None)
    print(f"# GUI latency, synthetic scene {w}x{h}, load {os.getloadavg()[0]:.1f}")
    print(f"first open (all stages + first preview frame): {t_first:.2f} s")
    rows = []
    for what, section, field, values in (("λ2 change", "refine", "lambda2", [3.0, 7.0, 5.0]),
                                         ("σs change", "filter", "sigma_s", [8.0, 12.0, 10.0])):
        for v in values[: args.repeats]:
            before_res = win.results
            frames, live = [], []
            win.render_jobs.progress.connect(lambda f, fr=frames: fr.append(time.perf_counter()))
            # the quick view: a live (proxy on large frames) result reaching the canvas, or the full one
            win.pipeline_jobs.progress.connect(
                lambda info, lv=live: lv.append(time.perf_counter()) if isinstance(info, dict)
                and "live_results" in info else None)
            t0 = time.perf_counter()
            win.params_panel.sliders[(section, field)].spin.setValue(v)  # as typed by the user
            wait(lambda: bool(live) or win.results is not before_res)
            app.processEvents()
            t_view = (live[0] if live else time.perf_counter()) - t0
            wait(lambda: getattr(win, "results_final", False) and not win.pipeline_jobs.is_busy)
            t_full = time.perf_counter() - t0
            frames.clear()  # frames of a render started before the full results are stale
            wait(lambda: len(frames) > 0)
            t_frame = frames[0] - t0
            wait(lambda: not win.render_jobs.is_busy)
            win.render_jobs.progress.disconnect()
            win.pipeline_jobs.progress.disconnect()
            win.pipeline_jobs.progress.connect(win.on_pipeline_progress)
            rows.append((what, v, t_view, t_frame, t_full, ", ".join(win.results.recomputed),
                         win.results.timings.get("refine", 0.0)))
    print("\n| change | value | → quick views (s) | → full refinement, mesh, 3D shown (s) | → first night frame (s) "
          "| recomputed (full) | full refine (s) |")
    print("|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:g} | {r[2]:.2f} | {r[4]:.2f} | {r[3]:.2f} | {r[5]} | {r[6]:.2f} |")
    for what in ("λ2 change", "σs change"):
        vals = [r[2] for r in rows if r[0] == what]
        print(f"{what}: median change→quick views {np.median(vals):.2f} s")

    if args.full_size:
        fw, fh = parse_size(args.full_size)
        big = street_scene(fw, fh)
        gaps: list[float] = []
        timer = QElapsedTimer()
        timer.start()
        last = [timer.elapsed()]

        def beat() -> None:
            now = timer.elapsed()
            gaps.append(now - last[0])
            last[0] = now
        hb = QTimer()
        hb.setInterval(10)
        hb.timeout.connect(beat)
        hb.start()
        t0 = time.perf_counter()
        win.set_scene(big, ChainParams())
        wait(lambda: win.results is not None and win.results.scene is big, timeout=900)
        t_quick = time.perf_counter() - t0
        wait(lambda: win.results.scene is big and win.results_final and not win.pipeline_jobs.is_busy, timeout=900)
        t_pipe = time.perf_counter() - t0
        wait(lambda: not win.render_jobs.is_busy and win.render_panel.night is not None, timeout=900)
        hb.stop()
        g = np.array(gaps[1:])
        print(f"\nfull-resolution {fw}x{fh}: quick views {t_quick:.1f} s, full pipeline {t_pipe:.1f} s, "
              f"until the night preview is done "
              f"{time.perf_counter() - t0:.1f} s; event-loop gap max {g.max():.0f} ms, "
              f"p99 {np.percentile(g, 99):.0f} ms, gaps > 100 ms: {(g > 100).sum()} of {len(g)}")
    win.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
