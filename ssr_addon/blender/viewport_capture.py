"""Capture the passes SSR needs from a 3D View: EEVEE's viewport engine draws each pass
into an offscreen buffer (GPUOffScreen.draw_view3d), one draw per pass.

The live viewport mode and the `preview` command share it. Each draw renders all the
viewport's TAA samples (scene.eevee.taa_samples), so the data passes (ONE_SAMPLE_PASSES) are
drawn at one. A capture yields the same RenderPasses a render does
(render_passes.passes_from_layers), so the chain cannot tell them apart:
- Combined, Normal, Specular Light and Color, and the roughness AOV come as they are;
- F0 is not drawn: EEVEE's Specular Color is the FG the composite would make of it
  (RenderPasses.f0 None), and every draw counts in a moving view's update;
- depth is the view-axis distance the materials write into the roughness AOV
  (material_aovs); only where a surface on screen has no node material to write it
  is the Position pass drawn as well, and depth taken from it;
- lamp highlights are split off Specular Light as a render splits them
  (render_passes.eevee_lamp_light): computed in the chain (analytic), or a draw of the lamps
  alone (lamp_renders.lamps_alone), with the Shadow pass where the split is unshadowed;
- the view holds still, so motion is zero.
Overlays are off while capturing: the grid and outlines would land in the passes.
Every setting the capture changes (shading pass, overlays, the scene for the lamp draw)
is restored before it returns.
"""
import bpy
import gpu
import mathutils
import numpy as np

from ..core.errors import SSRError
from ..core.gpu_backend import download, lap
from .lamp_renders import lamps_alone
from .material_aovs import ROUGHNESS_AOV, add_material_aovs
from .overrides import TemporaryChanges
from .render_passes import eevee_lamp_light, passes_from_layers, surface_layers, undo_coverage
from .render_setup import SSR_BASE_RAYTRACING, decide_lamp_split, use_eevee_raytracing
from .scene_io import shows_a_surface, view_depth

# Shadings whose viewport draw is EEVEE's and has render passes.
CAPTURE_SHADINGS = ("MATERIAL", "RENDERED")
# Pass name as a render's EXR names it -> the viewport's render_pass for it.
VIEWPORT_PASSES = {
    "Combined": "COMBINED", "Normal": "NORMAL", "Position": "POSITION",
    "Glossy Direct": "SPECULAR_LIGHT", "Glossy Color": "SPECULAR_COLOR", ROUGHNESS_AOV: ROUGHNESS_AOV,
}

# Passes one sample draws as all the viewport's samples do, bar edge antialiasing: drawn at one
# sample, since an offscreen draw renders every sample the viewport is set to
# (Instance::draw_viewport_image_render). Combined, Specular Light and Shadow, noisy from EEVEE's
# sampling of lights, shadows and rays, are drawn at the scene's viewport samples.
ONE_SAMPLE_PASSES = ("Normal", "Position", "Glossy Color", ROUGHNESS_AOV)


def capture_problem(scene, space):
    """Why a capture of SPACE (a SpaceView3D) cannot run on SCENE, or None."""
    if scene.render.engine != "BLENDER_EEVEE":
        return "live SSR needs the EEVEE render engine"
    if space.shading.type not in CAPTURE_SHADINGS:
        return "live SSR needs Material Preview or Rendered shading"
    return None


class ViewportCapture:
    """Draws the passes of one 3D View (SPACE, its WINDOW REGION) into an offscreen buffer kept
    between captures of the same size."""

    def __init__(self, space, region):
        self.space, self.region = space, region
        self._offscreen = None
        self.draws = 0  # draws so far: what a capture costs
        self._held_warnings = None  # the material warnings of a set-up held over captures (hold_set_up)

    def capture(self, scene, view_layer, view_matrix, projection_matrix, size, clip, lamp_split="auto", timer=None,
                samples=None):
        """RenderPasses of SCENE seen through VIEW_MATRIX and PROJECTION_MATRIX (4x4 arrays) at SIZE
        (width, height); CLIP is (clip_start, clip_end). The noisy passes are drawn at SAMPLES
        (default: the scene's viewport samples), the others at one. TIMER gets "capture", and
        "lamp_split" where the lamps are drawn alone."""
        samples = samples or scene.eevee.taa_samples
        split = decide_lamp_split(scene, "eevee", lamp_split)
        view, projection = _matrix(view_matrix), _matrix(projection_matrix)
        with TemporaryChanges() as changes:
            self._prepare(scene, size, changes)
            warnings = self._held_warnings
            if warnings is None:
                warnings = self._set_up(scene, view_layer, changes)
            wanted = dict(VIEWPORT_PASSES, **({"Shadow": "SHADOW"} if split.needs_shadow_pass else {}))

            def draw(names):
                # A render's passes have three channels but Combined: so do these.
                return self.draw_passes(scene, view_layer, view_matrix, projection_matrix, size, {
                    name: (wanted[name], 4 if name == "Combined" else 3, 1 if name in ONE_SAMPLE_PASSES else samples)
                    for name in names})
            layers = draw([name for name in wanted if name != "Position"])
            depth = material_depth(layers)
            layers["Depth"] = depth if depth is not None else view_depth(draw(["Position"])["Position"], view_matrix)
            lap(timer, "capture")
            surface = surface_layers(layers)

            def rendered_lamp_specular(shadows):
                with TemporaryChanges() as lamp_only:
                    lamps_alone(scene, lamp_only, shadows)
                    lamp_only.set(scene.eevee, "taa_samples", samples)
                    view_layer.update()
                    specular = self._draw(scene, view_layer, view, projection, "SPECULAR_LIGHT", 3)
                view_layer.update()
                lap(timer, "lamp_split")
                return specular

            view_array = np.asarray(view_matrix, np.float32)
            projection_array = np.asarray(projection_matrix, np.float32)
            lamp_light, lamps = eevee_lamp_light(split, layers, rendered_lamp_specular)
        view_layer.update()
        return passes_from_layers(layers, surface, layers["Glossy Direct"], lamp_light, view_array, projection_array,
                                  clip, "eevee", samples, warnings, lamps)

    def hold_set_up(self, scene, view_layer, changes):
        """Through CHANGES, keep SCENE set up for captures (the AOVs wired into its materials,
        EEVEE's ray tracing as SSR's base) for as long as CHANGES holds: wiring and unwiring
        every material each capture makes EEVEE sync them all anew, most of a one-sample capture."""
        self._held_warnings = self._set_up(scene, view_layer, changes)
        changes.on_restore(lambda: setattr(self, "_held_warnings", None))

    @staticmethod
    def _set_up(scene, view_layer, changes):
        use_eevee_raytracing(scene, SSR_BASE_RAYTRACING, changes)
        warnings = add_material_aovs(scene, view_layer, changes)
        view_layer.update()  # the viewport engine sees the new AOVs only once evaluated
        return warnings

    def draw_passes(self, scene, view_layer, view_matrix, projection_matrix, size, passes):
        """{name: (H, W, channels)} of SCENE seen through VIEW_MATRIX and PROJECTION_MATRIX at SIZE:
        PASSES maps each name to (viewport render_pass, channels, TAA samples). The view is drawn
        as it is shaded (hold_for_captures: Rendered, the scene's world and lights)."""
        with TemporaryChanges() as changes:
            self._prepare(scene, size, changes)
            changes.set(scene.eevee, "taa_samples", scene.eevee.taa_samples)
            view_layer.update()
            view, projection = _matrix(view_matrix), _matrix(projection_matrix)
            layers = {}
            for name, (render_pass, channels, samples) in passes.items():
                if scene.eevee.taa_samples != samples:
                    scene.eevee.taa_samples = samples  # 0 would mean unlimited
                    view_layer.update()  # else every draw after it syncs the whole scene anew
                layers[name] = self._draw(scene, view_layer, view, projection, render_pass, channels)
        return layers

    def hold_for_captures(self, changes):
        """Through CHANGES, shade the view as a render is (Rendered: the scene's world and lights)
        and without overlays for as long as CHANGES holds: switching the shading each capture
        would start EEVEE's viewport engine afresh each time."""
        changes.set(self.space.shading, "type", "RENDERED")
        changes.set(self.space.overlay, "show_overlays", False)

    def combined(self, scene, view_layer, view_matrix, projection_matrix, size):
        """EEVEE's image of the view alone, (H, W, 4)."""
        with TemporaryChanges() as changes:
            self._prepare(scene, size, changes)
            view_layer.update()
            combined = self._draw(scene, view_layer, _matrix(view_matrix), _matrix(projection_matrix), "COMBINED", 4)
        view_layer.update()
        return combined

    def _prepare(self, scene, size, changes):
        """Check that the view can be captured, size the offscreen buffer, and (through CHANGES)
        turn the overlays off: the grid and outlines would land in the passes."""
        problem = capture_problem(scene, self.space)
        if problem is not None:
            raise SSRError(problem)
        self._ensure_offscreen(size)
        if self.space.overlay.show_overlays:
            changes.set(self.space.overlay, "show_overlays", False)
        changes.set(self.space.shading, "render_pass", self.space.shading.render_pass)  # _draw switches it

    def _ensure_offscreen(self, size):
        if self._offscreen is None or (self._offscreen.width, self._offscreen.height) != tuple(size):
            self.release()
            try:
                self._offscreen = gpu.types.GPUOffScreen(*size, format="RGBA32F")
            except Exception as error:  # gpu raises plain Exceptions for allocation failures
                raise SSRError(f"cannot make a {size[0]}x{size[1]} offscreen buffer: {error}") from None

    def _draw(self, scene, view_layer, view, projection, render_pass, channels):
        """One pass of the view as an (H, W, CHANNELS) array in image order."""
        if self.space.shading.render_pass != render_pass:
            self.space.shading.render_pass = render_pass
        self.draws += 1
        try:
            self._offscreen.draw_view3d(scene, view_layer, self.space, self.region, view, projection,
                                        do_color_management=False)
        except Exception as error:  # a failing draw must end the capture, not Blender
            raise SSRError(f"the viewport could not draw its {render_pass} pass: {error}") from None
        return download(self._offscreen.texture_color, channels)

    def release(self):
        if self._offscreen is not None:
            self._offscreen.free()
            self._offscreen = None


def material_depth(layers):
    """The view-axis depth the materials wrote into LAYERS' roughness AOV, (H, W, 1); None where
    a surface (a pixel with a normal) is mostly unwritten: it has no node material."""
    aov = layers[ROUGHNESS_AOV]
    coverage = aov[..., 1]
    if np.any(shows_a_surface(layers["Normal"]) & (coverage < 0.25)):
        return None
    return undo_coverage(aov[..., 2], coverage, fallback=0.0)[..., None]


def _matrix(array):
    return mathutils.Matrix(np.asarray(array, np.float64).tolist())


def find_view3d(screen):
    """(space, region) of the largest 3D View of SCREEN, or None."""
    areas = [area for area in screen.areas if area.type == "VIEW_3D"] if screen else []
    if not areas:
        return None
    area = max(areas, key=lambda area: area.width * area.height)
    region = window_region(area)
    return (area.spaces.active, region) if region is not None else None


def window_region(area):
    """The region of AREA that draws the view itself (not its header or sidebar), or None."""
    return next((region for region in area.regions if region.type == "WINDOW"), None)


def headless_view3d():
    """The (space, region) a headless capture draws through: the startup file's 3D View."""
    window = bpy.context.window or (bpy.context.window_manager.windows[0]
                                    if bpy.context.window_manager.windows else None)
    found = find_view3d(window.screen if window else None)
    if found is None:
        raise SSRError("no 3D View to capture through: the open file's screen has none")
    return found


def headless_viewport():
    """A ViewportCapture through the open file's 3D View (headless_view3d), or None where it
    has none."""
    try:
        return ViewportCapture(*headless_view3d())
    except SSRError:
        return None
