"""lamp_split=analytic: lamp highlights computed from the scene's lights instead of a second render.

The GPU pass is checked against a plain Monte Carlo integral (random points on the lamp,
the albedo from random hemisphere directions: neither of the pass's two strategies nor its
table), and the whole split against EEVEE's own, rendered one.
"""
import math

import bpy
import numpy as np
import pytest

from conftest import metal_floor_under
from synthetic import perspective
from gpu_harness import lamp_specular, passes_lamp_split
from ssr_addon.blender.render_passes import render_passes
from ssr_addon.blender.render_setup import decide_lamp_split, decide_render
from ssr_addon.core.errors import SSRError
from ssr_addon.core.lamp_split import Lamp

pytestmark = [pytest.mark.blender, pytest.mark.slow]

HEIGHT = 2.0  # the camera looks straight down at the floor z = 0 from this height
HALF_FOV = math.radians(30)
SIZE = (48, 32)


def _camera():
    """View and projection matrices of a camera at (0, 0, HEIGHT) looking down -z."""
    view = np.eye(4)
    view[2, 3] = -HEIGHT
    return view, perspective(*SIZE, fov_y_degrees=math.degrees(2 * HALF_FOV)).astype(np.float64)


def _floor_point(row, column):
    aspect = SIZE[0] / SIZE[1]
    x = ((column + 0.5) / SIZE[0] * 2 - 1) * math.tan(HALF_FOV) * aspect * HEIGHT
    y = (1 - (row + 0.5) / SIZE[1] * 2) * math.tan(HALF_FOV) * HEIGHT
    return np.array([x, y, 0.0])


def _ggx_brdf_cos(normal, view, light, alpha):
    n_dot_v, n_dot_l = view @ normal, light @ normal
    half = (view + light) / np.linalg.norm(view + light, axis=-1, keepdims=True)
    n_dot_h = half @ normal
    a2 = alpha * alpha
    d = a2 / (math.pi * (n_dot_h ** 2 * (a2 - 1) + 1) ** 2)
    lambda_v = 0.5 * (np.sqrt(1 + a2 * (1 - n_dot_v ** 2) / n_dot_v ** 2) - 1)
    lambda_l = 0.5 * (np.sqrt(1 + a2 * (1 - n_dot_l ** 2) / np.maximum(n_dot_l ** 2, 1e-12)) - 1)
    return np.where(n_dot_l > 0, d / (4 * n_dot_v * (1 + lambda_v + lambda_l)), 0.0)


def _monte_carlo(lamp, point, roughness, rng, count=1_600_000):
    """Radiance-weighted integral of the normalised GGX lobe over LAMP (an upward-facing
    rectangle or a sun) seen from POINT on the floor, by uniform random sampling."""
    normal = np.array([0.0, 0.0, 1.0])
    view = np.array([0.0, 0.0, HEIGHT]) - point
    view /= np.linalg.norm(view)
    alpha = roughness ** 2
    # The lobe's reflectance: half vectors drawn from D(h) cos(theta_h) (not the visible normals).
    u1, u2 = rng.random(count), rng.random(count)
    cos_h = np.sqrt((1 - u1) / (1 + (alpha * alpha - 1) * u1))
    sin_h = np.sqrt(1 - cos_h ** 2)
    half = np.stack([sin_h * np.cos(2 * np.pi * u2), sin_h * np.sin(2 * np.pi * u2), cos_h], -1)
    v_dot_h = half @ view
    reflected = 2 * v_dot_h[:, None] * half - view
    pdf = alpha ** 2 / (math.pi * (cos_h ** 2 * (alpha ** 2 - 1) + 1) ** 2) * cos_h / (4 * np.abs(v_dot_h))
    albedo = np.mean(np.where(v_dot_h > 0, _ggx_brdf_cos(normal, view, reflected, alpha) / pdf, 0.0))
    if lamp.shape == "sun":  # a disk of angular radius atan(half_size) around the direction
        tangent = np.cross(lamp.position, [1.0, 0.0, 0.0])
        tangent /= np.linalg.norm(tangent)
        bitangent = np.cross(lamp.position, tangent)
        centre, x_axis, y_axis, ellipse = np.asarray(lamp.position), tangent, bitangent, True
    else:
        centre, x_axis, y_axis, ellipse = np.asarray(lamp.position) - point, np.asarray(lamp.x_axis), \
            np.asarray(lamp.y_axis), lamp.shape == "ellipse"
    a, b = rng.random(count) * 2 - 1, rng.random(count) * 2 - 1
    keep = (a * a + b * b <= 1) if ellipse else np.ones(count, bool)
    area = 4 * lamp.half_size[0] * lamp.half_size[1]
    points = centre + (a[:, None] * lamp.half_size[0]) * x_axis + (b[:, None] * lamp.half_size[1]) * y_axis
    distance = np.linalg.norm(points, axis=-1)
    directions = points / distance[:, None]
    cosine = np.abs(directions @ np.cross(x_axis, y_axis))
    integrand = _ggx_brdf_cos(normal, view, directions, alpha) / albedo * cosine / distance ** 2
    return np.asarray(lamp.radiance) * area * np.mean(np.where(keep, integrand, 0.0))


LAMPS = {
    "area": Lamp(name="area", shape="rect", radiance=(30.0, 20.0, 10.0), position=(0.3, 0.8, 1.2),
                 x_axis=(1.0, 0.0, 0.0), y_axis=(0.0, 1.0, 0.0), z_axis=(0.0, 0.0, 1.0), half_size=(0.4, 0.2)),
    "sun": Lamp(name="sun", shape="sun", radiance=(2000.0, 2000.0, 2000.0),
                position=tuple(np.array([0.2, 0.3, 1.0]) / np.linalg.norm([0.2, 0.3, 1.0])),
                half_size=(0.05, 0.05)),
}


@pytest.mark.parametrize("lamp_name", sorted(LAMPS))
@pytest.mark.parametrize("roughness", [0.15, 0.35, 0.6])
def test_the_lamp_pass_matches_a_monte_carlo_integral(gpu_backend, lamp_name, roughness):
    """On a floor seen from above, the pass's integral of each lamp agrees with a plain Monte
    Carlo estimate (1.6M random points, itself within 1 %) wherever the highlight is at least a
    tenth of its peak, from the mirror-like to the rough: to 2 % over the highlight, to 5 % on
    any pixel (the fixed 12x12 pattern is coarsest where a sharp highlight's edge crosses it)."""
    lamp = LAMPS[lamp_name]
    view, projection = _camera()
    depth = np.full(SIZE[::-1], HEIGHT, np.float32)
    normal = np.zeros(SIZE[::-1] + (3,), np.float32)
    normal[..., 2] = 1
    computed = lamp_specular([lamp], depth, normal, np.full(SIZE[::-1], roughness, np.float32), view, projection)
    rng = np.random.default_rng(7)
    peak = computed[..., 0].max()
    assert peak > 0, "the lamp must light the floor"
    lit = np.argwhere(computed[..., 0] >= 0.1 * peak)  # the highlight, and ten pixels across it
    assert len(lit) >= 3
    chosen = lit[np.linspace(0, len(lit) - 1, min(10, len(lit))).astype(int)]
    expected = np.array([_monte_carlo(lamp, _floor_point(row, column), roughness, rng) for row, column in chosen])
    got = computed[chosen[:, 0], chosen[:, 1]]
    np.testing.assert_allclose(got, expected, rtol=0.05)  # a pixel on a highlight's sharp edge
    assert abs(got.sum() / expected.sum() - 1) <= 0.02  # the split's own bound, over the highlight


def test_a_perfect_mirror_shows_a_lamp_only_in_its_mirror_image(gpu_backend):
    """Roughness 0 is a perfect mirror to EEVEE and Cycles alike: the sun lights it where the
    mirror image of its disk falls, fully, and nowhere else. The rays' lobe floor (MIN_ALPHA) has
    a tail that lit the floor all round (up to 3.8e-5 of the sun's radiance more than 5 degrees
    from its image)."""
    lamp = LAMPS["sun"]
    view, projection = _camera()
    depth = np.full(SIZE[::-1], HEIGHT, np.float32)
    normal = np.zeros(SIZE[::-1] + (3,), np.float32)
    normal[..., 2] = 1
    computed = lamp_specular([lamp], depth, normal, np.zeros(SIZE[::-1], np.float32), view, projection)[..., 0]
    camera = np.array([0.0, 0.0, HEIGHT])
    off_image = np.zeros(SIZE[::-1], bool)
    for row in range(SIZE[1]):
        for column in range(SIZE[0]):
            view_direction = camera - _floor_point(row, column)
            view_direction /= np.linalg.norm(view_direction)
            mirrored = 2 * view_direction[2] * np.array([0.0, 0.0, 1.0]) - view_direction
            angle = math.degrees(math.acos(np.clip(mirrored @ np.asarray(lamp.position), -1, 1)))
            off_image[row, column] = angle > math.degrees(math.atan(lamp.half_size[0])) + 5.0
    assert off_image.sum() > 0.8 * off_image.size
    assert computed.max() == pytest.approx(lamp.radiance[0], rel=0.05)  # the disk's full radiance
    assert computed[off_image].max() <= 1e-6 * lamp.radiance[0], computed[off_image].max() / lamp.radiance[0]


LIGHTS = {
    "POINT": {"energy": 100, "shadow_soft_size": 0.2},
    "SPOT": {"energy": 300, "shadow_soft_size": 0.1, "spot_size": math.radians(70), "spot_blend": 0.3},
    "SUN": {"energy": 3, "angle": math.radians(3)},
    "AREA": {"energy": 150, "size": 1.0, "size_y": 0.4, "shape": "RECTANGLE"},
}


@pytest.fixture(scope="module", params=sorted(LIGHTS))
def floor_splits(request, gpu_backend):
    """(light type, the floor's exact split (lamp_split=render), its analytic lamp highlights,
    floor mask) on a glossy metal floor under one light of each type."""
    scene = metal_floor_under(request.param, **LIGHTS[request.param])
    exact = render_passes(scene, decide_render(scene, samples=8, lamp_split="render"))
    analytic, _ = passes_lamp_split(render_passes(scene, decide_render(scene, samples=8, lamp_split="analytic")))
    floor = exact.depth < 1e9
    assert exact.specular_direct[floor].sum() > 0, "the lamp must light the floor"
    return request.param, exact, analytic, floor


def test_the_analytic_lamps_carry_eevees_light(floor_splits):
    """Against EEVEE's lamps-only render, each light type's highlight carries the same light
    within 15 % (EEVEE integrates a fitted lobe, LTC, not GGX itself; a wrong unit convention
    is off by pi or more)."""
    light_type, exact, analytic, floor = floor_splits
    ratio = analytic[floor].sum() / exact.specular_direct[floor].sum()
    print(f"{light_type}: analytic / rendered highlight light {ratio:.3f}")
    assert 0.85 <= ratio <= 1.15


# Known gap (the Cost issue): EEVEE's LTC lobe is wider than GGX's near its peak and lighter in
# its tails, so on a floor lit by little but the highlight the split moves 8-15 % of the image.
@pytest.mark.xfail(strict=True, reason="the analytic lobe is GGX, EEVEE's is an LTC fit of it")
def test_the_analytic_split_moves_the_image_by_at_most_2_percent(floor_splits):
    """What the split's error can move in the final image, specular colour times the
    highlight's error, stays under 2 % of the image on the floor (the Cost issue's bound)."""
    light_type, exact, analytic, floor = floor_splits
    image_error = (exact.specular_color * np.abs(analytic - exact.specular_direct))[floor].sum() \
        / exact.combined[..., :3][floor].sum()
    print(f"{light_type}: share of the image {image_error:.2%}")
    assert image_error <= 0.02


def test_analytic_refuses_lights_it_cannot_model():
    """Light linking is beyond the analytic lamps: asking for them says which light stops
    them, in one line; auto is analytic until then, and a rendered split after."""
    scene = metal_floor_under("POINT", energy=100)
    assert decide_lamp_split(scene, "eevee", "analytic").method == "analytic"
    assert decide_lamp_split(scene, "eevee", "auto").method == "analytic"
    linked = bpy.data.collections.new("Linked")
    scene.objects["Lamp"].light_linking.receiver_collection = linked
    with pytest.raises(SSRError, match="'Lamp' uses light linking"):
        decide_lamp_split(scene, "eevee", "analytic")
    assert decide_lamp_split(scene, "eevee", "auto").method == "unshadowed"


def test_a_lamp_array_packs_only_the_lamps_given():
    """LampBlock's array is MAX_LAMPS long; lamp_block packs the scene's lamps alone, so the rest
    must read as zero (lamp_count bounds the shader's loop) and more than fit is an error."""
    from ssr_addon.core.uniforms import LAMP_BLOCK, LAMP_DATA, MAX_LAMPS
    lamp = {field: 1 for field in LAMP_DATA.offsets}
    values = {field: 0 for field in LAMP_BLOCK.offsets}
    words = LAMP_BLOCK.pack(dict(values, lamps=[lamp, lamp]))
    padded = LAMP_BLOCK.pack(dict(values, lamps=[lamp, lamp] + [{f: 0 for f in LAMP_DATA.offsets}] * (MAX_LAMPS - 2)))
    assert np.array_equal(words, padded) and words.any()
    with pytest.raises(ValueError, match="room for"):
        LAMP_BLOCK.pack(dict(values, lamps=[lamp] * (MAX_LAMPS + 1)))


def test_the_chain_splits_the_lamps_off_on_the_gpu(gpu_backend):
    """With lamp_split=analytic nothing is read back before the chain: the passes bring EEVEE's
    whole Specular Light and the lamps, and the chain splits them from the textures it uploads.
    Its image is the one the same split gives read back and uploaded, and the passes EXR holds
    the split the chain used: highlights and the rest make up the Specular Light."""
    import dataclasses
    import os

    from conftest import SCENES
    from ssr_addon.batch.frame import render_frame
    from ssr_addon.batch.request import RenderRequest
    from ssr_addon.blender.scene_io import load_scene
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.inputs import ChainInputs
    from ssr_addon.core.layers import exr_channels
    from ssr_addon.core.settings import ChainSettings
    scene = load_scene(os.path.join(SCENES, "mirror_floor.py"))
    # Screen space alone: a guard band would trace a wider frame than the passes read back.
    settings = ChainSettings(lamp_split="analytic", fallback="off")
    images, timer = render_frame(scene, RenderRequest(out_dir="", resolution=(64, 36), samples=4, settings=settings))
    passes = images.passes
    assert passes.lamps is not None and passes.lamp_light is None and "lamp_split" in timer.milliseconds

    channels = exr_channels(images.layers)
    direct, indirect = (np.stack([channels[f"Specular {part}.{c}"] for c in "RGB"], -1)
                        for part in ("Direct", "Indirect"))
    read_back = dataclasses.replace(passes, lamp_light=direct, lamps=None)
    state = ChainState.still()
    state.begin_frame(scene.frame_current)
    final = download(run_chain(ChainInputs.from_passes(read_back, settings), settings, state)["final"])
    np.testing.assert_allclose(images.final, final, atol=1e-6)

    assert direct.max() > 0.1, "the lamps must light the floor"
    np.testing.assert_allclose(direct, passes_lamp_split(passes)[0], atol=1e-6)
    np.testing.assert_allclose(direct + indirect, np.maximum(passes.specular_light, direct), rtol=1e-5, atol=1e-6)
