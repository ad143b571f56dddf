"""Normal-guided depth refinement (docs/method.md §3.3, thesis eqs. 3.4-3.9).

Minimises ``L = λ1 L_normal + λ2 L_continuity + λ3 L_depth`` over the depth map.

With ``P(p) = d(p) r(p)``, ``r = K^-1 (u, v, 1)``, forward tangents
``T_u(p) = P(p+x) − P(p)``, ``T_v(p) = P(p+y) − P(p)`` and the current normal
``n̂(p) = normalize(T_v × T_u)`` (docs/method.md §1.3, toward the camera):

* ``L_normal = Σ_{p∈Ω_n} ‖n̂(p) − N(p)‖² / |Ω_n|``, Ω_n = pixels whose depth, right
  and lower neighbours' depth and normal N are valid (the last row/column has no
  forward tangent pair and is excluded).
* ``L_continuity = Σ_p (1 − U_p) [m_u (T_u·N)² + m_v (T_v·N)²] / n_c``, m_u / m_v
  = the forward pair and N are valid, n_c = number of pixels with m_u or m_v
  (uncertain pixels count in n_c, as in the thesis's 1/n). Linear residuals:
  this term is quadratic in depth.
* ``L_depth = Σ_{p valid} (d − d_est)² / |valid|``.

Pixels with invalid depth (NaN, inf, <= 0) or invalid normals (non-finite or
length < 1e-6) are excluded from every term and returned unchanged (NaN).
Normals are renormalised; normals facing away from the camera (N·r > 0) are
flipped, the usual sign-convention slip of a network (counted in the message).

Loss variants (``RefineParams.loss``):

``'thesis'``
    The formulas above, in metres (L_continuity in m², L_depth in m²).
``'scale_aware'``
    Continuity residual divided by the pixel footprint ``s = d_est / sqrt(fx fy)``
    (so it measures the tangent's angle to the normal plane, unitless, still
    quadratic in d) and the depth residual by d_est (relative error). Near and
    far pixels then weigh alike and λ's mean the same at every resolution.

Optimisers (``RefineParams.optimizer``):

``'fast'`` (default)
    Damped Gauss-Newton (Levenberg-Marquardt): every step linearises the loss into a
    sparse least-squares problem on the image grid and solves it by Jacobi-preconditioned
    conjugate gradients (:mod:`.gauss_newton`); a step is kept only if the true loss falls,
    and every pixel stays within ``max_rel_change`` of its input depth (default ±2 %).
    Judged by accuracy against ground truth, it reaches the faithful Adam's normal error and
    AbsRel at 2048x1024 in about a second (docs/refine.md §5).
``'adam_faithful'``
    torch Adam on the raw depth, lr 1e-4, 1000 steps (thesis). Adam moves each
    pixel by at most about lr per step, so the whole run changes depth by at
    most ~0.1-0.2 m (reported as ``RefineResult.max_change_m``).
``'lbfgs'``
    The previous default: L-BFGS (torch, strong-Wolfe line search) on a diagonally
    preconditioned variable ``d = d_est + s ⊙ x`` with s the pixel footprint: the normal term's
    curvature in d scales like (f/d)², so in x every pixel is equally well
    conditioned whatever its distance. Stops when the loss's relative decrease
    over 5 iterations is below ``tol`` or after ``steps`` iterations. It lowers the loss
    quickly but moves some depths by ~20 m before it matches Adam's accuracy.

Adam and L-BFGS use the hand-derived gradient of :meth:`RefinementProblem.value_and_grad`
(1.5x faster than autograd at 2048x1024; ``total_autograd`` is the reference).
All keep the best iterate, stop on a non-finite loss or a blow-up (loss above
``divergence_factor`` x the initial loss), check ``cancel`` every step (raising
:class:`~npsim_core.errors.NpsimCancelled`), call ``progress(step, total,
losses)`` every step and honour the ``max_time_s`` budget (counted from the call).
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import torch

from ..camera import Intrinsics, valid_depth_mask
from ..errors import NpsimCancelled, NpsimInputError
from ._inputs import as_depth, as_mask, as_normals, check_positive
from .params import _DEFAULT_LR, _DEFAULT_STEPS, PRESETS, RefineParams  # noqa: F401 (re-exported)

@dataclass
class RefineResult:
    """Output of :func:`refine_depth`.

    Attributes
    ----------
    depth : (H, W) float32
        Refined depth in metres (best iterate); NaN where the input was invalid.
    history : dict of 1-D float64 arrays
        Per iterate k = 0..steps: 'total', 'normal', 'continuity', 'depth' (unweighted
        terms; total is weighted) and 'time_s' (seconds since the optimisation began).
    timings : dict
        'setup_s', 'optimize_s', 'total_s' (seconds).
    converged, diverged : bool
    message : str
        Human-readable summary (why it stopped, flipped normals, ...).
    steps : int
        Iterations run.
    best_step : int
        Iterate whose depth is returned.
    max_change_m : float
        max |refined − initial| over valid pixels (m).
    kept_input : bool
        The chain's unfiltered input depth was returned (``refine_depth(input_depth=...)``): it
        agreed with the estimated normals at least as well as the refined depth.
    """

    depth: np.ndarray
    history: dict[str, np.ndarray]
    timings: dict[str, float]
    converged: bool
    diverged: bool
    message: str
    steps: int = 0
    best_step: int = 0
    max_change_m: float = 0.0
    kept_input: bool = False

    @property
    def final_loss(self) -> float:
        return float(self.history["total"][self.best_step]) if len(self.history["total"]) else float("nan")


def _is_cancelled(cancel) -> bool:
    if cancel is None:
        return False
    if isinstance(cancel, threading.Event) or hasattr(cancel, "is_set"):
        return bool(cancel.is_set())
    return bool(cancel())


class RefinementProblem:
    """The loss of docs/method.md §3.3 on fixed inputs, as torch tensors (built once, evaluated many times).

    ``terms(d)`` returns the three unweighted terms for a full HxW depth tensor;
    ``total(d)`` their λ-weighted sum. Invalid pixels hold placeholder depth 1 and
    are masked out of every term (masking by selection, so no NaN ever enters).
    """

    def __init__(self, depth: np.ndarray, normals: np.ndarray, intr: Intrinsics, uncertain: np.ndarray,
                 params: RefineParams, anchor: np.ndarray | None = None):
        self.params = params
        dt = torch.float64 if params.dtype == "float64" else torch.float32
        self.dtype = dt
        H, W = depth.shape
        self.shape = (H, W)
        vd = valid_depth_mask(depth)
        anchor = depth if anchor is None else anchor
        va = valid_depth_mask(anchor)
        vd &= va
        # Set-up in the working precision, on separate channels: rays K^-1 (u, v, 1) are separable
        # (x by column, y by row), so r·N needs no HxWx3 ray array (3x faster set-up at 2048x1024).
        npdt = np.float64 if dt == torch.float64 else np.float32
        nx, ny, nz = (np.asarray(normals[..., i], npdt) for i in range(3))
        finite = np.isfinite(nx) & np.isfinite(ny) & np.isfinite(nz)
        nx, ny, nz = (np.where(finite, c, 0) for c in (nx, ny, nz))
        length = np.sqrt(nx * nx + ny * ny + nz * nz)
        vn = finite & (length > 1e-6)
        inv_len = np.where(vn, 1 / np.maximum(length, 1e-12), 0).astype(npdt)
        xs = ((np.arange(W, dtype=np.float64) - intr.cx) / intr.fx).astype(npdt)[None, :]   # (1, W)
        ys = ((np.arange(H, dtype=np.float64) - intr.cy) / intr.fy).astype(npdt)[:, None]   # (H, 1)
        b = (nx * xs + ny * ys + nz) * inv_len
        away = vn & (b > 0)
        sign = np.where(away, -inv_len, inv_len)
        nx, ny, nz = nx * sign, ny * sign, nz * sign
        b = np.where(away, -b, b)
        self.n_flipped = int(away.sum())
        self.valid = vd
        d0 = np.where(vd, depth, 1.0).astype(npdt)
        da = np.where(vd, anchor, 1.0).astype(npdt)
        keep = ~np.asarray(uncertain, bool)
        t = lambda a: torch.from_numpy(np.ascontiguousarray(a, dtype=npdt))  # noqa: E731
        self.d_init = t(d0)
        self.d_est = t(da)
        # Normal term mask on the (H-1, W-1) grid of forward tangent pairs.
        mn = vd[:-1, :-1] & vd[:-1, 1:] & vd[1:, :-1] & vn[:-1, :-1]
        self.m_n = t(mn)
        self.n_n = max(1.0, float(np.count_nonzero(mn)))
        # Continuity: residual_u(p) = d(p+x) a_u(p) − d(p) b(p), a_u = r(p+x)·N(p), b = r(p)·N(p).
        a_u = b[:, :-1] + nx[:, :-1] * (xs[:, 1:] - xs[:, :-1])
        a_v = b[:-1, :] + ny[:-1, :] * (ys[1:] - ys[:-1])
        mu = vd[:, :-1] & vd[:, 1:] & vn[:, :-1]
        mv = vd[:-1, :] & vd[1:, :] & vn[:-1, :]
        any_c = np.zeros((H, W), bool)
        any_c[:, :-1] |= mu
        any_c[:-1, :] |= mv
        self.n_c = max(1.0, float(np.count_nonzero(any_c)))
        self.n_d = max(1.0, float(np.count_nonzero(vd)))
        f = math.sqrt(intr.fx * intr.fy)
        wu = mu & keep[:, :-1]
        wv = mv & keep[:-1, :]
        if params.loss == "scale_aware":
            inv_s2 = (f / da) ** 2  # 1 / pixel footprint²
            wu = wu * inv_s2[:, :-1]
            wv = wv * inv_s2[:-1, :]
            wd = vd / (da * da)
        else:
            wd = vd
        self.a_u, self.a_v = t(a_u), t(a_v)
        self.b_u, self.b_v = t(b[:, :-1]), t(b[:-1, :])
        self.fx, self.fy = float(intr.fx), float(intr.fy)
        self.x0 = t(xs[:, :-1])   # (1, W-1): x0 depends on the column only
        self.y0 = t(ys[:-1])      # (H-1, 1)
        self.Nx, self.Ny, self.Nz = t(nx[:-1, :-1]), t(ny[:-1, :-1]), t(nz[:-1, :-1])
        self.w_u, self.w_v, self.w_d = t(wu), t(wv), t(wd)
        # Preconditioner for the L-BFGS optimiser: pixel footprint in metres (1 where invalid: inert).
        self.scale = t(np.where(vd, da / f, 1.0))
        self.lambdas = tuple(float(x) for x in params.lambdas)
        self.m_n_sum = float(np.count_nonzero(mn))
        # Ray x (by column) and y (by row) for the tangents of the Gauss-Newton solver.
        self.rx = t(xs)     # (1, W)
        self.ry = t(ys)     # (H, 1)
        self.uncertain = ~keep
        self.deadline: float | None = None  # set by refine_depth from max_time_s
        self._last_terms = None

    def terms(self, d: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
        # n̂ in closed form: with d0 = d(p), d1 = d(p+x), d2 = d(p+y) and r(p) = (x0, y0, 1),
        # T_v × T_u = (d1 d2 / fx fy) · (g1, g2, −(1 + x0 g1 + y0 g2)), g1 = fx (1 − d0/d1),
        # g2 = fy (1 − d0/d2) -- a positive multiple, so n̂ depends on depth ratios only, and
        # ‖n̂ − N‖² = 2 − 2 n̂·N for unit N. About 3x fewer tensor ops than the generic cross product.
        d0 = d[:-1, :-1]
        g1 = self.fx * (1.0 - d0 / d[:-1, 1:])
        g2 = self.fy * (1.0 - d0 / d[1:, :-1])
        nz = -(1.0 + self.x0 * g1 + self.y0 * g2)
        dot = g1 * self.Nx + g2 * self.Ny + nz * self.Nz
        e = 2.0 - 2.0 * dot * torch.rsqrt(g1 * g1 + g2 * g2 + nz * nz)
        l_normal = (e * self.m_n).sum(dtype=torch.float64) / self.n_n
        ru = d[:, 1:] * self.a_u - d[:, :-1] * self.b_u
        rv = d[1:, :] * self.a_v - d[:-1, :] * self.b_v
        l_cont = ((ru * ru * self.w_u).sum(dtype=torch.float64)
                  + (rv * rv * self.w_v).sum(dtype=torch.float64)) / self.n_c
        r = d - self.d_est
        l_depth = (r * r * self.w_d).sum(dtype=torch.float64) / self.n_d
        return l_normal, l_cont, l_depth

    def total(self, d: torch.Tensor):
        """Weighted loss and its three terms. With ``d.requires_grad`` the gradient is the
        hand-derived one of :meth:`value_and_grad` (checked against autograd in the tests)."""
        if d.requires_grad and torch.is_grad_enabled():
            loss = _AnalyticLoss.apply(d, self)
            return loss, self._last_terms
        with torch.no_grad():
            total, terms, _ = self.value_and_grad(d, need_grad=False)
        return total, terms

    def total_autograd(self, d: torch.Tensor):
        """Same as :meth:`total` through torch autograd on :meth:`terms` (the reference)."""
        ln, lc, ld = self.terms(d)
        l1, l2, l3 = self.lambdas
        return l1 * ln + l2 * lc + l3 * ld, (ln, lc, ld)

    def value_and_grad(self, d: torch.Tensor, need_grad: bool = True):
        """(total, (normal, continuity, depth), dL/dd or None) in one pass, no autograd graph.

        Derivatives (notation of :meth:`terms`): with q = |n'|, dot = n'·N, a1 = Nx − x0 Nz,
        b1 = g1 − x0 nz, a2 = Ny − y0 Nz, b2 = g2 − y0 nz:
        ∂e/∂g1 = −2 (a1/q − dot b1/q³), ∂e/∂g2 = −2 (a2/q − dot b2/q³);
        ∂g1/∂d0 = −fx/d1, ∂g1/∂d1 = fx d0/d1², ∂g2/∂d0 = −fy/d2, ∂g2/∂d2 = fy d0/d2².
        Continuity and depth terms are quadratic: ∂(w r²) = 2 w r ∂r.
        """
        l1, l2, l3 = self.lambdas
        d = d.detach()
        d0, d1, d2 = d[:-1, :-1], d[:-1, 1:], d[1:, :-1]
        inv1, inv2 = 1.0 / d1, 1.0 / d2
        rho1, rho2 = d0 * inv1, d0 * inv2
        g1 = self.fx * (1.0 - rho1)
        g2 = self.fy * (1.0 - rho2)
        nz = -(1.0 + self.x0 * g1 + self.y0 * g2)
        dot = g1 * self.Nx + g2 * self.Ny + nz * self.Nz
        iq = torch.rsqrt(g1 * g1 + g2 * g2 + nz * nz)
        cos = dot * iq
        l_normal = (2.0 * self.m_n_sum - 2.0 * (cos * self.m_n).sum(dtype=torch.float64)) / self.n_n
        ru = d[:, 1:] * self.a_u - d[:, :-1] * self.b_u
        rv = d[1:, :] * self.a_v - d[:-1, :] * self.b_v
        wru = ru * self.w_u
        wrv = rv * self.w_v
        l_cont = ((ru * wru).sum(dtype=torch.float64) + (rv * wrv).sum(dtype=torch.float64)) / self.n_c
        r = d - self.d_est
        wr = r * self.w_d
        l_depth = (r * wr).sum(dtype=torch.float64) / self.n_d
        total = l1 * l_normal + l2 * l_cont + l3 * l_depth
        terms = (l_normal, l_cont, l_depth)
        if not need_grad:
            return total, terms, None
        # normal term
        iq3dot = dot * iq * iq * iq
        wn = self.m_n * (-2.0 * l1 / self.n_n)
        G1 = wn * ((self.Nx - self.x0 * self.Nz) * iq - (g1 - self.x0 * nz) * iq3dot)
        G2 = wn * ((self.Ny - self.y0 * self.Nz) * iq - (g2 - self.y0 * nz) * iq3dot)
        A = G1 * (self.fx * inv1)
        B = G2 * (self.fy * inv2)
        grad = (2.0 * l3 / self.n_d) * wr
        grad[:-1, :-1] -= A + B
        grad[:-1, 1:] += A * rho1
        grad[1:, :-1] += B * rho2
        # continuity term
        cu = (2.0 * l2 / self.n_c) * wru
        cv = (2.0 * l2 / self.n_c) * wrv
        grad[:, 1:] += cu * self.a_u
        grad[:, :-1] -= cu * self.b_u
        grad[1:, :] += cv * self.a_v
        grad[:-1, :] -= cv * self.b_v
        return total, terms, grad


class _AnalyticLoss(torch.autograd.Function):
    """Total loss with the hand-derived gradient (computed in the same pass as the value)."""

    @staticmethod
    def forward(ctx, d, prob):
        total, terms, grad = prob.value_and_grad(d, need_grad=True)
        prob._last_terms = terms
        ctx.save_for_backward(grad)
        return total

    @staticmethod
    def backward(ctx, g_out):
        (grad,) = ctx.saved_tensors
        return grad * g_out.to(grad.dtype), None


def _validate(depth, normals, intrinsics, uncertain):
    d = as_depth(depth)
    if not isinstance(intrinsics, Intrinsics):
        raise NpsimInputError(f"intrinsics must be an Intrinsics, got {type(intrinsics).__name__}")
    if d.shape != (intrinsics.height, intrinsics.width):
        raise NpsimInputError(f"depth has shape {d.shape} but the intrinsics are for "
                              f"{intrinsics.height}x{intrinsics.width} (HxW); use Intrinsics.resized()")
    n = as_normals(normals, d.shape)
    u = np.zeros(d.shape, bool) if uncertain is None else as_mask(uncertain, d.shape, "uncertain map")
    return d, n, u


def refine_depth(depth, normals, intrinsics: Intrinsics, uncertain=None, params: RefineParams | None = None, *,
                 anchor=None, progress: Callable[[int, int, dict], None] | None = None,
                 cancel=None, on_iterate: Callable[[int, float, np.ndarray], None] | None = None,
                 input_depth=None) -> RefineResult:
    """Normal-guided depth refinement.

    Parameters
    ----------
    depth : (H, W) real
        Initial depth in metres (the filtered depth in the pipeline); also the
        anchor d_est of L_depth unless ``anchor`` is given. Invalid = NaN/inf/<=0.
    normals : (H, W, 3) float
        Estimated unit normals N (camera frame, toward the camera).
    intrinsics : Intrinsics
        Camera of this image size.
    uncertain : (H, W) bool, optional
        Uncertain map U (no continuity penalty where True). None = all False.
    params : RefineParams
    anchor : (H, W) real, optional
        d_est of L_depth when it differs from the initial depth.
    progress : callable(step, total, losses), optional
        Called after every iterate with a dict of 'total', 'normal', 'continuity', 'depth'.
    cancel : threading.Event or callable returning bool, optional
        Checked every step; when set, raises NpsimCancelled.
    on_iterate : callable(step, time_s, depth), optional
        Called with every recorded iterate: its index, the optimiser's seconds so far and a
        float32 HxW copy of its depth (placeholder 1 m at invalid pixels; the input's NaN are
        not restored). Its own run time is excluded from ``time_s``, the history and the
        ``max_time_s`` budget (for accuracy-against-time curves, e.g. benchmarks/refine.py).
    input_depth : (H, W) real, optional
        The chain's input depth before filtering. When its normals agree with ``normals`` at least
        as well as the result's do (mean ‖n̂ − N‖² over the pixels valid in both), the refinement
        -- filter included -- made a good input worse, and the input is returned instead
        (:func:`keeps_input`; exact depth went from 12° to 22° normal RMSE before; docs/refine.md §3).

    Returns
    -------
    RefineResult
    """
    t_start = time.perf_counter()
    params = params if params is not None else RefineParams()
    if not isinstance(params, RefineParams):
        raise NpsimInputError(f"params must be RefineParams, got {type(params).__name__}")
    d, n, u = _validate(depth, normals, intrinsics, uncertain)
    a = None if anchor is None else as_depth(anchor, "anchor")
    if a is not None and a.shape != d.shape:
        raise NpsimInputError(f"anchor has shape {a.shape}, depth {d.shape}; pass matching arrays")
    prob = RefinementProblem(d, n, intrinsics, u, params, anchor=a)
    # The budget counts from the call, set-up included: it bounds what the caller waits.
    prob.deadline = None if params.max_time_s is None else t_start + float(params.max_time_s)
    t_setup = time.perf_counter()
    if params.optimizer == "adam_faithful":
        run = _run_adam
    elif params.optimizer == "fast":
        run = _run_gauss_newton
    else:
        def run(prob, params, progress, cancel, on_iterate=None):
            return _run_fast(prob, params, progress, cancel, (d, n, intrinsics, u, a), on_iterate=on_iterate)
    prev_threads = torch.get_num_threads()
    if params.threads:
        torch.set_num_threads(int(params.threads))
    try:
        best, hist, info = run(prob, params, progress, cancel, on_iterate=on_iterate)
    finally:
        if params.threads:
            torch.set_num_threads(prev_threads)
    t_end = time.perf_counter()
    out = np.full(d.shape, np.nan, np.float32)
    valid = prob.valid
    best_np = best.detach().cpu().numpy()
    ok = valid & np.isfinite(best_np) & (best_np > 0)
    out[ok] = best_np[ok].astype(np.float32)
    bad = valid & ~ok
    if bad.any():  # a non-positive or non-finite refined value would be silently invalid: keep the input there
        out[bad] = d[bad]
    msgs = [info["message"]]
    hn = hist.get("normal", [])
    bs = int(info["best_step"])
    if len(hn) > bs and np.isfinite(hn[0]) and hn[0] > 0 and not hn[bs] <= NORMAL_DRIFT * hn[0]:
        # The loss fell, yet the depth's normals agree less with the estimated normals than the
        # input's did: the optimiser left the region where the loss means accuracy (a step size
        # far too large, typically). Its result is not trusted: the input depth is kept.
        msgs.append(f"diverged: the normal term rose from {hn[0]:.4g} to {hn[bs]:.4g} (more than "
                    f"{NORMAL_DRIFT:g}x) although the loss fell; kept the input depth (lower the learning rate)")
        info = dict(info, diverged=True, best_step=0)
        out[valid] = d[valid]
    kept_input = False
    change = float(np.max(np.abs(out[valid].astype(np.float64) - d[valid]))) if valid.any() else 0.0
    if input_depth is not None and params.keep_input and valid.any():
        d_in = as_depth(input_depth, "input_depth")
        if d_in.shape != d.shape:
            raise NpsimInputError(f"input_depth has shape {d_in.shape}, depth {d.shape}; pass matching arrays")
        e_in, e_out = keeps_input(d_in, out, n, intrinsics)
        if e_in <= e_out:
            msgs.append(f"kept the input depth: its normals already agree with the estimated normals ({e_in:.4g}) "
                        f"at least as well as the filtered and refined depth's ({e_out:.4g})")
            out = np.where(valid_depth_mask(d_in), d_in, np.float32(np.nan)).astype(np.float32)
            info = dict(info, best_step=0)
            kept_input = True
            moved = np.abs(out[valid].astype(np.float64) - d[valid])
            change = float(moved[np.isfinite(moved)].max()) if np.isfinite(moved).any() else 0.0
    if prob.n_flipped:
        msgs.append(f"{prob.n_flipped} normals faced away from the camera and were flipped")
    if bad.any():
        msgs.append(f"{int(bad.sum())} pixels left non-positive by the optimiser kept their input depth")
    history = {k: np.asarray(v, np.float64) for k, v in hist.items()}
    return RefineResult(depth=out, history=history,
                        timings={"setup_s": t_setup - t_start, "optimize_s": t_end - t_setup,
                                 "total_s": t_end - t_start},
                        converged=info["converged"], diverged=info["diverged"], message="; ".join(msgs),
                        steps=info["steps"], best_step=info["best_step"], max_change_m=change, kept_input=kept_input)


def keeps_input(input_depth: np.ndarray, result: np.ndarray, normals: np.ndarray,
                intrinsics: Intrinsics) -> tuple[float, float]:
    """Mean ‖n̂ − N‖² of ``input_depth``'s and of ``result``'s normals n̂ against ``normals`` N, over
    the pixels where both depths' normals and N are valid (N renormalised, flipped toward the
    camera as in the loss). The refinement keeps the input when the first is not larger."""
    from ..camera import normals_from_depth

    # float32 maps, float64 sums: at 4000x3000 float64 copies of the three normal maps set the
    # refinement's memory peak.
    N = np.asarray(normals, np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        N = N / np.linalg.norm(N, axis=-1, keepdims=True)
        flip = np.einsum("hwc,hwc->hw", N, intrinsics.pixel_rays(np.float32)) > 0
    N[flip] *= -1
    a = normals_from_depth(input_depth, intrinsics)
    b = normals_from_depth(result, intrinsics)
    ok = np.isfinite(a).all(-1) & np.isfinite(b).all(-1) & np.isfinite(N).all(-1)
    if not ok.any():
        return math.inf, math.inf
    Nk = N[ok]
    return (float(((a[ok] - Nk) ** 2).sum(-1).mean(dtype=np.float64)),
            float(((b[ok] - Nk) ** 2).sum(-1).mean(dtype=np.float64)))


#: A refinement whose normal term (disagreement with the estimated normals) ends above this
#: multiple of its initial value is reported as diverged and its input depth kept.
NORMAL_DRIFT = 1.25


class _Tracker:
    """History, best iterate, divergence and cancellation shared by both optimisers."""

    def __init__(self, params: RefineParams, total_steps: int, progress, cancel, on_iterate=None):
        self.hist: dict[str, list] = {k: [] for k in ("total", "normal", "continuity", "depth", "time_s")}
        self.t0 = time.perf_counter()
        self.best_loss = math.inf
        self.best_d: torch.Tensor | None = None
        self.best_step = 0
        self.initial: float | None = None
        self.params = params
        self.total_steps = total_steps
        self.progress = progress
        self.cancel = cancel
        self.on_iterate = on_iterate
        self.deadline: float | None = None  # perf_counter() time at which max_time_s runs out

    def record(self, step: int, loss: torch.Tensor, terms, d: torch.Tensor) -> str | None:
        """Log iterate ``step`` (depth ``d``); returns a divergence reason or None."""
        lv = float(loss.detach())
        vals = [float(x.detach()) for x in terms]
        self.hist["total"].append(lv)
        self.hist["normal"].append(vals[0])
        self.hist["continuity"].append(vals[1])
        self.hist["depth"].append(vals[2])
        self.hist["time_s"].append(time.perf_counter() - self.t0)
        if self.progress is not None:
            self.progress(step, self.total_steps, {"total": lv, "normal": vals[0], "continuity": vals[1],
                                                   "depth": vals[2]})
        if self.on_iterate is not None:
            t_cb = time.perf_counter()
            self.on_iterate(step, self.hist["time_s"][-1], d.detach().cpu().numpy().astype(np.float32))
            spent = time.perf_counter() - t_cb  # the observer's time is not the optimiser's
            self.t0 += spent
            if self.deadline is not None:
                self.deadline += spent
        if not math.isfinite(lv) or not torch.isfinite(d).all():
            return f"loss became non-finite at step {step}"
        if self.initial is None:
            self.initial = lv
        if lv < self.best_loss:
            self.best_loss = lv
            self.best_d = d.detach().clone()
            self.best_step = step
        # A floor keeps a near-zero initial loss (a fixed point) from calling every wiggle a blow-up.
        if lv > self.params.divergence_factor * max(self.initial, 1e-6):
            return f"loss blew up to {lv:.3g} (initial {self.initial:.3g}) at step {step}"
        return None

    def check_cancel(self) -> None:
        if _is_cancelled(self.cancel):
            raise NpsimCancelled("depth refinement cancelled")

    def out_of_time(self) -> bool:
        if self.deadline is not None:
            return time.perf_counter() > self.deadline
        m = self.params.max_time_s
        return m is not None and time.perf_counter() - self.t0 > m


def _run_adam(prob: RefinementProblem, params: RefineParams, progress, cancel, on_iterate=None):
    steps = params.n_steps
    tr = _Tracker(params, steps, progress, cancel, on_iterate)
    tr.deadline = getattr(prob, "deadline", None)
    d = prob.d_init.clone().requires_grad_(True)
    opt = torch.optim.Adam([d], lr=params.learning_rate)
    reason = None
    k = 0
    for k in range(steps + 1):
        tr.check_cancel()
        opt.zero_grad(set_to_none=True)
        loss, terms = prob.total(d)
        reason = tr.record(k, loss, terms, d.detach())
        if reason or k == steps or tr.out_of_time():
            break
        loss.backward()
        opt.step()
    info = {"converged": False, "diverged": reason is not None, "steps": k, "best_step": tr.best_step,
            "message": (f"diverged: {reason}; kept the best iterate (step {tr.best_step})" if reason
                        else f"Adam ran {k} steps (lr {params.learning_rate:g})"
                        + (" (time budget)" if k < steps else ""))}
    best = tr.best_d if tr.best_d is not None else prob.d_init
    return best, tr.hist, info


def _area_down(x: np.ndarray, w: np.ndarray, size: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Validity-weighted area average to ``size`` = (w, h); returns (mean, weight)."""
    import cv2

    xw = np.where(w[..., None] if x.ndim == 3 else w, x, 0.0).astype(np.float32)
    ws = cv2.resize(w.astype(np.float32), size, interpolation=cv2.INTER_AREA)
    xs = cv2.resize(xw, size, interpolation=cv2.INTER_AREA)
    with np.errstate(invalid="ignore", divide="ignore"):
        m = xs / (ws[..., None] if xs.ndim == 3 else ws)
    return m, ws


def _coarse_init(prob: RefinementProblem, params: RefineParams, inputs, tr: "_Tracker") -> torch.Tensor | None:
    """Solve at 1/coarse_factor resolution; return the full-resolution initial depth (or None)."""
    import cv2

    d, n, intr, u, a = inputs
    f = int(params.coarse_factor)
    H, W = d.shape
    hc, wc = H // f, W // f
    if f <= 1 or params.coarse_steps == 0 or min(hc, wc) < 8:
        return None
    vd = prob.valid
    dc, wdc = _area_down(d, vd, (wc, hc))
    ac = dc if a is None else _area_down(a, vd & valid_depth_mask(a), (wc, hc))[0]
    vn = np.isfinite(n).all(-1)
    nc, _ = _area_down(np.nan_to_num(n), vn, (wc, hc))
    uc = cv2.resize(u.astype(np.float32), (wc, hc), interpolation=cv2.INTER_AREA) > 0
    ok = wdc > 0.5  # coarse pixels mostly valid
    dc = np.where(ok, dc, np.nan).astype(np.float32)
    sub = RefinementProblem(dc, nc.astype(np.float32), intr.resized(wc, hc), uc,
                            dataclasses_replace(params, steps=params.coarse_steps), anchor=ac)
    quiet = _Tracker(sub.params, params.coarse_steps, None, tr.cancel)
    best, _, _ = _run_lbfgs(sub, sub.params, None, tr.cancel, tracker=quiet)
    ratio = np.ones((hc, wc), np.float32)
    bn = best.detach().cpu().numpy()
    good = sub.valid & np.isfinite(bn) & (bn > 0)
    ratio[good] = (bn[good] / sub.d_init.cpu().numpy()[good]).astype(np.float32)
    up = cv2.resize(ratio, (W, H), interpolation=cv2.INTER_LINEAR)
    init = prob.d_init * torch.from_numpy(np.where(vd, up, 1.0)).to(prob.dtype)
    return init


def _run_fast(prob: RefinementProblem, params: RefineParams, progress, cancel, inputs, on_iterate=None):
    tr = _Tracker(params, params.n_steps, progress, cancel, on_iterate)
    tr.deadline = getattr(prob, "deadline", None)
    with torch.no_grad():  # iterate 0 is the input itself, so histories of all methods start alike
        loss0, terms0 = prob.total(prob.d_init)
    reason = tr.record(0, loss0, terms0, prob.d_init)
    if reason:
        return prob.d_init, tr.hist, {"converged": False, "diverged": True, "steps": 0, "best_step": 0,
                                      "message": f"diverged: {reason}"}
    if params.n_steps == 0:
        return prob.d_init, tr.hist, {"converged": False, "diverged": False, "steps": 0, "best_step": 0,
                                      "message": "no iterations requested"}
    init = _coarse_init(prob, params, inputs, tr)
    return _run_lbfgs(prob, params, progress, cancel, tracker=tr, init=init, first_step=1)


def dataclasses_replace(obj, **kw):
    import dataclasses

    return dataclasses.replace(obj, **kw)


def _run_lbfgs(prob: RefinementProblem, params: RefineParams, progress, cancel, *, tracker=None, init=None,
               first_step: int = 0):
    steps = params.n_steps
    tr = tracker or _Tracker(params, steps, progress, cancel)
    base = prob.d_init if init is None else init
    x = torch.zeros_like(base, requires_grad=True)
    scale = prob.scale
    opt = torch.optim.LBFGS([x], lr=params.learning_rate, max_iter=1, max_eval=50, tolerance_grad=0.0,
                            tolerance_change=0.0, history_size=int(params.history_size),
                            line_search_fn="strong_wolfe")
    state = {"calls": 0, "k": 0, "reason": None}
    n_scale = prob.n_d

    def closure():
        opt.zero_grad(set_to_none=True)
        d = base + scale * x
        loss, terms = prob.total(d)
        if state["calls"] == 0:  # the first evaluation of a step is at the current iterate: log it
            state["reason"] = tr.record(state["k"], loss, terms, d.detach())
        state["calls"] += 1
        # Optimise the *sum* over pixels (mean x pixel count): per-pixel gradients are then O(1) in x,
        # so unit steps are meaningful; the mean's 1/N gradients make every step vanish below float32
        # resolution at 2048x1024. The sums themselves are accumulated in float64.
        obj = loss * n_scale
        if torch.isfinite(obj):
            obj.backward()
        else:  # the line search sees a non-finite value and backs off; no NaN gradient
            x.grad = torch.zeros_like(x)
        return obj

    converged = False
    timed_out = False
    k = first_step
    while True:
        tr.check_cancel()
        state["calls"] = 0
        state["k"] = k
        if k >= steps:
            with torch.no_grad():
                d = base + scale * x
                loss, terms = prob.total(d)
            state["reason"] = tr.record(k, loss, terms, d)
            break
        if tr.out_of_time():
            with torch.no_grad():
                d = base + scale * x
                loss, terms = prob.total(d)
            state["reason"] = tr.record(k, loss, terms, d)
            timed_out = True
            break
        opt.step(closure)
        if state["reason"]:
            break
        tot = tr.hist["total"]
        if len(tot) > 5 and tot[-6] - tot[-1] <= params.tol * max(abs(tot[-6]), 1e-30):
            converged = True
            break
        k += 1
    reason = state["reason"]
    info = {"converged": converged, "diverged": reason is not None, "steps": k, "best_step": tr.best_step}
    if reason:
        info["message"] = f"diverged: {reason}; kept the best iterate (step {tr.best_step})"
    elif converged:
        info["message"] = f"L-BFGS converged after {k} iterations"
    elif timed_out:
        info["message"] = f"L-BFGS stopped by the {params.max_time_s:g} s time budget after {k} iterations"
    else:
        info["message"] = f"L-BFGS stopped at the {steps}-iteration budget"
    best = tr.best_d if tr.best_d is not None else base
    return best, tr.hist, info


def _run_gauss_newton(prob: RefinementProblem, params: RefineParams, progress, cancel, on_iterate=None):
    """Levenberg-Marquardt on the linearised loss (:mod:`.gauss_newton`), moves boxed to ±max_rel_change."""
    from .gauss_newton import LinearisedSystem, damped_pcg

    steps = params.n_steps
    tr = _Tracker(params, steps, progress, cancel, on_iterate)
    tr.deadline = getattr(prob, "deadline", None)
    d = prob.d_init.clone()
    loss, terms = prob.total(d)
    reason = tr.record(0, loss, terms, d)
    cur = float(loss)
    b = params.max_rel_change
    # Without a bound a step could still cross zero depth: keep every pixel above 1 % of its input.
    lo = prob.d_init * (1.0 - b if b is not None and b < 1.0 else 0.01)
    hi = prob.d_init * (1.0 + b) if b is not None else None
    mu = float(params.damping)
    k = 0
    cg_total = 0
    converged = timed_out = False
    while not reason and k < steps:
        tr.check_cancel()
        if tr.out_of_time():
            timed_out = True
            break
        k += 1
        system = LinearisedSystem(prob, d)
        delta, its = damped_pcg(system, mu, int(params.cg_iters), float(params.cg_rtol), tr.deadline,
                                tr.check_cancel)
        cg_total += its
        del system
        if its == 0:  # the model's gradient vanishes: a fixed point (e.g. a plane matching its normals)
            converged = True
            tr.record(k, loss, terms, d)
            break
        cand = torch.clamp(d + delta, min=lo, max=hi)
        loss_c, terms_c = prob.total(cand)
        new = float(loss_c)
        if math.isfinite(new) and new < cur:
            rel = (cur - new) / max(abs(cur), 1e-30)
            d, cur, loss, terms = cand, new, loss_c, terms_c
            mu = max(mu / 3.0, 1e-6)
            converged = rel < params.tol
        else:
            mu = mu * 4.0 if mu > 0 else 1e-3
        reason = tr.record(k, loss, terms, d)
        if converged:
            break
        if tr.out_of_time():
            timed_out = k < steps
            break
    info = {"converged": converged, "diverged": reason is not None, "steps": k, "best_step": tr.best_step}
    what = f"Gauss-Newton/PCG ran {k} steps ({cg_total} CG iterations"
    what += f", moves within ±{b * 100:g} %)" if b is not None else ")"
    if reason:
        info["message"] = f"diverged: {reason}; kept the best iterate (step {tr.best_step})"
    elif converged:
        info["message"] = what + ", converged"
    elif timed_out:
        info["message"] = what + f", stopped by the {params.max_time_s:g} s time budget"
    else:
        info["message"] = what
    best = tr.best_d if tr.best_d is not None else prob.d_init
    return best, tr.hist, info
