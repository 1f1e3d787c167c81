"""The live overlay's colours against Blender's own colour management: the baked LUT
(blender/colour_management.py, display_transform.glsl) must show a scene-linear image as `save_render`
writes it, for the view transforms, looks and exposures artists use."""
import numpy as np
import pytest

pytestmark = pytest.mark.blender



def hdr_colours(spread, size=(64, 48), seed=3):
    """Scene-linear colours over 19 stops of brightness, each channel up to SPREAD stops under
    the brightest, a band of greys and black included."""
    rng = np.random.default_rng(seed)
    stops = rng.uniform(-12.0, 7.0, size=(size[1], size[0], 1)) - rng.uniform(0.0, spread, size=(size[1], size[0], 3))
    stops[: size[1] // 4] = stops[: size[1] // 4, :, :1]
    rgb = np.exp2(stops)
    rgb[0, :8] = 0.0
    return np.concatenate([rgb, np.ones(rgb.shape[:2] + (1,))], axis=-1).astype(np.float32)


# Colours as renders hold them (channels at most 8:1 apart), and extremes: a pure primary whose
# other channels are a thousandth of it. Errors in steps of an 8-bit display: 3 steps is about
# 1 %, under the difference in brightness an eye notices.
REALISTIC = dict(spread=3.0, mean=0.25, tail=1.5, worst=3.0)
# The worst pixels sit where AgX's and Filmic's gamut handling bends hardest between lattice
# points: a few steps, about 2 %, on isolated pixels.
EXTREME = dict(spread=10.0, mean=0.25, tail=4.0, worst=8.0)


@pytest.mark.parametrize("colours", [REALISTIC, EXTREME], ids=["realistic", "extreme"])
@pytest.mark.parametrize("view_transform, look, exposure", [
    ("AgX", "None", 0.0), ("AgX", "AgX - Punchy", 1.5), ("Filmic", "None", -1.0), ("Standard", "None", 0.5)])
def test_overlay_colours_match_blender_colour_management(gpu_backend, view_transform, look, exposure,
                                                         colours):
    import bpy
    from ssr_addon.blender.colour_management import DisplayTransform, blender_display
    from ssr_addon.core.gpu_backend import TexturePool, download, upload
    from ssr_addon.blender.overrides import TemporaryChanges
    scene = bpy.context.scene
    rgba = hdr_colours(colours["spread"])
    with TemporaryChanges() as changes:
        changes.set_all(scene.view_settings, view_transform=view_transform, look=look, exposure=exposure)
        expected = blender_display(scene, rgba)
        shown = download(DisplayTransform().apply(scene, upload(rgba), TexturePool()))[..., :3]
    error = np.abs(shown - expected) * 255
    tail = np.percentile(error, 99.9)
    print(f"{view_transform}/{look}/{exposure}: mean {error.mean():.3f}, 99.9 % {tail:.2f}, max {error.max():.2f} steps")
    assert error.mean() <= colours["mean"] and tail <= colours["tail"] and error.max() <= colours["worst"]


def test_debug_views_get_the_plain_srgb_curve(gpu_backend):
    import bpy
    from ssr_addon.blender.colour_management import DisplayTransform
    from ssr_addon.core.gpu_backend import TexturePool, download, upload
    shown = download(DisplayTransform().apply(bpy.context.scene, upload(np.full((4, 4, 4), 0.5, np.float32)),
                                              TexturePool(), view_transform=False))
    assert shown[..., :3] == pytest.approx(0.7354, abs=1e-3)
