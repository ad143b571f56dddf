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


def test_refine_benchmark_tiny_run(capsys):
    assert cli_main(["bench", "refine", "--sizes", "64x32", "--adam-steps", "3", "--budgets", "2",
                     "--kernel-budget", "2"]) == 0
    out = capsys.readouterr().out
    for title in ("Cross-bilateral filter, 64x32", "Variance filter, 64x32", "Refinement, 64x32", "Whole kernel"):
        assert title in out
    assert "reaches Adam's final loss" in out
