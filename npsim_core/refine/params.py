"""Parameters of the normal-guided refinement (:mod:`.optimize`), importable without torch.

The command line builds its parser and validates ``--set refine.*`` from here; torch is
imported only when a refinement runs (``npsim --help`` must not pay for it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from ..errors import NpsimInputError
from ._inputs import check_positive

__all__ = ["PRESETS", "RefineParams", "OPTIMIZER_FIELDS"]

#: The two λ = (λ1 normal, λ2 continuity, λ3 depth) sets the thesis states.
PRESETS: dict[str, tuple[float, float, float]] = {
    "appendix_b": (1.0, 5.0, 1.0),      # appendix B grid search result (default)
    "section_3_4_3": (1.0, 1.0, 5.0),   # as printed in the thesis's §3.4.3
}

_DEFAULT_STEPS = {"adam_faithful": 1000, "lbfgs": 100, "fast": 10}
_DEFAULT_LR = {"adam_faithful": 1e-4, "lbfgs": 1.0, "fast": 1.0}


@dataclass(frozen=True)
class RefineParams:
    """Parameters of the normal-guided refinement.

    Attributes
    ----------
    lambdas : (float, float, float) or preset name
        (λ1 normal, λ2 continuity, λ3 depth); a name from :data:`PRESETS` is
        resolved on construction. Default: 'appendix_b' = (1, 5, 1).
    optimizer : {'fast', 'lbfgs', 'adam_faithful'}
        'fast' (default): damped Gauss-Newton steps solved by preconditioned conjugate gradients
        (:mod:`.gauss_newton`); 'lbfgs': the previous default, L-BFGS on footprint-scaled depth;
        'adam_faithful': the thesis's Adam.
    steps : int or None
        Iteration budget; None = 1000 for Adam (thesis), 100 for 'lbfgs', 10 Gauss-Newton steps for
        'fast' (upper bounds for the last two: they stop on convergence).
    lr : float or None
        Learning rate; None = 1e-4 for Adam (thesis), 1.0 for L-BFGS (its natural step); unused by 'fast'.
    loss : {'thesis', 'scale_aware'}
        Loss variant (module docstring).
    dtype : {'float32', 'float64'}
    tol : float
        'lbfgs' convergence: relative loss decrease over 5 iterations below tol; 'fast': relative
        decrease of one accepted Gauss-Newton step below tol.
    divergence_factor : float
        A loss above this multiple of the initial loss counts as divergence.
    history_size : int
        L-BFGS memory.
    coarse_factor, coarse_steps : int
        'lbfgs' only: first solve the problem downsampled ``coarse_factor`` times
        (area-averaged depth and normals, resized intrinsics) for up to
        ``coarse_steps`` iterations, and start the full-resolution run from the
        input depth times the upsampled coarse correction d_coarse/d_coarse_init.
        Smooth error modes, which L-BFGS fixes slowly at full resolution, are cheap
        there. ``coarse_factor=1`` (default) disables it: measured on the synthetic
        street it *raised* the full-resolution loss (see docs/refine.md).
    max_time_s : float or None
        Wall-clock budget of the whole call, set-up included (every optimiser); the
        best iterate so far is returned when it runs out (for live previews). The
        clock is read every iteration (every CG iteration for 'fast'), so the
        overshoot is one iteration plus one loss evaluation (~0.1 s at 2048x1024).
        A budget below the set-up (~0.3-0.6 s at 2048x1024) returns the input depth.
    cg_iters : int
        'fast': conjugate-gradient iterations per Gauss-Newton step (at most).
    cg_rtol : float
        'fast': CG stops when its preconditioned residual falls below this fraction of the initial one.
    damping : float
        'fast': initial Levenberg-Marquardt damping μ (system ``A + μ diag A``); divided by 3 after
        an accepted step, multiplied by 4 after a rejected one (the loss did not fall).
    max_rel_change : float or None
        'fast': bound on the relative move ``|d − d_in| / d_in`` of every pixel (a box constraint
        applied after each step); None = unbounded. Default 0.02 (docs/refine.md).
    keep_input : bool
        Return the chain's unfiltered input depth when its normals agree with the estimated normals
        at least as well as the filtered and refined depth's (``refine_depth(input_depth=...)``): a
        good input is never made worse. Measured at 256x128 on the synthetic street:
        exact depth kept (AbsRel 0, normal RMSE 23.0° instead of 0.0076 and 29.3°), the pop-up prior
        kept (0.0636 / 35.5° instead of 0.0676 / 40.5°), the simulated prediction refined as before.
    threads : int
        torch intra-op threads during the run (restored after); 0 = leave torch's setting.
        Default 1: on this 2-core machine shared with other jobs, 2 OpenMP threads
        made each step 30-100x slower (every op's barrier waits for a descheduled
        thread), while one thread loses at most 2x on an idle machine.
    """

    lambdas: Any = "appendix_b"
    optimizer: str = "fast"
    steps: int | None = None
    lr: float | None = None
    loss: str = "thesis"
    dtype: str = "float32"
    tol: float = 1e-6
    divergence_factor: float = 1e3
    history_size: int = 10
    threads: int = 1
    coarse_factor: int = 1
    coarse_steps: int = 60
    max_time_s: float | None = None
    cg_iters: int = 15
    cg_rtol: float = 1e-3
    damping: float = 0.01
    max_rel_change: float | None = 0.02
    keep_input: bool = True

    def __post_init__(self) -> None:
        lam = self.lambdas
        if isinstance(lam, str):
            if lam not in PRESETS:
                raise NpsimInputError(f"unknown λ preset {lam!r}; choose one of {sorted(PRESETS)}")
            lam = PRESETS[lam]
        try:
            lam = tuple(float(x) for x in lam)
        except TypeError:
            raise NpsimInputError(f"lambdas must be 3 numbers or a preset name, got {self.lambdas!r}") from None
        if len(lam) != 3 or not all(math.isfinite(x) and x >= 0 for x in lam):
            raise NpsimInputError(f"lambdas must be 3 finite numbers >= 0, got {self.lambdas!r}")
        object.__setattr__(self, "lambdas", lam)
        if self.optimizer not in _DEFAULT_STEPS:
            raise NpsimInputError(f"optimizer must be one of {sorted(_DEFAULT_STEPS)}, got {self.optimizer!r}")
        if self.loss not in ("thesis", "scale_aware"):
            raise NpsimInputError(f"loss must be 'thesis' or 'scale_aware', got {self.loss!r}")
        if self.dtype not in ("float32", "float64"):
            raise NpsimInputError(f"dtype must be 'float32' or 'float64', got {self.dtype!r}")
        if self.steps is not None and int(self.steps) < 0:
            raise NpsimInputError(f"steps must be >= 0, got {self.steps}")
        if self.lr is not None:
            check_positive(self.lr, "RefineParams.lr")
        check_positive(self.tol, "RefineParams.tol", allow_zero=True)
        check_positive(self.divergence_factor, "RefineParams.divergence_factor")
        if int(self.coarse_factor) < 1 or int(self.coarse_steps) < 0:
            raise NpsimInputError(f"coarse_factor must be >= 1 and coarse_steps >= 0, got "
                                  f"{self.coarse_factor}, {self.coarse_steps}")
        if self.max_time_s is not None:
            check_positive(self.max_time_s, "RefineParams.max_time_s")
        if int(self.threads) < 0:
            raise NpsimInputError(f"threads must be >= 0, got {self.threads}")
        if int(self.history_size) < 1:
            raise NpsimInputError(f"history_size must be >= 1, got {self.history_size}")
        if int(self.cg_iters) < 1:
            raise NpsimInputError(f"cg_iters must be >= 1, got {self.cg_iters}")
        check_positive(self.cg_rtol, "RefineParams.cg_rtol", allow_zero=True)
        check_positive(self.damping, "RefineParams.damping", allow_zero=True)
        if self.max_rel_change is not None:
            check_positive(self.max_rel_change, "RefineParams.max_rel_change")

    @classmethod
    def preset(cls, name: str, **kwargs) -> "RefineParams":
        """Parameters with the λ's of a named preset (see :data:`PRESETS`)."""
        return cls(lambdas=name, **kwargs)

    @property
    def n_steps(self) -> int:
        return int(self.steps) if self.steps is not None else _DEFAULT_STEPS[self.optimizer]

    @property
    def learning_rate(self) -> float:
        return float(self.lr) if self.lr is not None else _DEFAULT_LR[self.optimizer]


#: The fields only some optimisers read (every other field is read by all): field -> optimisers
#: that read it. A field set for an optimiser that does not read it is reported
#: (:func:`npsim_core.chain.params.unread_fields`).
OPTIMIZER_FIELDS: dict[str, tuple[str, ...]] = {
    "lr": ("lbfgs", "adam_faithful"),
    "tol": ("fast", "lbfgs"),
    "history_size": ("lbfgs",),
    "coarse_factor": ("lbfgs",),
    "coarse_steps": ("lbfgs",),
    "cg_iters": ("fast",),
    "cg_rtol": ("fast",),
    "damping": ("fast",),
    "max_rel_change": ("fast",),
}
