"""Depth refinement kernel (docs/method.md §3, thesis §3.4).

* :mod:`.bilateral` -- dual-reference cross-bilateral filter (exact reference and fast).
* :mod:`.uncertainty` -- dual-reference variance filter -> uncertain map U.
* :mod:`.optimize` -- normal-guided depth refinement (default damped Gauss-Newton, faithful Adam, L-BFGS).
* :mod:`.gauss_newton` -- the default solver's linearised system and preconditioned CG.

The cached chain filter -> uncertain -> refine is :class:`npsim_core.chain.Chain`.
"""

from .bilateral import FilterParams, cross_bilateral, cross_bilateral_reference
from .optimize import PRESETS, RefinementProblem, RefineParams, RefineResult, refine_depth
from .uncertainty import UncertaintyParams, region_variance, uncertain_map

__all__ = ["FilterParams", "cross_bilateral", "cross_bilateral_reference", "UncertaintyParams", "uncertain_map",
           "region_variance", "RefineParams", "RefineResult", "RefinementProblem", "refine_depth", "PRESETS"]
