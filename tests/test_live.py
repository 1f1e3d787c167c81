"""Live SSR in the 3D View and the headless `preview` command (issue "Live SSR in the viewport").

The capture goes through EEVEE's viewport engine (draw_view3d on the startup
file's 3D View), so these tests see what the artist's viewport would give the
chain; the preview is checked against `render --method ssr` of the same frame,
which reads the passes another way (a final render's EXR).
"""
import json
import os

import bpy
import mathutils
import numpy as np
import pytest

import ssr_addon
from ssr_addon.blender.colour_management import blender_display
from ssr_addon.core.errors import SSRError
from ssr_addon.ui.live_session import DEBOUNCE_S, LiveSession
from ssr_addon.blender.overrides import TemporaryChanges
from ssr_addon.blender.scene_io import load_scene
from ssr_addon.ui import live
from ssr_addon.blender.viewport_capture import headless_view3d

from conftest import SCENES, read_exr, rgb, run_cli

pytestmark = [pytest.mark.blender, pytest.mark.slow]

RESOLUTION = "160x90"


def reflective_relative_error(image, reference, passes):
    """Relative L1 error of IMAGE against REFERENCE on the reflective pixels (as the bench counts them)."""
    specular = rgb(passes, "Specular Color").mean(axis=-1)
    reflective = (passes["Roughness.V"] <= 0.5) & (specular >= 0.1)
    assert reflective.sum() > 1000
    return float(np.abs(image - reference)[reflective].sum() / np.abs(reference)[reflective].sum())


def test_the_preview_of_the_camera_view_is_the_render_of_the_frame(tmp_path):
    # Both under the default fallback=auto: the preview draws the floor's planar capture where the
    # render renders it.
    run_cli("render", os.path.join(SCENES, "mirror_floor.py"), "--out", tmp_path / "render", "--method", "ssr",
            "--resolution", RESOLUTION)
    result = run_cli("preview", os.path.join(SCENES, "mirror_floor.py"), "--out", tmp_path / "preview",
                     "--resolution", RESOLUTION)
    assert "first image" in result.stdout
    render = rgb(read_exr(tmp_path / "render" / "frame_0001.exr"))
    passes = read_exr(tmp_path / "render" / "frame_0001.passes.exr")
    preview = rgb(read_exr(tmp_path / "preview" / "preview.exr"))
    without_ssr = rgb(passes, "Combined")
    # The bound; and SSR must show: the engine's own image is far from it.
    assert reflective_relative_error(preview, render, passes) <= 0.1
    assert reflective_relative_error(without_ssr, render, passes) > 0.1
    timings = json.loads((tmp_path / "preview" / "preview.json").read_text())
    # Where it stops on the same passes: test_convergence; these passes come through the viewport.
    assert timings["converged"] and timings["iterations"] >= 1
    assert timings["time_to_first_image_ms"] <= timings["time_to_last_image_ms"]
    assert set(timings["capture_ms"]) == {"capture", "planar_capture", "upload"}
    assert timings["chain_ms_per_iteration"] > 0
    assert "lamp_split" in timings["chain_stages_ms"]  # the analytic split: the chain's first pass
    assert (tmp_path / "preview" / "first.png").is_file() and (tmp_path / "preview" / "preview.png").is_file()


def test_bad_preview_arguments_get_one_line(tmp_path):
    result = run_cli("preview", os.path.join(SCENES, "mirror_floor.py"), "--out", tmp_path, "--iterations", "0",
                     check=False)
    assert result.returncode == 2
    assert result.stderr.strip().splitlines() == ["error: --iterations must be at least 1, got 0"]
    result = run_cli("preview", os.path.join(SCENES, "mirror_floor.py"), "--out", tmp_path / "orbit", "--orbit", "-2",
                     check=False)
    assert result.returncode == 2 and not (tmp_path / "orbit").exists()
    assert result.stderr.strip().splitlines() == ["error: --orbit must be 0 or more views, got -2"]
    result = run_cli("preview", os.path.join(SCENES, "mirror_floor.py"), "--out", tmp_path / "step", "--orbit", "2",
                     "--orbit-step", "0", check=False)
    assert result.returncode == 2 and not (tmp_path / "step").exists()
    assert result.stderr.strip().splitlines() == ["error: --orbit-step must be more than 0 and at most 180 degrees, "
                                                  "got 0"]


@pytest.fixture(scope="module")
def live_view(gpu_backend):
    """The mirror floor in the startup file's 3D View, Rendered shading, the add-on registered."""
    scene = load_scene(os.path.join(SCENES, "mirror_floor.py"))
    ssr_addon.register()
    try:
        space, region = headless_view3d()
        shading = space.shading.type
        space.shading.type = "RENDERED"
        scene.ssr.live_resolution = 10
        yield scene, space, region
        space.shading.type = shading
    finally:
        live.stop()
        ssr_addon.unregister()


def _tick_until(session, scene, clock, condition, limit=400):
    for _ in range(limit):
        clock[0] += DEBOUNCE_S
        session.tick(scene, now=clock[0])
        if condition():
            return
    raise AssertionError(f"not reached after {limit} ticks: {session.status}")


def test_a_still_view_refines_until_it_stops_and_a_change_restarts_it(live_view):
    from ssr_addon.core.gpu_backend import download
    scene, space, region = live_view
    session = LiveSession(space, region, space.region_3d)
    clock = [0.0]
    assert not session.tick(scene, now=clock[0]) and session.texture is None  # waits for the view to hold
    assert session.tick(scene, now=clock[0] + DEBOUNCE_S / 2) is False and session.texture is None
    _tick_until(session, scene, clock, lambda: session.texture is not None)
    held_capture = session._passes.capture
    assert held_capture is not None  # fallback=auto: the floor's planar capture, drawn through the view
    seen = [session._view.iterations]
    first_image = session.texture
    _tick_until(session, scene, clock, lambda: seen.append(session._view.iterations) or session._view.done)
    assert seen == sorted(seen) and seen[-1] > seen[0]
    assert "converged" in session.status and f"{seen[-1]} iterations" in session.status
    assert session.tick(scene, now=clock[0] + 1) is False  # converged: nothing more to draw
    assert session.texture is first_image  # the pool's display texture, redrawn in place
    converged = download(session.texture)

    scene.ssr.debug_view = "CONFIDENCE"  # another look at the same iterations: no new capture
    try:
        assert session.tick(scene, now=clock[0] + 1.5) is True
        assert not np.allclose(download(session.texture), converged) and session._view.iterations == seen[-1]
    finally:
        scene.ssr.debug_view = "FINAL"
    assert session.tick(scene, now=clock[0] + 1.6) is True and np.allclose(download(session.texture), converged)

    scene.view_settings.exposure += 1.0  # the colour management: shown anew, not recaptured
    try:
        assert session.tick(scene, now=clock[0] + 1.7) is True and session._view.iterations == seen[-1]
        assert download(session.texture)[..., :3].mean() > converged[..., :3].mean()
    finally:
        scene.view_settings.exposure -= 1.0

    aovs, nodes, samples = len(scene.view_layers[0].aovs), _material_nodes(), scene.eevee.taa_samples
    space.region_3d.view_location += mathutils.Vector((0.05, 0.0, 0.0))  # orbiting: followed at once
    draws = session.capture.draws
    assert session.tick(scene, now=clock[0] + 2) is True
    assert session.texture is not None and "moving" in session.status, session.status
    assert session._view.iterations == 1 and session._view.state.sequence.has_history  # the last view's, reprojected
    assert session._passes.capture is held_capture  # traced from the moving view, not drawn again
    assert scene.eevee.taa_samples == samples and session.capture.draws > draws
    assert session.tick(scene, now=clock[0] + 2 + DEBOUNCE_S / 2) is False  # holding: not yet refined
    assert len(scene.view_layers[0].aovs) > aovs  # the capture's set-up is held while the view moves...
    assert session.tick(scene, now=clock[0] + 2.01 + DEBOUNCE_S) is True and "iterations" in session.status
    assert (len(scene.view_layers[0].aovs), _material_nodes()) == (aovs, nodes)  # ...and put back once it holds

    draws = session.capture.draws
    thickness = scene.ssr.thickness
    scene.ssr.thickness = thickness * 2  # a setting the chain alone reads: re-run on the same passes
    try:
        assert session.tick(scene, now=clock[0] + 10) is True and session.texture is not None
        assert session.capture.draws == draws and session._view.iterations >= 1
    finally:
        scene.ssr.thickness = thickness
        session.release()


def _material_nodes():
    return sorted((material.name, len(material.node_tree.nodes)) for material in bpy.data.materials
                  if material.node_tree is not None)


def test_an_orbit_shows_ssr_in_every_view_and_history_only_helps(live_view, tmp_path):
    """preview --orbit: each moving view, shown after one iteration from the last view's history, is
    nearer a converged still of that view than one iteration of its own passes without history,
    SSR shows in every view, and the orbit flickers within the stability suite's limit and less
    than those iterations without history do."""
    from lab.bench.stability import FLICKER_LIMIT
    from lab.live_latency import orbit_quality
    from ssr_addon.core.settings import ChainSettings
    scene, _, _ = live_view
    timings, rows, flicker = orbit_quality(scene, tmp_path, ChainSettings(), (160, 90), 4)
    assert [row["view"] for row in rows] == [1, 2, 3, 4]
    for row in rows:
        assert row["moving"] <= row["without_history"], rows
        assert row["moving"] <= 0.1 < row["without_ssr"], rows  # the preview's bound; SSR shows
    assert flicker["moving"] <= min(FLICKER_LIMIT, flicker["without_history"]), flicker  # history steadies it
    assert all(view["history"] and view["draws"] >= 6 for view in timings["orbit"])
    assert timings["orbit_updates_per_second"] > 0
    assert all((tmp_path / "orbit" / f"view_{index:02d}.{extension}").is_file()
               for index in range(1, 5) for extension in ("exr", "png"))


def test_the_draw_handler_draws_the_sessions_image(live_view):
    """The handler's body draws the session's image as Blender's colour management shows it."""
    import gpu
    from ssr_addon.core.gpu_backend import download, upload
    scene, space, region = live_view
    session = LiveSession(space, region, space.region_3d)
    red = np.zeros((region.height, region.width, 4), np.float32)
    red[..., 0], red[..., 3] = 0.5, 1.0
    session._display(scene, upload(red), view_transform=True)
    offscreen = gpu.types.GPUOffScreen(region.width, region.height, format="RGBA32F")
    with offscreen.bind(), gpu.matrix.push_pop(), gpu.matrix.push_pop_projection():
        gpu.matrix.load_identity()  # pixel space, as a POST_PIXEL handler has it
        gpu.matrix.load_projection_matrix(mathutils.Matrix.Translation((-1.0, -1.0, 0.0)) @ mathutils.Matrix.Diagonal(
            (2.0 / region.width, 2.0 / region.height, 1.0, 1.0)))
        assert live.draw_session(session)
    drawn = download(offscreen.texture_color)
    offscreen.free()
    expected = blender_display(scene, red[:1, :1])[0, 0]  # the scene's view transform (AgX)
    assert np.allclose(drawn[..., :3], expected, atol=1.5 / 255)
    session._texture = None
    assert not live.draw_session(session)


def test_a_view_the_capture_cannot_use_stops_with_a_message(live_view):
    scene, space, region = live_view
    session = LiveSession(space, region, space.region_3d)
    for struct, name, value, message in ((space.shading, "type", "SOLID", "Material Preview or Rendered"),
                                         (scene.render, "engine", "CYCLES", "EEVEE")):
        with TemporaryChanges() as changes:
            changes.set(struct, name, value)
            with pytest.raises(SSRError, match=message):
                session.tick(scene)


def test_a_failing_draw_is_a_message_and_the_view_is_restored(live_view):
    scene, space, region = live_view
    session = LiveSession(space, region, space.region_3d)
    width, height = session.capture_size(scene)

    class BrokenOffscreen:  # offscreen EEVEE crashes in some Blender versions (GBuffer::acquire)
        def __init__(self):
            self.width, self.height = width, height

        def draw_view3d(self, *args, **kwargs):
            raise RuntimeError("GBuffer::acquire")

        def free(self):
            pass
    session.capture._offscreen = BrokenOffscreen()
    before = (space.shading.render_pass, space.overlay.show_overlays, len(scene.view_layers[0].aovs))
    assert session.tick(scene, now=0.0) is False
    with pytest.raises(SSRError, match="could not draw its COMBINED pass: GBuffer::acquire"):
        session.tick(scene, now=1.0)
    assert (space.shading.render_pass, space.overlay.show_overlays, len(scene.view_layers[0].aovs)) == before
    session.release()


def test_data_passes_are_drawn_at_one_sample_and_the_samples_restored(live_view, monkeypatch):
    """A draw renders all the viewport's TAA samples; the passes one sample gives alike (Normal,
    Glossy Color, the material AOVs, Position where drawn) are drawn at one, the noisy ones at the scene's.
    The scene's samples are as before after a capture, and after one whose draw fails halfway."""
    from ssr_addon.blender.viewport_capture import ViewportCapture
    scene, space, region = live_view
    scene.eevee.taa_samples = 6
    drawn, fail_at = [], []
    real_draw = ViewportCapture._draw

    def counting_draw(self, scene, view_layer, view, projection, render_pass, channels):
        drawn.append((render_pass, scene.eevee.taa_samples))
        if render_pass in fail_at:
            raise SSRError(f"the viewport could not draw its {render_pass} pass")
        return real_draw(self, scene, view_layer, view, projection, render_pass, channels)
    monkeypatch.setattr(ViewportCapture, "_draw", counting_draw)
    session = LiveSession(space, region, space.region_3d)
    clock = [0.0]
    aovs, nodes = len(scene.view_layers[0].aovs), _material_nodes()
    try:
        _tick_until(session, scene, clock, lambda: drawn)
        samples = dict(drawn)
        assert {samples[name] for name in ("NORMAL", "SPECULAR_COLOR", "ssr_roughness")} == {1}, drawn
        assert samples["COMBINED"] == samples["SPECULAR_LIGHT"] == 6, drawn
        assert scene.eevee.taa_samples == 6
        drawn.clear()
        space.region_3d.view_location += mathutils.Vector((0.02, 0.0, 0.0))  # moving: every pass at one sample
        _tick_until(session, scene, clock, lambda: drawn)
        assert {samples for _, samples in drawn} == {1} and scene.eevee.taa_samples == 6, drawn
        fail_at.append("SPECULAR_LIGHT")  # after the one-sample Normal and Glossy Color
        space.region_3d.view_location += mathutils.Vector((0.02, 0.0, 0.0))
        with pytest.raises(SSRError, match="SPECULAR_LIGHT"):  # a moving view's capture fails halfway
            session.tick(scene, now=clock[0] + 1.0)
        session.release()  # as the operator stops it
        assert (len(scene.view_layers[0].aovs), _material_nodes(), scene.eevee.taa_samples) == (aovs, nodes, 6)
        session = LiveSession(space, region, space.region_3d)
        with pytest.raises(SSRError, match="SPECULAR_LIGHT"):
            _tick_until(session, scene, clock, lambda: False)
        assert scene.eevee.taa_samples == 6
    finally:
        session.release()


def _ray_cast_depth(scene, view_layer, view, projection, size, name):
    """View-axis distance of the first surface along each pixel centre's ray (BVH ray casts, not
    the rasteriser), NaN where the ray meets nothing; and where the surface is object NAME's."""
    width, height = size
    camera_to_world = np.linalg.inv(view)
    origin = mathutils.Vector(camera_to_world[:3, 3])
    depsgraph = view_layer.depsgraph
    depth, on_object = np.full((height, width), np.nan), np.zeros((height, width), bool)
    for row in range(height):
        for column in range(width):
            ndc = np.array([(column + 0.5) / width * 2 - 1, 1 - (row + 0.5) / height * 2, -1.0, 1.0])
            point = np.linalg.inv(projection) @ ndc
            direction = mathutils.Vector(camera_to_world[:3, :3] @ (point[:3] / point[3])).normalized()
            hit, location, _, _, hit_object, _ = scene.ray_cast(depsgraph, origin, direction)
            if hit:
                depth[row, column] = -(view[2, :3] @ np.array(location) + view[2, 3])
                on_object[row, column] = hit_object.name == name
    return depth, on_object


def test_a_capture_finds_depth_in_the_materials_and_draws_position_only_for_surfaces_without_one(live_view):
    """Depth comes with the roughness AOV (one draw less a capture); where a surface on screen
    has no node material to write it, the capture draws the Position pass as well. Either way it
    is the distance a ray cast finds, to half precision."""
    from ssr_addon.blender.render_setup import rendered_view_layer
    from ssr_addon.blender.scene_io import camera_matrices
    from ssr_addon.blender.viewport_capture import ViewportCapture
    scene, space, region = live_view
    size = (64, 36)
    view_layer = rendered_view_layer(scene)
    view, projection = (np.asarray(matrix) for matrix in camera_matrices(scene, *size))
    clip = scene.camera.data.clip_start, scene.camera.data.clip_end
    capture = ViewportCapture(space, region)
    cube = scene.objects["CubeGreen"]

    def captured_depth():
        draws = capture.draws
        passes = capture.capture(scene, view_layer, view, projection, size, clip, "analytic", samples=1)
        return passes.depth, capture.draws - draws

    try:
        with TemporaryChanges() as changes:
            changes.set(space.shading, "type", "RENDERED")
            with_materials, draws = captured_depth()
            cube_material = cube.material_slots[0].material
            cube.material_slots[0].material = None
            try:
                without_one, draws_without = captured_depth()
            finally:
                cube.material_slots[0].material = cube_material
    finally:
        capture.release()
    expected, on_cube = _ray_cast_depth(scene, view_layer, view, projection, size, cube.name)
    # Inside surfaces (not their antialiased edges): depth is not blended there.
    inside = np.isfinite(expected)
    for axis in (0, 1):
        for shift in (-1, 1):
            neighbour = np.roll(expected, shift, axis=axis)
            inside &= np.isfinite(neighbour) & (np.abs(neighbour - expected) <= 0.05 * expected)
    assert inside.sum() > 500 and (inside & on_cube).sum() >= 4, (inside.sum(), (inside & on_cube).sum())
    assert draws_without == draws + 1  # the Position pass, drawn only for the bare cube
    for depth in (with_materials, without_one):
        assert np.abs(depth - expected)[inside].max() <= 2e-3 * expected[inside].max(), \
            np.abs(depth - expected)[inside].max()


def test_unregistering_stops_the_session_and_leaves_no_timer(live_view):
    scene, space, region = live_view
    window_manager = bpy.context.window_manager
    live.start(LiveSession(space, region, space.region_3d), window_manager, window_manager.windows[0])
    assert live.running_session() is not None and live._timer is not None
    ssr_addon.unregister()
    try:
        assert live.running_session() is None and live._timer is None and live._draw_handle is None
    finally:
        ssr_addon.register()  # for the fixture's teardown
