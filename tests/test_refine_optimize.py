"""Normal-guided depth refinement: losses, fixed points, optimisers, cancellation, stability."""

import threading

import numpy as np
import pytest
import torch

from npsim_core.camera import Intrinsics, normals_from_depth
from npsim_core.errors import NpsimCancelled, NpsimInputError
from npsim_core.refine.optimize import PRESETS, RefinementProblem, RefineParams, refine_depth


def tilted_plane(H=24, W=32, normal=(0.2, -0.5, -1.0), c=-6.0):
    """Depth of the plane n·P = c (n toward the camera) and its exact normals."""
    intr = Intrinsics.from_fov(W, H, 60.0)
    n = np.asarray(normal, np.float64)
    n /= np.linalg.norm(n)
    rays = intr.pixel_rays(np.float64)
    d = (c / (rays @ n)).astype(np.float32)
    assert (d > 0).all()
    N = np.broadcast_to(n, (H, W, 3)).astype(np.float32).copy()
    return d, N, intr


def noisy_plane(seed=0, H=24, W=32, noise=0.02):
    d, N, intr = tilted_plane(H, W)
    rng = np.random.default_rng(seed)
    return (d * (1 + rng.normal(0, noise, d.shape))).astype(np.float32), N, intr, d


def test_presets():
    assert RefineParams().lambdas == (1.0, 5.0, 1.0) == PRESETS["appendix_b"]
    assert RefineParams.preset("section_3_4_3").lambdas == (1.0, 1.0, 5.0)
    assert RefineParams(lambdas=[2, 0, 1e3]).lambdas == (2.0, 0.0, 1000.0)
    with pytest.raises(NpsimInputError):
        RefineParams(lambdas="nope")
    with pytest.raises(NpsimInputError):
        RefineParams(lambdas=(1, -1, 1))
    with pytest.raises(NpsimInputError):
        RefineParams(optimizer="sgd")


def test_losses_vanish_on_a_consistent_plane_and_match_hand_values():
    d, N, intr = tilted_plane()
    prob = RefinementProblem(d, N, intr, np.zeros(d.shape, bool), RefineParams(dtype="float64"))
    ln, lc, ld = prob.terms(prob.d_init)
    assert float(ln) < 1e-10 and float(lc) < 1e-10 and float(ld) == 0.0  # float32 depth rounding only
    # depth term by hand: a uniform +0.1 m offset gives exactly 0.01 m²
    ln2, lc2, ld2 = prob.terms(prob.d_init + 0.1)
    assert float(ld2) == pytest.approx(0.01, rel=1e-12)
    # the normal term agrees with camera.normals_from_depth on the interior
    rng = np.random.default_rng(0)
    dn = d * (1 + 0.01 * rng.standard_normal(d.shape))
    prob = RefinementProblem(dn, N, intr, np.zeros(d.shape, bool), RefineParams(dtype="float64"))
    n_ref = normals_from_depth(dn, intr).astype(np.float64)[:-1, :-1]
    expect = np.mean(np.sum((n_ref - N[:-1, :-1]) ** 2, axis=-1))
    assert float(prob.terms(prob.d_init)[0]) == pytest.approx(expect, rel=1e-4)


@pytest.mark.parametrize("optimizer", ["fast", "lbfgs", "adam_faithful"])
def test_tilted_plane_is_a_fixed_point(optimizer):
    d, N, intr = tilted_plane()
    r = refine_depth(d, N, intr, None, RefineParams(optimizer=optimizer, steps=10, dtype="float64"))
    assert not r.diverged
    np.testing.assert_allclose(r.depth, d, rtol=1e-5)


def test_fast_lowers_loss_and_improves_normals():
    dn, N, intr, d_true = noisy_plane()
    r = refine_depth(dn, N, intr, None, RefineParams(steps=60))
    h = r.history
    assert h["total"][r.best_step] < 0.2 * h["total"][0]
    ang0 = _angle_rmse(normals_from_depth(dn, intr), N)
    ang1 = _angle_rmse(normals_from_depth(r.depth, intr), N)
    assert ang1 < 0.5 * ang0
    assert np.abs(r.depth - d_true).mean() < np.abs(dn - d_true).mean()


def _angle_rmse(a, b):
    cos = np.clip(np.sum(a * b, -1), -1, 1)
    return float(np.sqrt(np.nanmean(np.degrees(np.arccos(cos)) ** 2)))


def test_faithful_adam_moves_at_most_about_lr_per_step_and_logs_history():
    dn, N, intr, _ = noisy_plane(1)
    seen = []
    r = refine_depth(dn, N, intr, None, RefineParams(optimizer="adam_faithful", steps=20),
                     progress=lambda k, total, losses: seen.append((k, total, losses["total"])))
    assert r.steps == 20 and len(r.history["total"]) == 21 and len(seen) == 21
    assert seen[0][1] == 20 and seen[-1][0] == 20
    assert set(r.history) == {"total", "normal", "continuity", "depth", "time_s"}
    assert 0 < r.max_change_m <= 1.5 * 20 * 1e-4
    assert r.history["total"][-1] < r.history["total"][0]


def test_cancel_from_another_thread():
    dn, N, intr, _ = noisy_plane(2, H=48, W=64)
    ev = threading.Event()
    out = {}

    def work():
        try:
            refine_depth(dn, N, intr, None, RefineParams(optimizer="adam_faithful", steps=100000),
                         progress=lambda k, t, l: out.setdefault("started", True), cancel=ev)
        except NpsimCancelled as exc:
            out["cancelled"] = exc

    th = threading.Thread(target=work)
    th.start()
    for _ in range(200):
        if out.get("started"):
            break
        th.join(0.01)
    ev.set()
    th.join(30)
    assert not th.is_alive() and isinstance(out.get("cancelled"), NpsimCancelled)
    with pytest.raises(NpsimCancelled):
        refine_depth(dn, N, intr, None, RefineParams(steps=5), cancel=lambda: True)


@pytest.mark.parametrize("optimizer,lr", [("adam_faithful", 50.0), ("fast", 1e6), ("lbfgs", 1e6)])
def test_divergence_detected_best_iterate_kept(optimizer, lr):
    dn, N, intr, _ = noisy_plane(3)
    r = refine_depth(dn, N, intr, None, RefineParams(optimizer=optimizer, lr=lr, steps=50,
                                                     divergence_factor=10.0))
    assert np.isfinite(r.depth).all() and (r.depth > 0).all()
    h = r.history["total"]
    assert r.final_loss == np.nanmin(h) <= h[0]
    if optimizer == "adam_faithful":
        assert r.diverged and "diverged" in r.message


def test_stability_hard_inputs():
    H, W = 21, 27
    intr = Intrinsics.from_fov(W, H, 70.0)
    rng = np.random.default_rng(4)
    d = np.where(rng.random((H, W)) < 0.5, 0.1, 1000.0).astype(np.float32)
    d[0, 0], d[1, 1], d[2, 2], d[3, 3] = np.nan, np.inf, 0.0, -2.0
    N = np.broadcast_to(np.array([0, 0, -1.0], np.float32), (H, W, 3)).copy()
    N[4, 4] = 0.0                  # zero length
    N[5, 5] = (0, 0, 1.0)          # facing away: flipped
    N[6, 6] = np.nan
    U = rng.random((H, W)) < 0.3
    for lam in [(0, 0, 0), (1e3, 1e3, 1e3), (1, 0, 0), (0, 0, 1)]:
        for opt in ("fast", "lbfgs", "adam_faithful"):
            r = refine_depth(d.astype(np.float16)[:, ::-1], N[:, ::-1], intr, U[:, ::-1],
                             RefineParams(lambdas=lam, optimizer=opt, steps=5))
            valid = (np.isfinite(d) & (d > 0))[:, ::-1]
            assert np.isfinite(r.depth[valid]).all() and (r.depth[valid] > 0).all()
            assert np.isnan(r.depth[~valid]).all()
            assert all(np.isfinite(v).all() for v in r.history.values())
    assert "flipped" in r.message


@pytest.mark.parametrize("shape", [(1, 1), (2, 3), (5, 4)])
def test_tiny_images(shape):
    H, W = shape
    intr = Intrinsics.from_fov(W, H, 60.0)
    d = np.full(shape, 3.0, np.float32)
    N = np.broadcast_to(np.array([0, 0, -1.0], np.float32), (H, W, 3))
    for opt in ("fast", "lbfgs", "adam_faithful"):
        r = refine_depth(d, N, intr, None, RefineParams(optimizer=opt, steps=3))
        assert r.depth.shape == shape and np.isfinite(r.depth).all()


def test_zero_lambdas_leave_depth_unchanged():
    dn, N, intr, _ = noisy_plane(5)
    r = refine_depth(dn, N, intr, None, RefineParams(lambdas=(0, 0, 0), steps=5))
    np.testing.assert_array_equal(r.depth, dn)


def test_scale_aware_variant_and_float64_run():
    dn, N, intr, d_true = noisy_plane(6)
    r = refine_depth(dn * 100, N, intr, None, RefineParams(loss="scale_aware", steps=40, dtype="float64"))
    r1 = refine_depth(dn, N, intr, None, RefineParams(loss="scale_aware", steps=40, dtype="float64"))
    # scale-free: the same scene 100x farther refines to the same shape
    np.testing.assert_allclose(r.depth / 100, r1.depth, rtol=1e-3)


def test_threads_restored():
    before = torch.get_num_threads()
    dn, N, intr, _ = noisy_plane(7)
    refine_depth(dn, N, intr, None, RefineParams(steps=2, threads=1))
    assert torch.get_num_threads() == before


def test_bad_inputs():
    d, N, intr = tilted_plane()
    with pytest.raises(NpsimInputError, match="intrinsics"):
        refine_depth(d, N, intr.resized(16, 12))
    with pytest.raises(NpsimInputError, match="normals"):
        refine_depth(d, N[..., :2], intr)
    with pytest.raises(NpsimInputError, match="normals"):
        refine_depth(d, N.astype(np.int32), intr)
    with pytest.raises(NpsimInputError, match="uncertain"):
        refine_depth(d, N, intr, np.zeros((3, 3), bool))
    with pytest.raises(NpsimInputError, match="RefineParams"):
        refine_depth(d, N, intr, None, {"steps": 3})


@pytest.mark.parametrize("loss", ["thesis", "scale_aware"])
def test_analytic_gradient_matches_autograd(loss):
    dn, N, intr, _ = noisy_plane(8, H=13, W=17, noise=0.05)
    dn[3, 4] = np.nan
    N = N.copy()
    N[6, 7] = 0.0
    U = np.zeros(dn.shape, bool)
    U[2:5, 2:5] = True
    prob = RefinementProblem(dn, N, intr, U, RefineParams(lambdas=(1.3, 2.0, 0.7), loss=loss, dtype="float64"))
    d = prob.d_init.clone().requires_grad_(True)
    ref, ref_terms = prob.total_autograd(d)
    (g_ref,) = torch.autograd.grad(ref, d)
    d2 = prob.d_init.clone().requires_grad_(True)
    val, terms = prob.total(d2)
    val.backward()
    assert float(val.detach()) == pytest.approx(float(ref.detach()), rel=1e-10)
    for a, b in zip(terms, ref_terms):
        assert float(a.detach()) == pytest.approx(float(b.detach()), rel=1e-9, abs=1e-15)
    np.testing.assert_allclose(d2.grad.numpy(), g_ref.numpy(), rtol=1e-7, atol=1e-12 * float(g_ref.abs().max()))
