"""Command-line start-up: wall time and peak memory of ``npsim --help`` and argument errors.

Target: ≤ 0.5 s and ≤ 120 MB each. The command line builds its parser from
modules that import nothing heavy; torch, Mitsuba, Qt, Ray and OIDN are imported only by the
commands that run them. Each case runs ``--repeat`` times as a fresh process (the median time
and the largest peak RSS are printed, the latter from ``os.wait4``), with the load average.
Also lists which of the heavy modules a plain ``--help`` imported (must be none).

Run: ``python -m benchmarks.cli_start`` or ``npsim bench cli_start``.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import time

#: (what, arguments of ``python -m npsim_cli``, expected exit code)
CASES = (
    ("npsim --help", ["--help"], 0),
    ("npsim run --help", ["run", "--help"], 0),
    ("npsim mesh (no -o: argument error)", ["mesh", "scene"], 2),
    ("npsim batch --workers x (argument error)", ["batch", "d", "-o", "o", "--workers", "x"], 2),
    ("npsim (no command)", [], 2),
)
HEAVY = ("torch", "mitsuba", "PySide6", "ray", "pyoidn", "cv2", "numpy")


def run_once(argv: list[str]) -> tuple[float, float, int]:
    """Wall seconds, peak RSS (MB) and exit code of one ``python -m npsim_cli ARGV`` process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "npsim_cli", *argv], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    dt = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    return dt, usage.ru_maxrss / 1024.0, proc.returncode


def heavy_imports(argv: list[str]) -> list[str]:
    """The heavy top-level modules imported while parsing ``argv`` (``SystemExit`` caught)."""
    code = ("import sys\nfrom npsim_cli.main import main\ntry:\n    main(%r)\nexcept SystemExit:\n    pass\n"
            "print('HEAVY:' + ','.join(m for m in %r if m in sys.modules))" % (argv, HEAVY))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=False)
    line = [ln for ln in out.stdout.splitlines() if ln.startswith("HEAVY:")]
    return [m for m in line[-1][len("HEAVY:"):].split(",") if m] if line else ["(failed to run)"]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="benchmarks.cli_start", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="fresh processes per case (default 5)")
    args = ap.parse_args(argv)
    print(f"load {os.getloadavg()[0]:.2f} (1-min average, {os.cpu_count()} cores); python {sys.version.split()[0]}")
    print("\n| command | median s | max s | peak RSS MB | exit | target |")
    print("|---|---|---|---|---|---|")
    ok = True
    for what, cmd, code in CASES:
        runs = [run_once(cmd) for _ in range(max(1, args.repeat))]
        med = statistics.median(r[0] for r in runs)
        rss = max(r[1] for r in runs)
        met = med <= 0.5 and rss <= 120 and all(r[2] == code for r in runs)
        ok &= met
        print(f"| {what} | {med:.3f} | {max(r[0] for r in runs):.3f} | {rss:.0f} | {runs[0][2]} | "
              f"{'met' if met else 'NOT met'} (≤ 0.5 s, ≤ 120 MB) |")
    print(f"\nheavy modules imported by 'npsim --help': {', '.join(heavy_imports(['--help'])) or 'none'}")
    print(f"load after: {os.getloadavg()[0]:.2f}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
