"""Against a Cycles reference: accumulation converges, and ray reuse plus the temporal
filter beat the same rays without them."""
import os

import numpy as np
import pytest

from conftest import SCENES
from gpu_harness import passes_lamp_split
from ssr_addon.core.settings import ChainSettings

pytestmark = [pytest.mark.blender, pytest.mark.slow]

RESOLUTION = (160, 90)


@pytest.fixture(scope="module")
def spheres(gpu_backend):
    """EEVEE passes and a Cycles reference of the rough-spheres scene, rendered once."""
    from ssr_addon.blender.render_passes import render_passes
    from ssr_addon.blender.render_setup import decide_render
    from ssr_addon.blender.scene_io import load_scene
    scene = load_scene(os.path.join(SCENES, "rough_spheres.py"))
    passes = render_passes(scene, decide_render(scene, "eevee", samples=8, resolution=RESOLUTION))
    cycles = render_passes(scene, decide_render(scene, "cycles", samples=256, resolution=RESOLUTION))
    reference = cycles.combined[..., :3]
    # Glossy pixels SSR is responsible for: the spheres below max_roughness, away from the
    # sun's highlight (a lamp, which both engines shade directly and differently). The highlight
    # is grown by two pixels: its rim, where the split's lobe and EEVEE's differ most, is still it.
    glossy = ((passes.roughness > 0.02) & (passes.roughness <= 0.45) & (passes.specular_color.mean(-1) > 0.3)
              & ~grown(passes_lamp_split(passes)[0].max(-1) >= 0.05, 2))
    assert glossy.sum() > 300
    return passes, reference, glossy


def grown(mask, pixels):
    """MASK with every pixel within PIXELS (8-connected steps) of it set."""
    for _ in range(pixels):
        padded = np.pad(mask, 1)
        mask = np.logical_or.reduce([padded[1 + dy:padded.shape[0] - 1 + dy, 1 + dx:padded.shape[1] - 1 + dx]
                                     for dy in (-1, 0, 1) for dx in (-1, 0, 1)])
    return mask


def chain_final(spheres, settings, frames=1, first_frame=0):
    """The composited image of a still (FRAMES 1) or after FRAMES animation frames of a static
    camera, numbered from FIRST_FRAME."""
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.inputs import ChainInputs
    from ssr_addon.core.gpu_backend import download
    passes = spheres[0]
    inputs = ChainInputs.from_passes(passes, settings)
    state = ChainState.still() if frames == 1 else ChainState()
    for frame in range(first_frame, first_frame + frames):
        state.begin_frame(frame)
        outputs = run_chain(inputs, settings, state)
    final = download(outputs["final"])[..., :3]
    assert np.isfinite(final).all()
    return final


def chain_error(spheres, settings, frames=1):
    """RMSE against Cycles on the glossy pixels."""
    _, reference, glossy = spheres
    final = chain_final(spheres, settings, frames)
    return float(np.sqrt(np.mean((final[glossy] - reference[glossy]) ** 2)))


# The Monte Carlo estimator alone: the spatial filter and the firefly guard remove most of a
# single iteration's noise, which would hide whether accumulation itself converges.
ESTIMATOR_ONLY = dict(use_spatial_filter=False, use_firefly_guard=False, noise_threshold=0.0)


def test_accumulation_adds_no_error_against_cycles(spheres):
    """Against Cycles this scene's error is bias (EEVEE's lighting), not noise: from 1 to 64
    iterations its MSE moves by under 2 %, either way (1 and 16 iterations land within 1e-6
    of each other by chance). That accumulation converges is held elsewhere: to the exact
    lobe integral (test_glossy_resolve), at 1/sqrt(n) (below), until converged (below).
    Here: accumulating must not add error beyond 2 % (the ratio estimator's few-sample bias
    may land on either side of Cycles; since the resolve reuses no ray from another surface,
    the spheres' contacts with the floor included, 16 iterations land 1.3 % above one),
    and the reflections must beat the probes."""
    errors = {n: chain_error(spheres, ChainSettings(accumulate_iterations=n, **ESTIMATOR_ONLY)) for n in (1, 16)}
    probe_only = chain_error(spheres, ChainSettings(use_ssr=True, max_roughness=0.0))
    print("RMSE vs Cycles by accumulated frames:", errors, "probe only:", probe_only)
    assert errors[16] <= 1.02 * errors[1]
    assert errors[16] < 0.95 * probe_only


def test_noise_halves_when_accumulated_frames_quadruple(spheres):
    """Two stills of different frames draw disjoint points of the sequence, so they differ by
    the noise; it falls at least as 1/sqrt(frames). The cones are off: they narrow as the
    history grows (history_lib.glsl), trading their noise reduction for less blur, so with
    them each later iteration is noisier by design."""
    glossy = spheres[2]
    noise = {}
    for frames in (1, 4, 16):
        settings = ChainSettings(accumulate_iterations=frames, use_cone_filter=False, **ESTIMATOR_ONLY)
        a = chain_final(spheres, settings, first_frame=0)
        b = chain_final(spheres, settings, first_frame=1)
        noise[frames] = float(np.sqrt(np.mean((a[glossy] - b[glossy]) ** 2) / 2))
    print("noise RMS by accumulated frames:", noise)
    assert noise[4] < 0.6 * noise[1]
    assert noise[16] < 0.6 * noise[4]


def test_reuse_and_temporal_filter_beat_the_same_rays_without_them(spheres):
    """Four frames of one half-resolution ray per pixel each, static camera (noise_threshold off:
    the same rays, not as many as convergence takes; no sharp rays: every pixel reuses)."""
    only_half_resolution_rays = dict(use_sharp_rays=False)
    plain = chain_error(spheres, ChainSettings(resolve_samples=1, use_temporal=False, **only_half_resolution_rays),
                        frames=4)
    reuse = chain_error(spheres, ChainSettings(resolve_samples=4, use_temporal=False, **only_half_resolution_rays),
                        frames=4)
    both = chain_error(spheres, ChainSettings(resolve_samples=4, use_temporal=True, accumulate_iterations=1,
                                              noise_threshold=0.0, **only_half_resolution_rays), frames=4)
    print(f"RMSE: no reuse/no temporal {plain:.4f}, reuse {reuse:.4f}, reuse + temporal {both:.4f}")
    assert reuse < plain
    assert both < reuse


def still_reflection(spheres, settings):
    """(premultiplied reflection RGB, iterations run) of a still."""
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.inputs import ChainInputs
    from ssr_addon.core.gpu_backend import download
    state = ChainState.still()
    state.begin_frame(0)
    outputs = run_chain(ChainInputs.from_passes(spheres[0], settings), settings, state)
    return download(outputs["reflection"])[..., :3], outputs.iterations


def test_a_still_accumulates_until_converged(spheres):
    """noise_threshold's promise: the still keeps doubling its iterations until doubling moves the
    reflection by less than the threshold, so it ends within about that of a 256-iteration still,
    where a fixed 4 iterations are not."""
    glossy = spheres[2]
    converged, _ = still_reflection(spheres, ChainSettings(accumulate_iterations=256, **ESTIMATOR_ONLY))
    level = converged[glossy].mean()

    def distance(reflection):
        return float(np.abs(reflection[glossy] - converged[glossy]).mean() / level)
    threshold = 0.02
    fixed, fixed_iterations = still_reflection(spheres, ChainSettings(accumulate_iterations=4, **ESTIMATOR_ONLY))
    adaptive, iterations = still_reflection(
        spheres, ChainSettings(accumulate_iterations=4, **{**ESTIMATOR_ONLY, "noise_threshold": threshold}))
    print(f"distance to 256 iterations: fixed {fixed_iterations} {distance(fixed):.4f}, "
          f"adaptive {iterations} {distance(adaptive):.4f}")
    assert fixed_iterations == 4 and distance(fixed) > threshold, "the scene must need more than 4 iterations"
    assert 4 < iterations < 256
    assert distance(adaptive) <= 1.5 * threshold


def test_the_live_view_stops_where_the_render_stops(spheres):
    """The live view and `preview` refine a view a few iterations per tick (ProgressiveView); on
    the same passes they must end on the render's iterations and its image, whatever the ticks."""
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.progressive import ProgressiveView
    settings = ChainSettings()
    rendered, rendered_iterations = still_reflection(spheres, settings)
    refining = ProgressiveView(spheres[0], settings)
    refining.step()
    while not refining.done:
        refining.step(max_iterations=3)  # ticks that cut across the render's doublings
    live = download(refining.outputs["reflection"])[..., :3]
    assert rendered_iterations > settings.accumulate_iterations, "the still must need a doubling"
    assert refining.iterations == rendered_iterations
    np.testing.assert_allclose(live, rendered, atol=1e-5)


def test_convergence_check_measures_the_change_per_reflecting_tile(gpu_backend):
    """The GPU tile sums (convergence.ConvergenceCheck) on changes whose answer is known: every
    tile counts alike, pixels that reflect at neither check do not count, and there is nothing
    to compare with on the first check, after forget() or when the size changes."""
    from ssr_addon.core.convergence import ConvergenceCheck
    from ssr_addon.core.gpu_backend import TexturePool, upload
    pool, check = TexturePool(), ConvergenceCheck()
    height, width = 20, 40  # 3 x 2 tiles of 16 pixels, the last column and row partial
    steady = np.ones((height, width, 4), np.float32)

    def change(image):
        return check.change(upload(image), pool)
    assert change(steady) is None
    assert change(1.1 * steady) == pytest.approx(0.1 / 1.1, rel=1e-5)  # a uniform 10 % change
    object_moved = 1.1 * steady
    object_moved[height - 16:, :16, :3] *= 1.5  # one full tile (tiles count from the bottom-left)
    assert change(object_moved) == pytest.approx((0.5 / 1.5) / 6, rel=1e-5)
    hole = object_moved.copy()
    hole[:, 16:32] = 0.0                        # the middle tiles reflect at neither check ...
    sparse = hole.copy()
    sparse[height - 1, 16, :] = 5.0             # ... but for one pixel, under a quarter of its tile
    check.forget()
    assert change(hole) is None
    assert change(sparse) == pytest.approx(0.0, abs=1e-6)  # the other four tiles did not move
    assert check.change(upload(steady[:, :32]), pool) is None  # another size: no yardstick
