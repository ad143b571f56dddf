"""The nights' path tracer at one bounce, without the path's last ray (docs/relight.md, "One bounce
without the last ray").

Mitsuba's ``path`` integrator at ``max_depth`` 3 (camera ray, one bounce) traces five rays per
sample: the camera ray, a shadow ray (next-event estimation, NEE) at the first vertex, the
bounce, a shadow ray at the second vertex and a last BSDF-sampled ray from the second vertex,
which only looks for an emitter to weigh against that vertex's NEE (multiple importance
sampling, MIS). :class:`OneBounce` is the same estimator up to the second vertex and ends the
path with NEE alone: the last ray is not traced (27 % less render CPU at 2048x1024, 16 spp).
Lamps, windows and the sky are all reachable by NEE (area, spot and constant emitters), so the
estimate stays unbiased where the second vertex is diffuse (NEE with weight 1); on glossy second
vertices NEE keeps its MIS weight and the BSDF's share is dropped (a lamp's glossy reflection
seen in an indirect bounce, ~1 % of the light, not the fireflies that weight 1 gives there).

On the frontier crops it is within the seed spread of ``path`` (6 seeds, docs/relight.md).
Tried and not kept: weight 1 or the MIS weight everywhere at the second vertex (the same error),
and one-sample MIS there (NEE or the BSDF ray, one of the two at random: further from the
reference, RMSE 20.8 vs 20.5 levels, and less CPU saved).

Only for the LLVM variants: a Python integrator is traced once per render into the JIT kernel,
while the scalar variants would call Python for every sample (those keep ``path``).
"""

from __future__ import annotations

#: Mitsuba plugin name of :func:`register`'s integrator.
NAME = "npsim_onebounce"

_registered: set[str] = set()


def available(mi) -> bool:
    """True when the current Mitsuba variant can use the integrator (a JIT variant)."""
    return not mi.variant().startswith("scalar")


def register(mi) -> bool:
    """Register :data:`NAME` for the current variant (once); False (nothing registered) for the
    scalar variants."""
    variant = mi.variant()
    if not available(mi):
        return False
    if variant in _registered:
        return True
    import drjit as dr

    def mis(a, b):
        a2, b2 = dr.square(a), dr.square(b)
        w = a2 / (a2 + b2)
        return dr.select(dr.isfinite(w), w, 0.0)

    class OneBounce(mi.SamplingIntegrator):
        """Camera ray, NEE + BSDF sample with MIS at the first vertex, NEE at the second (module doc)."""

        def sample(self, scene, sampler, ray, medium=None, active=True):
            ctx = mi.BSDFContext()
            active = mi.Bool(active)
            si = scene.ray_intersect(ray, ray_flags=mi.RayFlags.All, coherent=True, active=active)
            L = si.emitter(scene, active).eval(si, active)  # emitters (and the sky) seen directly
            valid = active & si.is_valid()
            bsdf = si.bsdf(ray)

            def nee(si_, bsdf_, active_, full_weight, scale=1.0):
                """Next-event estimate at ``si_``: MIS-weighted against the BSDF's own sample, or at
                weight 1 where ``full_weight`` (and for delta lights); times ``scale`` (the path's throughput)."""
                a = active_ & mi.has_flag(bsdf_.flags(), mi.BSDFFlags.Smooth)
                ds, em_w = scene.sample_emitter_direction(si_, sampler.next_2d(a), True, a)
                a &= ds.pdf != 0.0
                val, pdf = bsdf_.eval_pdf(ctx, si_, si_.to_local(ds.d), a)
                return dr.select(a, scale * dr.select(ds.delta | full_weight, 1.0, mis(ds.pdf, pdf)) * val * em_w, 0.0)

            # first vertex: NEE, MIS-weighted against the BSDF sample below
            L += nee(si, bsdf, valid, mi.Bool(False))
            # the bounce: emitters it hits (MIS), then the second vertex
            bs, bw = bsdf.sample(ctx, si, sampler.next_1d(valid), sampler.next_2d(valid), valid)
            beta = dr.select(valid, bw, 0.0)
            alive = valid & dr.any(beta != 0.0)
            ray2 = si.spawn_ray(si.to_world(bs.wo))
            si2 = scene.ray_intersect(ray2, ray_flags=mi.RayFlags.All, coherent=False, active=alive)
            ds2 = mi.DirectionSample3f(scene, si=si2, ref=si)
            delta = mi.has_flag(bs.sampled_type, mi.BSDFFlags.Delta)
            w_hit = dr.select(delta, 1.0, mis(bs.pdf, scene.pdf_emitter_direction(si, ds2, alive & ~delta)))
            L += dr.select(alive, beta * w_hit * si2.emitter(scene, alive).eval(si2, alive), 0.0)
            # second vertex: NEE alone (weight 1 on diffuse, its MIS weight on glossy surfaces)
            alive2 = alive & si2.is_valid()
            bsdf2 = si2.bsdf(ray2)
            L += nee(si2, bsdf2, alive2, ~mi.has_flag(bsdf2.flags(), mi.BSDFFlags.Glossy), beta)
            return L, active, []

    mi.register_integrator(NAME, lambda props: OneBounce(props))
    _registered.add(variant)
    return True
