"""Depth refinement kernel (docs/method.md §3, thesis §3.4).

* :mod:`.bilateral` -- dual-reference cross-bilateral filter (exact reference and fast).
* :mod:`.uncertainty` -- dual-reference variance filter -> uncertain map U.
* :mod:`.optimize` -- normal-guided depth refinement (default damped Gauss-Newton, faithful Adam, L-BFGS).
* :mod:`.gauss_newton` -- the default solver's linearised system and preconditioned CG.

The cached chain filter -> uncertain -> refine is :class:`npsim_core.chain.Chain`.
"""

from ..lazy import lazy_exports

#: Public names and their modules, imported on first use (PEP 562): :mod:`.optimize` imports
#: torch, which the command line's start must not pay for.
_EXPORTS = {"FilterParams": "bilateral", "cross_bilateral": "bilateral", "cross_bilateral_reference": "bilateral",
            "UncertaintyParams": "uncertainty", "uncertain_map": "uncertainty", "region_variance": "uncertainty",
            "RefineParams": "params", "PRESETS": "params", "RefinementProblem": "optimize",
            "RefineResult": "optimize", "refine_depth": "optimize"}
__all__ = list(_EXPORTS)

__getattr__ = lazy_exports(__name__, _EXPORTS)
