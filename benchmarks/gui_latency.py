"""GUI latency on Cityscapes-layout frames: open, slider, brush stroke, memory and event-loop stalls.

Run under Xvfb (the 3D view needs a display)::

    xvfb-run -a -s "-screen 0 1600x900x24" .venv/bin/python -m benchmarks.gui_latency [--sizes 512x256,2048x1024]
    xvfb-run -a -s "-screen 0 1600x900x24" .venv/bin/python -m benchmarks.gui_latency --frame X_leftImg8bit.png

For each size a two-frame Cityscapes-layout fixture (``npsim_core.synthetic.cityscapes``: image,
labelIds, stereo disparity and camera JSON, no NPSim file) is written to a temporary folder and
the app is driven as a user would:

* **open → canvas shown**: ``File > Open dataset image`` of frame 0 until the editor canvas shows it;
* **open → full pipeline / night preview**: until the full-resolution mesh and the first complete
  night preview are shown (both in workers);
* **slider → quick view**: a λ2 change (typed into the spin box, as a user would) until the
  quick view (proxy resolution on frames wider than ``MainWindow.PROXY_WIDTH``) reaches the
  canvas; changes are 1.5 s apart, as when trying values, so full-resolution runs get cancelled;
* **brush stroke → canvas**: one mouse event of a brush stroke (press, 20 moves, release) until
  the canvas has repainted (median and max over the events);
* **peak RSS**: the process's peak resident memory (``VmHWM``, reset when the frame is opened)
  while the frame is opened, its full-resolution mesh built and the night previewed;
* **accept / undo**: after *Propose lights* (Ctrl+P, in a worker), Ctrl+Shift+A at 0.5 and 0.9, an accept
  with nothing left, Ctrl+Z and redo, each driven as its shortcut does: the action's time on the GUI
  thread and the longest heartbeat stall during it and the 2 s after (the night preview updates);
* **memory per frame** (``--opens N``): the dataset root stepped through N times (next, previous, …),
  the resident memory after each frame's mesh and night (target: ≤ 2.5 GB after any number);
* **longest stall**: the largest lateness of a 10 ms ``QTimer`` heartbeat on the GUI thread over
  the whole session of that size, from just before the frame is opened (the open itself counts;
  the window's first paint at start-up does not) (target: no gap over 100 ms); each stall over
  100 ms is listed with the benchmark phase, the app's busy label and the jobs running.

Targets: slider → quick view ≤ 0.3 s at both sizes, brush stroke → canvas ≤ 50 ms,
open a 2048×1024 frame → canvas shown ≤ 5 s, peak memory ≤ 2.5 GB.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np


def _rss_kib(field: str) -> int:
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1])
    return 0


def _reset_peak_rss() -> None:
    try:  # Linux: "5" resets the peak resident set size (VmHWM) to the current one
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
    except OSError:
        pass


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--sizes", default="512x256,2048x1024")
    ap.add_argument("--repeats", type=int, default=3, help="slider changes per size")
    ap.add_argument("--fixture-dir", default="", help="where to write the fixtures (default: a temporary folder)")
    ap.add_argument("--frame", default="", help="a real-layout frame: a dataset image (e.g. a Cityscapes "
                    "X_leftImg8bit.png with its gtFine labels) instead of the generated fixtures")
    ap.add_argument("--opens", type=int, default=0, help="memory per frame opened: step through the dataset root "
                    "of --frame (or of the fixture) this many times, RSS after each frame's mesh and night")
    ap.add_argument("--memory-only", action="store_true", help="only the --opens measurement")
    args = ap.parse_args(argv)
    from PySide6.QtCore import QElapsedTimer, QPoint, Qt, QTimer
    from PySide6.QtTest import QTest
    from PySide6.QtWidgets import QApplication

    from npsim_cli.options import parse_size
    from npsim_core.synthetic.cityscapes import write_cityscapes_fixture
    from npsim_gui.editor.tools import Tool
    from npsim_gui.main_window import MainWindow

    app = QApplication.instance() or QApplication(sys.argv[:1])
    from PySide6.QtCore import QSettings

    for fmt in (QSettings.Format.NativeFormat, QSettings.Format.IniFormat):  # fresh layout, user's settings untouched
        QSettings.setPath(fmt, QSettings.Scope.UserScope, tempfile.mkdtemp(prefix="npsim-settings-"))
    base = Path(args.fixture_dir or tempfile.mkdtemp(prefix="npsim-gui-latency-"))

    def wait(cond, timeout=900.0) -> float:
        t0 = told = time.perf_counter()
        while not cond():
            app.processEvents()
            time.sleep(0.002)
            now = time.perf_counter()
            if now - t0 > timeout:
                raise TimeoutError(f"timed out in phase {phase[0]!r}")
            if now - told > 60:
                told = now
                jobs = [ch.name for ch in (win.pipeline_jobs, win.render_jobs, win.view_jobs, win.export_jobs,
                                           win.editor.proposal_jobs) if ch.is_busy]
                print(f"  … still in {phase[0]!r} after {now - t0:.0f} s (jobs: {', '.join(jobs) or 'none'}; "
                      f"{win.busy_label.text()})", file=sys.stderr, flush=True)
        return time.perf_counter() - t0

    rows, slider_rows, brush_rows, stall_rows, action_rows = [], [], [], [], []
    if args.frame:
        import cv2

        shape = cv2.imread(args.frame, cv2.IMREAD_UNCHANGED)
        if shape is None:
            print(f"{args.frame}: not an image", file=sys.stderr)
            return 2
        runs = [(Path(args.frame), shape.shape[1], shape.shape[0])]
    else:
        runs = []
        for size in [s for s in args.sizes.split(",") if s]:
            w, h = parse_size(size)
            root = base / f"cityscapes_{w}x{h}"
            stems = write_cityscapes_fixture(root, frames=2, size=(w, h), corrupt=0)
            runs.append((root / "leftImg8bit" / "val" / "synthcity" / f"{stems[0]}_leftImg8bit.png", w, h))
    for image, w, h in (runs if not args.memory_only else []):

        gaps: list[float] = []
        phase = ["start"]
        where: list[str] = []  # the benchmark phase each heartbeat ended in (to name the stalls)
        clock = QElapsedTimer()
        clock.start()
        last = [clock.elapsed()]

        def beat() -> None:
            now = clock.elapsed()
            gaps.append(now - last[0] - 10)  # lateness beyond the 10 ms interval
            jobs = [ch.name for ch in (win.pipeline_jobs, win.render_jobs, win.view_jobs) if ch.is_busy]
            where.append(f"{phase[0]} ({win.busy_label.text()[:40]}; jobs: {', '.join(jobs) or 'none'})")
            last[0] = now
        win = MainWindow()
        win.ask = lambda *a: "Discard"
        win.show()
        # the window's first paint (OpenGL context, empty 3D view) belongs to starting the app, not to opening
        QTest.qWaitForWindowExposed(win)
        t_start = time.perf_counter()
        wait(lambda: time.perf_counter() - t_start > 1.0, 10)
        hb = QTimer()
        hb.setInterval(10)
        hb.timeout.connect(beat)
        last[0] = clock.elapsed()  # every gap from here on counts, the open's included
        hb.start()
        # ---- open the frame
        phase[0] = "open (synchronous load)"
        rss0 = _rss_kib("VmRSS")
        _reset_peak_rss()
        t0 = time.perf_counter()
        win.open_scene(image)
        wait(lambda: win.editor.canvas.base.array.shape[:2] == (h, w))
        app.processEvents()  # the canvas paints
        t_canvas = time.perf_counter() - t0
        phase[0] = "after open: chain, 3D view, night"
        wait(lambda: win.results is not None and win.results_final and not win.pipeline_jobs.is_busy)
        t_pipe = time.perf_counter() - t0
        app.processEvents()
        if win.render_panel.night is None and not win.render_jobs.is_busy:
            # the night renders only while its dock is on screen (a window manager may cover it)
            print(f"  night preview not on screen ({win.night_preview_shown()}): F6", file=sys.stderr, flush=True)
            win.render_now()
        wait(lambda: win.render_panel.night is not None and not win.render_jobs.is_busy)
        t_night = time.perf_counter() - t0
        peak = _rss_kib("VmHWM")
        rows.append((f"{w}x{h}", t_canvas, t_pipe, t_night, rss0 / 2**20, peak / 2**20))
        # ---- sliders: quick views
        phase[0] = "sliders"
        for v in (3.0, 7.0, 4.0, 6.0, 8.0)[: args.repeats]:
            live: list[float] = []

            def on_progress(info, lv=live) -> None:
                if isinstance(info, dict) and "live_results" in info:
                    lv.append(time.perf_counter())
            win.pipeline_jobs.progress.connect(on_progress)
            before = win.results
            t0 = time.perf_counter()
            win.params_panel.sliders[("refine", "lambda2")].spin.setValue(v)
            wait(lambda: bool(live) or win.results is not before)
            t_view = (live[0] if live else time.perf_counter()) - t0
            win.pipeline_jobs.progress.disconnect(on_progress)
            slider_rows.append((f"{w}x{h}", v, t_view, win.proxy_chain is not None))
            wait(lambda: time.perf_counter() - t0 > 1.5, 5)  # trying values: the next one comes soon
        t0 = time.perf_counter()
        wait(lambda: win.results_final and not win.pipeline_jobs.is_busy)
        t_settle = time.perf_counter() - t0
        # ---- a brush stroke on the canvas
        phase[0] = "brush stroke (driven synchronously)"
        ed = win.editor
        ed.set_tool(Tool.BRUSH)
        ed.session.set_current_class(8)
        c = ed.canvas
        vp = c.viewport()
        pts = [c.view_point(w * (0.3 + 0.4 * k / 21), h * 0.4) for k in range(22)]
        times = []
        for k, p in enumerate(pts):
            t0 = time.perf_counter()
            if k == 0:
                QTest.mousePress(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, QPoint(p))
            elif k == len(pts) - 1:
                QTest.mouseRelease(vp, Qt.MouseButton.LeftButton, Qt.KeyboardModifier.NoModifier, QPoint(p))
            else:
                QTest.mouseMove(vp, QPoint(p))
            app.processEvents()  # the canvas repaints what the event changed
            times.append(time.perf_counter() - t0)
        painted = int((ed.session.ann.instance_map > 0).sum())
        brush_rows.append((f"{w}x{h}", float(np.median(times)), float(np.max(times)), painted))
        wait(lambda: not win.jobs_busy)
        # ---- proposals: propose (worker), then accept / undo as the shortcuts do; each action is driven
        # synchronously, then 2 s of the app's own follow-up (night update) count towards it
        phase[0] = "propose (Ctrl+P, worker)"
        ed.actions_by_name["propose"].trigger()
        wait(lambda: ed.proposal_book is not None and not ed.proposal_jobs.is_busy)
        n_prop = len(ed.proposal_book.light_ids)

        def act(name: str, fn) -> None:
            phase[0] = name
            k0 = len(gaps)
            t0 = time.perf_counter()
            fn()
            app.processEvents()
            t_act = time.perf_counter() - t0
            wait(lambda: time.perf_counter() - t0 > 2.0, 10)
            g = gaps[k0:] or [0.0]
            action_rows.append((f"{w}x{h}", name, t_act, float(max(g)), len(ed.session.existing_ids())))
        ed.confidence_slider.setValue(50)
        act("accept ≥ 0.50 (Ctrl+Shift+A)", ed.actions_by_name["accept_above"].trigger)
        act("undo the accept (Ctrl+Z)", ed.actions_by_name["undo"].trigger)
        ed.confidence_slider.setValue(90)
        act("accept ≥ 0.90 (Ctrl+Shift+A)", ed.actions_by_name["accept_above"].trigger)
        act("accept again: nothing left (Ctrl+Shift+A)", ed.actions_by_name["accept_above"].trigger)
        act("undo (Ctrl+Z)", ed.actions_by_name["undo"].trigger)
        act("redo (Ctrl+Shift+Z)", ed.actions_by_name["redo"].trigger)
        phase[0] = "after the actions"
        wait(lambda: not win.jobs_busy)
        hb.stop()
        g = np.array(gaps) if gaps else np.zeros(1)
        for i in np.argsort(g)[::-1][:3]:
            if g[i] > 100:
                stall_rows.append((f"{w}x{h}", float(g[i]), where[i]))
        rows[-1] = rows[-1] + (t_settle, float(g.max()), float(np.percentile(g, 99)), int((g > 100).sum()), len(g))
        win.editor.session.discard_recovery()
        win.confirm_close = lambda: True
        win.close()
        app.processEvents()
        win = None  # the next size starts from a new window

    mem_rows = []
    if args.opens:
        # the dataset root above the frame's leftImg8bit/ folder (Cityscapes layout), else its folder
        phase = ["memory per frame"]
        img = Path(runs[-1][0])
        root = next((p.parent for p in img.parents if p.name == "leftImg8bit"), img.parent)
        win = MainWindow()
        win.ask = lambda *a: "Discard"
        win.show()
        QTest.qWaitForWindowExposed(win)
        _reset_peak_rss()
        win.open_dataset(root)
        for k in range(args.opens):
            if k:
                win.step_frame(+1 if k % 2 else -1)
            wait(lambda: win.results is not None and win.results_final and not win.pipeline_jobs.is_busy)
            app.processEvents()
            if win.render_panel.night is None and not win.render_jobs.is_busy:
                win.render_now()  # the night renders only while its dock is on screen
            wait(lambda: win.render_panel.night is not None and not win.jobs_busy)
            mem_rows.append((k + 1, win.chain.scene.name, _rss_kib("VmRSS") / 2**20, _rss_kib("VmHWM") / 2**20))
        win.confirm_close = lambda: True
        win.close()

    load = os.getloadavg()[0]
    print(f"# GUI latency on Cityscapes-layout frames (load {load:.1f}, {os.cpu_count()} cores)\n")
    if mem_rows:
        print("| frames opened | frame | RSS after its mesh and night (GB) | peak RSS so far (GB) |")
        print("|---|---|---|---|")
        for r in mem_rows:
            print(f"| {r[0]} | {r[1]} | {r[2]:.2f} | {r[3]:.2f} |")
        print()
    if not rows:
        return 0
    print("| frame | open → canvas shown (s) | open → full mesh (s) | open → night preview (s) | RSS before (GB) "
          "| peak RSS (GB) | last slider → full res (s) | longest stall (ms) | p99 stall (ms) | stalls > 100 ms |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(f"| {r[0]} | {r[1]:.2f} | {r[2]:.1f} | {r[3]:.1f} | {r[4]:.2f} | {r[5]:.2f} | {r[6]:.1f} | {r[7]:.0f} "
              f"| {r[8]:.0f} | {r[9]} of {r[10]} |")
    print("\n| frame | λ2 | slider → quick view (s) | from a proxy |")
    print("|---|---|---|---|")
    for r in slider_rows:
        print(f"| {r[0]} | {r[1]:g} | {r[2]:.2f} | {'yes' if r[3] else 'no'} |")
    for size in dict.fromkeys(r[0] for r in slider_rows):
        vals = [r[2] for r in slider_rows if r[0] == size]
        print(f"{size}: median slider → quick view {np.median(vals):.2f} s (target 0.3 s)")
    print("\n| frame | brush event → canvas, median (ms) | max (ms) | pixels painted |")
    print("|---|---|---|---|")
    for r in brush_rows:
        print(f"| {r[0]} | {r[1] * 1000:.1f} | {r[2] * 1000:.1f} | {r[3]} |")
    if not action_rows:
        return 0
    print(f"\n| frame | action ({n_prop} proposals) | action → canvas (ms) | longest stall, action and the "
          "2 s after (ms) | lights after |")
    print("|---|---|---|---|---|")
    for r in action_rows:
        print(f"| {r[0]} | {r[1]} | {r[2] * 1000:.0f} | {r[3]:.0f} | {r[4]} |")
    if stall_rows:
        print("\n| frame | stall (ms) | during (benchmark phase, the app's busy label) |")
        print("|---|---|---|")
        for r in stall_rows:
            print(f"| {r[0]} | {r[1]:.0f} | {r[2]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
