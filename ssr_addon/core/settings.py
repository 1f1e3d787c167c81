"""Settings of the SSR chain: one schema for the PropertyGroup, the CLI and the chain.

Pure Python (no bpy) so the chain, the CLI and the tests share it. The
PropertyGroup in `settings.py` is generated from SETTINGS_SCHEMA, so a setting
is declared exactly once; metadata["group"] places it in a panel.
"""
import math
from dataclasses import dataclass, field, fields, replace

from .errors import SSRError


def _setting(default, description, minimum=None, maximum=None, items=None, group="tracing"):
    return field(default=default, metadata={
        "description": description, "min": minimum, "max": maximum, "items": items, "group": group})


# The levels of the fallback hierarchy after the screen trace, in the order they are tried.
FALLBACK_LEVELS = {"guard_band": "the frame rendered wider, so rays that leave it find what lies just outside",
                   "planar": "a capture of the scene mirrored in the main flat reflector",
                   "cube": "a depth cube map from a point in free space, traced with parallax and occlusion"}


def fallback_levels(fallback):
    """The levels a ChainSettings.fallback asks for: None for auto (the frame decides), a tuple
    otherwise (empty for off). A bad value raises SSRError."""
    text = fallback.strip().lower()
    if text == "auto":
        return None
    if text == "off":
        return ()
    levels = tuple(level.strip() for level in text.split(","))
    unknown = [level for level in levels if level not in FALLBACK_LEVELS]
    if unknown or not levels:
        raise SSRError(f"fallback={fallback!r}: expected auto, off or a comma-separated list of "
                       f"{', '.join(FALLBACK_LEVELS)}")
    return levels


@dataclass(frozen=True)
class ChainSettings:
    """Parameters of the reflection chain; names follow EEVEE's where one exists.

    Each `use_*` switch turns one stage of the slides off, so its effect can be
    seen and measured (STAGE_TOGGLES).
    """
    use_ssr: bool = _setting(True, "Trace screen-space reflections (off: probe/world reflections only)")
    # Tracing
    use_hiz: bool = _setting(True, "Trace smooth surfaces hierarchically through a min-depth pyramid (expensive rays)")
    expensive_ray_budget: float = _setting(
        0.3, "Fraction of traced rays that get expensive Hi-Z rays, smoothest pixels first "
             "(more where sharp_roughness asks)",
        0.0, 1.0)
    sharp_roughness: float = _setting(
        0.2, "Surfaces at most this rough always get expensive Hi-Z rays, whatever the budget: a cheap ray's "
             "coarse steps show as stair-steps in a sharp reflection", 0.0, 1.0)
    use_sharp_rays: bool = _setting(
        True, "With half-resolution tracing, surfaces at most sharp_roughness rough also trace a full-resolution "
              "ray of their own every iteration: a curved mirror shows its own reflection, not its neighbours', "
              "and a nearly smooth floor its sharp one. A view on the move in the viewport leaves them out: "
              "there the reprojected history carries a mirror's image, and each update costs less")
    hiz_max_iterations: int = _setting(96, "Hi-Z tracing: most cell visits per ray", 8, 1024)
    use_importance_sampling: bool = _setting(
        True, "Sample ray directions from the GGX lobe (Halton sequence); off: mirror directions only")
    ray_sampling: str = _setting(
        "halton", "How importance-sampled ray directions are drawn (the deck's choice is Halton points of "
                  "the GGX lobe; the others are there to compare it with)",
        items=(("halton", "GGX + Halton", "Visible GGX normals at the points of a Halton (2, 3) sequence"),
               ("random", "GGX + Random", "Visible GGX normals at independent random points"),
               ("uniform", "Uniform", "Directions spread evenly over the hemisphere, whatever the surface")))
    half_resolution: bool = _setting(True, "Trace one ray per 2x2 pixels and resolve at full resolution")
    thickness: float = _setting(
        0.2, "Assumed depth of every surface in the depth buffer, in scene units", 0.001, 100.0)
    trace_steps: int = _setting(64, "Cheap rays (linear march): most depth-buffer tests per ray", 4, 1024)
    trace_stride: float = _setting(
        2.0, "Cheap rays (linear march): shortest step between depth tests, in pixels", 0.5, 64.0)
    refine_steps: int = _setting(6, "Binary search steps that refine a linear-march hit", 0, 16)
    max_distance: float = _setting(100.0, "Longest reflection ray, in scene units", 0.01, 10000.0)
    # Resolve
    resolve_samples: int = _setting(
        4, "Rays each pixel reuses from its neighbourhood (ratio estimator); 1: its own ray only", 1, 9,
        group="resolve")
    resolve_resolution: str = _setting(
        "full", "Where the colour is resolved when rays are traced at half resolution (the deck's "
                "\"Sparse Ray Tracing\": full is its choice, half is there to compare it with)",
        items=(("full", "Full", "Every pixel resolves its own colour from the four nearest rays"),
               ("half", "Half", "Each traced ray's pixel resolves, and the result is scaled up: cheaper, "
                                "blurred across edges")),
        group="resolve")
    use_cone_filter: bool = _setting(
        True, "Read each reused ray as a cone from a colour pyramid, wider with roughness and distance, "
        "narrower as iterations accumulate",
        group="resolve")
    use_firefly_guard: bool = _setting(
        True, "Average the reused rays' colours tone-mapped, so one bright ray cannot dominate a pixel; "
        "less so as iterations accumulate, so a settled still keeps its bright reflections",
        group="resolve")
    use_spatial_filter: bool = _setting(
        True, "Smooth the resolved reflection over each pixel's lobe footprint, stopping at depth, "
        "normal and roughness edges, narrower as iterations accumulate", group="resolve")
    denoise_radius: float = _setting(
        8.0, "Spatial filter: widest radius in pixels (a pixel's lobe footprint sets its own)", 1.0, 32.0,
        group="resolve")
    # Temporal
    use_temporal: bool = _setting(
        True, "Blend with the previous frames' reflections, reprojected through both frames' cameras",
        group="temporal")
    temporal_reprojection: str = _setting(
        "hit", "Which point is reprojected into the previous frame: the ray hit (virtual image) or the surface",
        items=(("hit", "Hit Point", "Reproject the reflected hit point: reflections stay put under camera motion"),
               ("surface", "Surface", "Reproject the reflecting surface: reflections smear under camera motion")),
        group="temporal")
    temporal_weight: float = _setting(
        0.9, "Largest share of the history in a temporally filtered pixel", 0.0, 0.99, group="temporal")
    accumulate_iterations: int = _setting(
        16, "Jittered iterations a frame accumulates when it has no history (a still, an animation's first "
            "frame); a frame with history traces one", 1, 256, group="temporal")
    noise_threshold: float = _setting(
        0.02, "Then keep doubling a frame's iterations (up to 256) until its reflection changes by less than "
              "this share of its level from one doubling to the next (0: never)",
        0.0, 1.0, group="temporal")
    # Fading
    max_roughness: float = _setting(
        0.5, "Surfaces rougher than this keep their probe/world reflection", 0.0, 1.0, group="fading")
    border_fade: float = _setting(
        0.04, "Fade hits within this fraction of the screen from where their ray leaves it", 0.0, 0.5,
        group="fading")
    camera_facing_fade: float = _setting(
        0.5, "Fade rays that point back towards the camera (0: never fade)", 0.0, 1.0, group="fading")
    # Beyond the screen: what resolves the rays the screen cannot.
    fallback: str = _setting(
        "auto", "Where the rays the screen cannot resolve are traced next: auto (the levels a frame needs), "
                "off (probes and world only) or a comma-separated list of levels: "
                + ", ".join(f"{level} ({description})" for level, description in FALLBACK_LEVELS.items()),
        group="fallback")
    guard_band_size: float = _setting(
        0.06, "Guard band: share of the frame's width and height rendered beyond each of its sides "
              "(4-8 % gives most of the benefit for 17-35 % more pixels)", 0.01, 0.25, group="fallback")
    capture_engine: str = _setting(
        "eevee", "What renders the fallback levels' captures",
        items=(("eevee", "EEVEE", "EEVEE, drawn through the 3D View where there is one: fast; what they show is lit "
                                  "without indirect light, as EEVEE lights the frame"),
               ("cycles", "Cycles", "Cycles at a few samples, denoised: what they show is lit as a path tracer "
                                    "lights it, and a floor's reflection takes that light even where the frame "
                                    "shows the same surface; at the cost of a Cycles render per capture")),
        group="fallback")
    cube_size: int = _setting(128, "Depth cube map: pixels along each face's side", 16, 2048, group="fallback")
    cube_steps: int = _setting(64, "Depth cube map: march steps per ray before the secant search", 8, 512,
                               group="fallback")
    # Lamps: SSR replaces reflected light, never a highlight of a lamp it cannot see on screen,
    # so the engine's specular light is split into the two.
    lamp_split: str = _setting(
        "auto", "How lamp highlights are told apart from reflected light, which SSR replaces",
        items=(("auto", "Auto", "Analytic with EEVEE (Unshadowed where a light is not modelled), Render with Cycles"),
               ("analytic", "Analytic",
                "EEVEE only: lamp highlights computed from the scene's lights (point, spot, sun, area), "
                "shadowed by the Shadow pass: no second render, but EEVEE's fitted lobe differs from "
                "GGX's by about 10 % of a highlight"),
               ("render", "Render",
                "A second render with lamps only: exact, at the cost of a full render"),
               ("unshadowed", "Unshadowed",
                "EEVEE only: a lamps-only render without shadows, shadowed by the Shadow pass: "
                "a fraction of a render's cost, exact for one lamp"),
               ("off", "Off", "No split: SSR replaces lamp highlights too (scenes without lamps)")),
        group="lamps")

    def __post_init__(self):
        fallback_levels(self.fallback)

    def with_overrides(self, overrides):
        """Return a copy with `key=value` strings (from --set) parsed by each field's type.

        `preset=NAME` applies a named preset first; later keys override it.
        """
        known = {f.name: f for f in fields(self)}
        settings, values = self, {}
        for text in overrides:
            key, sep, raw = text.partition("=")
            key, raw = key.strip(), raw.strip()
            if sep and key == "preset":
                settings, values = preset(raw), {}
                continue
            if not sep or key not in known:
                raise SSRError(f"--set {text!r}: expected key=value with key one of preset, "
                               f"{', '.join(sorted(known))}")
            values[key] = _parse_value(known[key], raw)
        return replace(settings, **values)


def _parse_value(spec, raw):
    kind = type(spec.default)
    items = spec.metadata["items"]
    try:
        if kind is bool:
            lowered = raw.lower()
            if lowered not in ("1", "0", "true", "false", "on", "off", "yes", "no"):
                raise ValueError(raw)
            value = lowered in ("1", "true", "on", "yes")
        else:
            value = kind(raw)
    except ValueError:
        raise SSRError(f"--set {spec.name}={raw}: not a valid {kind.__name__}") from None
    if kind is float and not math.isfinite(value):
        raise SSRError(f"--set {spec.name}={raw}: must be a finite number")
    if items and value not in [item[0] for item in items]:
        raise SSRError(f"--set {spec.name}={raw}: expected one of {', '.join(item[0] for item in items)}")
    low, high = spec.metadata["min"], spec.metadata["max"]
    if kind in (int, float) and ((low is not None and value < low) or (high is not None and value > high)):
        raise SSRError(f"--set {spec.name}={raw}: must lie in [{low}, {high}]")
    return value


SETTINGS_SCHEMA = fields(ChainSettings)

# Switches that turn one stage of the chain off (the bench switches each off in turn).
STAGE_TOGGLES = ("use_hiz", "use_importance_sampling", "half_resolution", "use_cone_filter", "use_firefly_guard",
                 "use_spatial_filter", "use_temporal")

PRESETS = {
    "draft": {"half_resolution": True, "resolve_samples": 4, "expensive_ray_budget": 0.1,
              "trace_steps": 32, "trace_stride": 4.0, "hiz_max_iterations": 48, "accumulate_iterations": 4,
              "noise_threshold": 0.0},
    "balanced": {},
    "high": {"half_resolution": False, "resolve_samples": 9, "expensive_ray_budget": 1.0,
             "trace_steps": 128, "trace_stride": 1.0, "hiz_max_iterations": 192, "accumulate_iterations": 64,
             "noise_threshold": 0.01},
}


def preset(name):
    if name not in PRESETS:
        raise SSRError(f"unknown preset {name!r}: expected one of {', '.join(PRESETS)}")
    return replace(ChainSettings(), **PRESETS[name])
