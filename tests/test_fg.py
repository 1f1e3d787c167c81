"""The pre-integrated FG term: the DFG table against numpy, and FG from the F0 AOV against the
engine's own specular colour."""
import os

import numpy as np
import pytest

from conftest import SCENES
from gpu_harness import run_synthetic_chain
from oracles import dfg_table, hammersley
from synthetic import facing_plane
from ssr_addon.core.settings import ChainSettings
from ssr_addon.core.gpu_passes import DFG_SAMPLES, DFG_SIZE

pytestmark = pytest.mark.blender


@pytest.fixture(scope="module")
def gpu_table(gpu_backend):
    """The FG table the chain composites with, after it has run a frame."""
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.gpu_passes import dfg_table as chain_dfg_table
    depth, normal, projection = facing_plane(8, 8)
    run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, ChainSettings())
    return download(chain_dfg_table())[::-1, :, :2]  # rows: roughness upwards, as the numpy table


def test_dfg_table_matches_numpy_on_the_same_points(gpu_table):
    u1, u2 = hammersley(DFG_SAMPLES)
    np.testing.assert_allclose(gpu_table, dfg_table(DFG_SIZE, u1, u2), atol=2e-4)


def test_dfg_table_is_converged_and_conserves_energy(gpu_table):
    converged = dfg_table(DFG_SIZE, *hammersley(1 << 15))
    np.testing.assert_allclose(gpu_table, converged, atol=0.015)  # grazing angles converge slowest
    albedo = gpu_table.sum(-1)
    assert (albedo <= 1.0 + 1e-3).all(), "a BRDF reflects no more than arrives"
    assert albedo[0, -1] == pytest.approx(1.0, abs=0.01), "a smooth surface seen head on reflects all"
    assert albedo[-1, -1] < 0.5 * albedo[0, -1], "single scattering: rough microfacets shadow each other"


@pytest.mark.slow
def test_fg_from_the_f0_aov_matches_eevee_specular_colour(gpu_backend):
    """EEVEE weights reflected light by its own split-sum FG: ours, from the F0 AOV, must agree."""
    from ssr_addon.blender.render_passes import render_passes
    from ssr_addon.blender.render_setup import decide_render
    from ssr_addon.blender.scene_io import load_scene
    scene = load_scene(os.path.join(SCENES, "rough_spheres.py"))
    passes = render_passes(scene, decide_render(scene, "eevee", samples=1, resolution=(160, 90)))
    metal = passes.roughness <= 0.5
    # Metals: F0 is the base colour (spheres (0.95, 0.8, 0.6), floor 0.8), whatever the view angle.
    sphere = np.abs(passes.roughness - 0.25) < 0.01
    assert sphere.sum() > 50
    np.testing.assert_allclose(passes.f0[sphere], np.broadcast_to((0.95, 0.8, 0.6), passes.f0[sphere].shape),
                               atol=5e-3)
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.gpu_passes import dfg_table as chain_dfg_table
    from ssr_addon.core.inputs import ChainInputs
    settings = ChainSettings(accumulate_iterations=1)
    state = ChainState.still()
    state.begin_frame(1)
    run_chain(ChainInputs.from_passes(passes, settings), settings, state)
    table = download(chain_dfg_table())[::-1, :, :2]
    # FG per pixel: F0 * A + B at the pixel's n.v and roughness (nearest texel).
    view = passes.view_matrix[:3, :3] @ passes.normal.reshape(-1, 3).T
    from oracles import view_positions
    _, incident = view_positions(passes.depth, np.linalg.inv(passes.projection_matrix))
    n_dot_v = np.clip(np.sum(view.T.reshape(incident.shape) * -incident, -1), 0, 1)
    column = np.minimum((n_dot_v * DFG_SIZE).astype(int), DFG_SIZE - 1)
    row = np.minimum((passes.roughness * DFG_SIZE).astype(int), DFG_SIZE - 1)
    scale_bias = table[row, column]
    fg = passes.f0 * scale_bias[..., :1] + scale_bias[..., 1:]
    glossy = metal & (passes.specular_color.max(-1) > 0.1) & (n_dot_v > 0.2)
    relative = np.abs(fg[glossy] - passes.specular_color[glossy]) / passes.specular_color[glossy]
    print("FG vs EEVEE specular colour, relative error percentiles:", np.percentile(relative, [50, 90]))
    assert np.median(relative) < 0.05


@pytest.mark.slow
def test_a_viewport_capture_without_f0_composites_as_with_it(gpu_backend):
    """A viewport capture draws no F0 AOV (a draw less a moving view's update): the composite's FG
    is then EEVEE's own specular colour. Over the same passes, the image must be the one FG from
    the F0 AOV and the add-on's DFG table gives, to the table's own precision."""
    from dataclasses import replace
    from ssr_addon.blender.material_aovs import F0_AOV, ROUGHNESS_AOV
    from ssr_addon.blender.overrides import TemporaryChanges
    from ssr_addon.blender.render_passes import undo_coverage
    from ssr_addon.blender.render_setup import rendered_view_layer
    from ssr_addon.blender.scene_io import camera_matrices, load_scene
    from ssr_addon.blender.viewport_capture import ViewportCapture, headless_view3d
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    from ssr_addon.core.inputs import ChainInputs
    scene = load_scene(os.path.join(SCENES, "rough_spheres.py"))
    view_layer = rendered_view_layer(scene)
    size = (160, 90)
    view, projection = (np.asarray(matrix) for matrix in camera_matrices(scene, *size))
    capture = ViewportCapture(*headless_view3d())
    try:
        with TemporaryChanges() as changes:
            capture.hold_for_captures(changes)
            capture.hold_set_up(scene, view_layer, changes)
            passes = capture.capture(scene, view_layer, view, projection, size,
                                     (scene.camera.data.clip_start, scene.camera.data.clip_end), samples=1)
            aovs = capture.draw_passes(scene, view_layer, view, projection, size,
                                       {name: (name, 3, 1) for name in (F0_AOV, ROUGHNESS_AOV)})
    finally:
        capture.release()
    assert passes.f0 is None
    with_f0 = replace(passes, f0=undo_coverage(aovs[F0_AOV], aovs[ROUGHNESS_AOV][..., 1], fallback=0.0))
    settings = ChainSettings(fallback="off")
    images = []
    for frame_passes in (passes, with_f0):
        state = ChainState.still()
        state.begin_frame(1)
        outputs = run_chain(ChainInputs.from_passes(frame_passes, settings), settings, state)
        images.append(download(outputs["final"])[..., :3])
    reflective = (passes.roughness <= 0.5) & (passes.specular_color.mean(-1) >= 0.1)
    assert reflective.sum() > 1000
    without, reference = images[0][reflective], images[1][reflective]
    relative = float(np.abs(without - reference).sum() / np.abs(reference).sum())
    print("composite without F0 against with it, relative L1 on the reflective pixels:", relative)
    assert relative <= 0.015  # the DFG table's own convergence at grazing angles (test above)
