"""The deck's resolve slides: importance sampling, reusing neighbours' rays, sparse tracing and
filtered importance sampling, each measured as noise (one iteration against the same chain
settled) and as error against Cycles."""
from .intro import MIRROR
from .section import CONVERGED, ONE_ITERATION, section

GLOSSY = "wet_street"  # a wet street whose roughness varies across it: glossy reflections, visibly noisy
# Where the street reflects the lit windows and lamps, enlarged.
GLOSSY_INSET = (0.35, 0.55, 0.65, 0.85)
# Where the mirror floor reflects the green cube and the marker's edges, enlarged.
MIRROR_INSET = (0.40, 0.45, 0.60, 0.80)


def _noise(context, **settings):
    """(one iteration's Render, its noise) of the chain with SETTINGS on the glossy street."""
    render, = context.chain(GLOSSY, **ONE_ITERATION, **settings)
    converged, = context.chain(GLOSSY, **CONVERGED)
    return render, context.noise(GLOSSY, render, converged)


def _with_inset(context, label, stem, rgb, box=GLOSSY_INSET):
    """The image (label, STEM.png) of RGB and its part BOX enlarged (STEM_inset.png)."""
    return [(label, context.save(f"{stem}.png", rgb)),
            (f"{label}, enlarged", context.save_inset(f"{stem}_inset.png", rgb, box), "inset")]


def importance_sampling(context):
    images, numbers = [], {}
    for sampling, label in (("halton", "GGX lobe, Halton points"), ("random", "GGX lobe, random points"),
                            ("uniform", "Uniform over the hemisphere")):
        render, numbers[f"{sampling}_noise"] = _noise(context, ray_sampling=sampling)
        settled, = context.chain(GLOSSY, accumulate_iterations=16, noise_threshold=0.0, ray_sampling=sampling)
        numbers[f"{sampling}_noise16"] = context.noise(GLOSSY, settled, context.chain(GLOSSY, **CONVERGED)[0])
        images.append((f"{label}, one iteration", context.save(f"sampling_{sampling}.png", render.final)))
    return section("Importance Sampling: BRDF, Halton sequence", images, numbers,
                   "Rays drawn where the BRDF is large carry most of the light; drawn evenly over the "
                   "hemisphere, most of them land where the lobe is faint, and the few that count make "
                   "speckles. Noise (mean difference from the settled image on the reflective pixels, "
                   "relative to their level) after one iteration: GGX with Halton points {halton_noise}, "
                   "with random points {random_noise}, uniform {uniform_noise}. After 16 iterations: {halton_noise16}, "
                   "{random_noise16} and {uniform_noise16}: a pixel's Halton points fill the lobe's strata "
                   "evenly, so its error falls faster than with independent random points.")


def neighbour_reuse(context):
    images, numbers = [], {}
    for samples, label in ((1, "No ray reuse"), (4, "4 neighbor reuse = 4 resolve samples")):
        render, numbers[f"reuse{samples}_noise"] = _noise(context, resolve_samples=samples)
        numbers[f"reuse{samples}_resolve_ms"] = render.iteration_ms("resolve")
        images += _with_inset(context, f"1 ray per 2x2 pixels, {label}", f"reuse_{samples}", render.final)
    return section("Weighing Neighbors", images, numbers,
                   "Nearby pixels see nearly the same reflection, so each pixel also reads its neighbours' "
                   "rays, weighted by its own BRDF over the pdf they were drawn with (the ratio estimator). "
                   "One iteration, noise against the settled image: {reuse1_noise} with its own ray only, "
                   "{reuse4_noise} with 4 resolve samples; the resolve took {reuse1_resolve_ms} ms and "
                   "{reuse4_resolve_ms} ms.")


# The sparse slide's variants: (name, chain settings, the stages whose cost it compares, label).
_SPARSE_VARIANTS = (
    ("full", dict(half_resolution=False), ("trace",), "1 ray per pixel, resolved per pixel"),
    ("half_resolve", dict(half_resolution=True, resolve_resolution="half"), ("resolve",),
     "1 ray per 2x2 pixels, resolved at half resolution and scaled up"),
    ("half", dict(half_resolution=True, resolve_resolution="full"), ("trace", "resolve"),
     "1 ray per 2x2 pixels, resolved at full resolution"))


def sparse_ray_tracing(context):
    """On the mirror floor, whose sharp reflections show where a resolve blurs."""
    images, numbers = [], {}
    every_pixel, = context.chain(MIRROR, **_SPARSE_VARIANTS[0][1])  # the first variant: what the others approximate
    for name, settings, stages, label in _SPARSE_VARIANTS:
        render, = context.chain(MIRROR, **settings)
        if name != _SPARSE_VARIANTS[0][0]:
            numbers[f"{name}_gap"] = context.noise(MIRROR, render, every_pixel)
        numbers.update({f"{name}_{metric}": value for metric, value in context.error(MIRROR, render).items()})
        for stage in stages:
            numbers[f"{name}_{stage}_ms"] = render.iteration_ms(stage)
        numbers[f"{name}_iterations"] = render.images.stats["iterations"]
        numbers[f"{name}_rays"] = render.images.stats["traced_rays"]
        images += _with_inset(context, label, f"sparse_{name}", render.final, MIRROR_INSET)
    return section("Sparse Ray Tracing", images, numbers,
                   "Tracing is decoupled from the colour resolve: rays are traced for one pixel of each 2x2 "
                   "quad, and every full-resolution pixel resolves its colour from the four nearest, weighed "
                   "by its own BRDF. Resolved at half resolution instead and scaled up, the reflection blurs "
                   "across its edges. Each still ran until it settled ({full_iterations}, "
                   "{half_resolve_iterations} and {half_iterations} iterations). FLIP against Cycles: "
                   "{full_flip} tracing every pixel; tracing a quarter, {half_resolve_flip} resolving at half "
                   "resolution, {half_flip} at full (relative MAE {full_rel_mae}, {half_resolve_rel_mae} and "
                   "{half_rel_mae}); their mean difference from tracing every pixel, relative to its level, is "
                   "{half_resolve_gap} and {half_gap}. An iteration traced {full_rays} rays in {full_trace_ms} ms "
                   "for every pixel and {half_rays} in {half_trace_ms} ms for a quarter; its resolve "
                   "{half_resolve_resolve_ms} ms at half "
                   "resolution and {half_resolve_ms} ms at full.")


def filtered_importance_sampling(context):
    images, numbers = [], {}
    for cone, name, label in ((False, "monte_carlo", "Monte Carlo"), (True, "cone", "Mixed with cone sampling")):
        render, numbers[f"{name}_noise"] = _noise(context, use_cone_filter=cone)
        settled, = context.chain(GLOSSY, use_cone_filter=cone)
        numbers[f"{name}_flip"] = context.error(GLOSSY, settled)["flip"]
        images += _with_inset(context, f"{label}, one iteration", f"cones_{name}", render.final)
    return section("Filtered Importance Sampling", images, numbers,
                   "Each ray is read as a cone: from a blurred level of the colour pyramid, wider as the "
                   "surface is rougher and the hit farther, so a few rays cover the lobe instead of "
                   "sampling points of it. One iteration, noise against the settled image: Monte Carlo "
                   "{monte_carlo_noise}, with cones {cone_noise}. Settled, FLIP against Cycles: "
                   "{monte_carlo_flip} and {cone_flip}.")
