"""Linearised refinement step: the loss of docs/method.md §3.3 as a sparse least-squares problem in depth.

Every term of the loss is (close to) a sum of squared residuals that are *linear* in depth:

* continuity: ``r_u(p) = T_u·N = d(p+x) a_u(p) − d(p) b(p)`` (and ``r_v``), exactly linear;
* normal: for small angles ``‖n̂ − N‖² = 2 − 2 cos θ ≈ θ² ≈ (T_u·N / |T_u|)² + (T_v·N / |T_v|)²``
  (the tangents' tilts out of the plane normal to N), i.e. the same residuals weighted by
  ``1 / |T|²``, with |T| frozen at the current depth (iteratively reweighted least squares);
* depth: ``d − d_est``, linear.

So around the current depth the loss is ``Σ W r(d)²`` with a 5-point-stencil Jacobian J, and one
Levenberg-Marquardt step solves ``(JᵀWJ + μ diag(JᵀWJ)) Δ = −JᵀW r`` -- a sparse, symmetric
positive (semi-)definite system on the image grid -- matrix-free by Jacobi-preconditioned conjugate
gradients. The damping μ is the trust region: it keeps the smooth, weakly constrained modes (whole
surfaces sliding in depth, which integrating normals cannot pin down) from moving far in one step.

Everything is a handful of whole-image torch operations per CG iteration (no per-pixel loops).
"""

from __future__ import annotations

import time

import torch


class LinearisedSystem:
    """The damped normal equations of one Gauss-Newton step at depth ``d`` (see module docstring).

    Parameters
    ----------
    prob : RefinementProblem
        Fixed inputs (normals, masks, weights, rays, λ's) of :mod:`.optimize`.
    d : (H, W) torch tensor
        Current depth in metres (placeholder 1 at invalid pixels, which carry no weight).

    Attributes
    ----------
    grad : (H, W) tensor
        ``JᵀW r(d)``, the model's gradient (half the gradient of the linearised loss).
    diag : (H, W) tensor
        ``diag(JᵀWJ)``; 0 at pixels no term touches (they never move).
    """

    def __init__(self, prob, d: torch.Tensor):
        l1, l2, l3 = prob.lambdas
        # Weights are per-pixel sums (the mean's 1/N factors scaled by N): float32-friendly, same solution.
        n = prob.n_d
        d0 = d[:, :-1]
        d1 = d[:, 1:]
        rx0, rx1 = prob.rx[:, :-1], prob.rx[:, 1:]
        tux = d1 * rx1 - d0 * rx0
        dz = d1 - d0
        tu2 = tux * tux + dz * dz * (1.0 + prob.ry * prob.ry)
        e0 = d[:-1, :]
        e2 = d[1:, :]
        ry0, ry1 = prob.ry[:-1], prob.ry[1:]
        tvy = e2 * ry1 - e0 * ry0
        dzv = e2 - e0
        tv2 = tvy * tvy + dzv * dzv * (1.0 + prob.rx * prob.rx)
        wn = prob.m_n * (l1 * n / prob.n_n)
        wu = prob.w_u * (l2 * n / prob.n_c)
        wv = prob.w_v * (l2 * n / prob.n_c)
        wu[:-1, :] += wn / tu2[:-1, :]
        wv[:, :-1] += wn / tv2[:, :-1]
        self.wu, self.wv = wu, wv
        self.wd = prob.w_d * (l3 * n / prob.n_d)
        self.a_u, self.b_u, self.a_v, self.b_v = prob.a_u, prob.b_u, prob.a_v, prob.b_v
        ru = d1 * self.a_u - d0 * self.b_u
        rv = e2 * self.a_v - e0 * self.b_v
        self.grad = self._jt(self.wd * (d - prob.d_est), wu * ru, wv * rv)
        diag = self.wd.clone()
        diag[:, 1:] += self.a_u * self.a_u * wu
        diag[:, :-1] += self.b_u * self.b_u * wu
        diag[1:, :] += self.a_v * self.a_v * wv
        diag[:-1, :] += self.b_v * self.b_v * wv
        self.diag = diag
        # JᵀWJ is a 5-point stencil: each pair residual couples two pixels with weight −a b W.
        self.off_u = -(self.a_u * self.b_u * wu)
        self.off_v = -(self.a_v * self.b_v * wv)

    def _jt(self, base: torch.Tensor, su: torch.Tensor, sv: torch.Tensor) -> torch.Tensor:
        """``base + Jᵀ(su, sv)``: scatter the weighted pair residuals back onto their pixels (in place)."""
        base[:, 1:] += self.a_u * su
        base[:, :-1] -= self.b_u * su
        base[1:, :] += self.a_v * sv
        base[:-1, :] -= self.b_v * sv
        return base

    def matvec(self, v: torch.Tensor, diag: torch.Tensor | None = None, out: torch.Tensor | None = None) -> torch.Tensor:
        """``(JᵀWJ − diag(JᵀWJ) + diag) v`` (``diag`` defaults to JᵀWJ's own: plain ``JᵀWJ v``)."""
        out = torch.mul(self.diag if diag is None else diag, v, out=out)
        out[:, :-1].addcmul_(self.off_u, v[:, 1:])
        out[:, 1:].addcmul_(self.off_u, v[:, :-1])
        out[:-1, :].addcmul_(self.off_v, v[1:, :])
        out[1:, :].addcmul_(self.off_v, v[:-1, :])
        return out


def _dot(a: torch.Tensor, b: torch.Tensor) -> float:
    return float(torch.dot(a.reshape(-1), b.reshape(-1)))


def damped_pcg(system: LinearisedSystem, mu: float, max_iter: int, rtol: float, deadline: float | None = None,
               cancel_check=None) -> tuple[torch.Tensor, int]:
    """Solve ``(A + μ diag A) Δ = −g`` by Jacobi-preconditioned CG from Δ = 0.

    Stops after ``max_iter`` iterations, when the preconditioned residual falls below ``rtol`` times its
    initial value, or when ``time.perf_counter()`` passes ``deadline`` (then the current Δ, which already
    lowers the model, is returned). Returns (Δ, iterations run).
    """
    g = system.grad
    dg = system.diag * (1.0 + mu)
    pos = dg > 0
    minv = torch.where(pos, 1.0 / torch.where(pos, dg, torch.ones_like(dg)), torch.zeros_like(dg))
    x = torch.zeros_like(g)
    r = -g
    z = minv * r
    p = z.clone()
    ap = torch.empty_like(g)
    rz = _dot(r, z)
    if not rz > 0.0:
        return x, 0
    rz0 = rz
    it = 0
    for it in range(1, max_iter + 1):
        system.matvec(p, dg, out=ap)
        pap = _dot(p, ap)
        if not pap > 0.0:
            break
        alpha = rz / pap
        x.add_(p, alpha=alpha)
        r.add_(ap, alpha=-alpha)
        torch.mul(minv, r, out=z)
        rz_new = _dot(r, z)
        if rz_new <= (rtol * rtol) * rz0:
            break
        if cancel_check is not None:
            cancel_check()
        if deadline is not None and time.perf_counter() > deadline:
            break
        torch.add(z, p, alpha=rz_new / rz, out=p)
        rz = rz_new
    return x, it
