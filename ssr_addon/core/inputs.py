"""What the chain starts from: the engine's passes of one frame (RenderPasses, numpy, from a
render or a viewport capture) and the same uploaded as textures (ChainInputs)."""
from dataclasses import dataclass, fields, replace

import numpy as np

from .gpu_backend import lap, upload
from .ray_budget import ray_budget

BACKGROUND_DEPTH = 1e10  # depth of pixels that show the world (past any clip_end)


@dataclass
class RenderPasses:
    """One frame's passes as the engine rendered them, float32 in image order (row 0 at the top)."""
    combined: np.ndarray         # (H, W, 4) the engine's final image, scene linear
    depth: np.ndarray            # (H, W) distance along the view axis; BACKGROUND_DEPTH for the world
    normal: np.ndarray           # (H, W, 3) world-space shading normal
    roughness: np.ndarray        # (H, W) 1 where no specular BSDF was rendered
    specular_color: np.ndarray   # (H, W, 3) the engine's pre-integrated specular reflectance (its FG)
    f0: np.ndarray               # (H, W, 3) specular reflectance at normal incidence (shader AOV); None
                                 # where not captured (the viewport's): FG is then the engine's specular_color
    motion: np.ndarray           # (H, W, 2) screen offset to the previous frame, pixels, y up (Vector pass)
    specular_light: np.ndarray   # (H, W, 3) all reflected light, before FG: EEVEE's Specular Light,
                                 # Cycles' Glossy Direct + Indirect
    lamp_light: np.ndarray       # (H, W, 3) the part of it that stays, highlights of lamps the camera cannot
                                 # see; None where the chain splits them off itself (lamps)
    view_matrix: np.ndarray      # (4, 4) world to view
    projection_matrix: np.ndarray  # (4, 4) view to clip
    clip_start: float
    clip_end: float
    engine: str
    samples: int                 # samples per pixel the engine rendered with
    material_warnings: tuple = ()  # materials whose roughness/F0 the AOVs could not read, and what was assumed
    lamps: object = None         # lamp_split.LampLights the chain splits off the specular light (analytic)
    capture: object = None       # captures.PlanarCapture rays off the main reflector are traced in
    cube: object = None          # captures.CubeCapture what nothing else resolves is traced in
    crop: tuple = None           # (x, y, width, height) of the requested frame, image order, where the
                                 # passes hold a guard band around it; None: all of them

    @property
    def size(self):
        return self.depth.shape[1], self.depth.shape[0]

    @property
    def frame_rect(self):
        """The requested frame in pixels of the passes, bottom-up as the GPU counts them:
        (x0, y0, x1, y1)."""
        width, height = self.size
        x, y, crop_width, crop_height = self.crop or (0, 0, width, height)
        return (x, height - y - crop_height, x + crop_width, height - y)

    def cropped(self):
        """These passes as the requested frame: the guard band (crop) cut off, the projection
        the frame's own camera's; the passes themselves without a band."""
        if self.crop is None:
            return self
        x, y, width, height = self.crop
        rendered_height, rendered_width = self.depth.shape
        images = {spec.name: crop_image(getattr(self, spec.name), self.crop) for spec in fields(self)
                  if isinstance(getattr(self, spec.name), np.ndarray) and getattr(self, spec.name).ndim >= 2
                  and getattr(self, spec.name).shape[:2] == self.depth.shape}
        lamps = self.lamps if self.lamps is None else replace(self.lamps, shadow=crop_image(self.lamps.shadow,
                                                                                              self.crop))
        projection = np.diag((rendered_width / width, rendered_height / height, 1.0, 1.0)) @ self.projection_matrix
        return replace(self, **images, lamps=lamps, projection_matrix=projection.astype(np.float32), crop=None)

    @property
    def specular_direct(self):
        """(H, W, 3) lamp highlights, kept as they are; where the chain splits them off
        (lamps), its "Specular Direct" layer holds them."""
        if self.lamp_light is None:
            raise ValueError("the chain splits these lamps off on the GPU: read its Specular Direct layer")
        return self.lamp_light

    @property
    def specular_indirect(self):
        """(H, W, 3) reflected light SSR replaces, before FG: probes/world and, with the scene's
        ray tracing on, EEVEE's own traced reflections (EEVEE); world, emissive and other
        surfaces (Cycles). As lamp_split.glsl splits it on the GPU."""
        return np.maximum(self.specular_light - self.specular_direct, 0.0)


def crop_image(image, crop):
    """The (x, y, width, height) CROP of IMAGE (image order), or IMAGE where CROP is None."""
    if crop is None:
        return image
    x, y, width, height = crop
    return np.ascontiguousarray(image[y:y + height, x:x + width])


@dataclass
class ChainInputs:
    """One frame's inputs as textures at full resolution, by the resource names the passes read
    (gpu_passes): radiance (the lit scene reflections are fetched from), depth, normal,
    roughness, combined, specular_color, f0 (specular reflectance at normal incidence, for FG),
    motion (screen offset to the previous frame in pixels, the Vector pass) and either
    specular_indirect or, where LAMPS are given, specular_light and shadow, which the chain's
    first pass splits; with a CAPTURE, its capture_radiance, capture_depth and capture_normal;
    with a CUBE, cube_radiance and cube_depth."""
    textures: dict
    view_matrix: np.ndarray
    projection_matrix: np.ndarray
    clip_start: float
    clip_end: float
    # Pixels rougher than this get cheap rays; ties at it are expensive with this probability.
    ray_budget: tuple = (1.0, 1.0)
    lamps: tuple = None          # lamp_split.Lamp records the chain splits off the specular light
    capture: object = None       # captures.PlanarCapture (its textures are capture_* resources)
    cube: object = None          # captures.CubeCapture (cube_* resources)
    frame_rect: tuple = None     # RenderPasses.frame_rect; None: the whole frame
    # The frame's own reflection, which stands wherever SSR resolves nothing, is a probe's (EEVEE):
    # a capture's view of the world and of what the screen's fades leave betters it. A path
    # tracer's (Cycles) is exact, to the pixel's edges.
    probe_reflection: bool = True
    # Without an F0 pass (RenderPasses.f0 None) the composite's FG is the engine's own specular
    # colour, which EEVEE pre-integrates as the add-on's DFG table does (to 0.2 % median).
    fg_from_specular_color: bool = False

    @property
    def size(self):
        depth_tx = self.textures["depth"]
        return depth_tx.width, depth_tx.height

    @classmethod
    def from_passes(cls, passes, settings, timer=None):
        """Upload RenderPasses (TIMER: "upload"); the lit scene (Combined) is also what reflections show."""
        combined_tx, specular_color_tx = upload(passes.combined), upload(passes.specular_color)
        textures = {"radiance": combined_tx, "combined": combined_tx, "depth": upload(passes.depth),
                    "normal": upload(passes.normal), "roughness": upload(passes.roughness),
                    "specular_color": specular_color_tx,
                    "f0": specular_color_tx if passes.f0 is None else upload(passes.f0),  # unread without F0
                    "motion": upload(passes.motion)}
        for capture in (passes.capture, passes.cube):
            if capture is not None:
                textures.update(capture.textures())
        if passes.lamps is None:
            textures["specular_indirect"] = upload(passes.specular_indirect)
        else:
            textures["specular_light"] = upload(passes.specular_light)
            textures["shadow"] = upload(passes.lamps.shadow)
        inputs = cls(textures, view_matrix=passes.view_matrix, projection_matrix=passes.projection_matrix,
                     clip_start=passes.clip_start, clip_end=passes.clip_end,
                     ray_budget=ray_budget(passes.roughness, passes.depth, passes.clip_end, settings),
                     lamps=None if passes.lamps is None else passes.lamps.lamps, capture=passes.capture,
                     cube=passes.cube, frame_rect=passes.frame_rect,
                     probe_reflection=passes.engine == "eevee", fg_from_specular_color=passes.f0 is None)
        lap(timer, "upload")
        return inputs
