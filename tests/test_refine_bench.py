"""`npsim bench` dispatch and the refinement benchmark's entry point (tiny run)."""

import pytest

from npsim_cli.main import main as cli_main
from npsim_cli.commands.bench import available, load_benchmark
from npsim_core.errors import NpsimInputError


def test_bench_dispatch():
    assert "refine" in available()
    mod = load_benchmark("refine")
    assert callable(mod.main)
    with pytest.raises(NpsimInputError, match="unknown benchmark"):
        load_benchmark("no_such_benchmark")
    assert cli_main(["bench", "no_such_benchmark"]) == 2


def test_refine_benchmark_tiny_run(capsys, tmp_path):
    plot = tmp_path / "acc.png"
    assert cli_main(["bench", "refine", "--sizes", "64x32", "--adam-steps", "3", "--lbfgs-steps", "2",
                     "--fast-steps", "2", "--fixture", "64x32", "--fixture-frames", "1", "--cache", str(tmp_path),
                     "--plot", str(plot)]) == 0
    out = capsys.readouterr().out
    for title in ("Cross-bilateral filter, 64x32", "Variance filter, 64x32", "Refinement accuracy against time, 64x32",
                  "Whole kernel", "Stereo-only Cityscapes-layout fixture, 64x32"):
        assert title in out
    assert "Adam-3's accuracy" in out and "within 11.25°" in out
    assert plot.stat().st_size > 1000
    assert len(list(tmp_path.glob("adam_*.json"))) == 2  # Adam's curves cached (street and fixture frame)
