"""Settings of the SSR chain: one schema for the PropertyGroup, the CLI and the chain.

Pure Python (no bpy) so the chain, the CLI and the tests share it. The
PropertyGroup in `settings.py` is generated from SETTINGS_SCHEMA, so a setting
is declared exactly once.
"""
from dataclasses import dataclass, field, fields, replace

from .errors import SSRError


def _setting(default, description, minimum=None, maximum=None, items=None):
    return field(default=default, metadata={
        "description": description, "min": minimum, "max": maximum, "items": items})


@dataclass(frozen=True)
class ChainSettings:
    """Parameters of the reflection chain; names follow EEVEE's where one exists."""
    use_ssr: bool = _setting(True, "Trace screen-space reflections (off: probe/world reflections only)")
    max_roughness: float = _setting(
        0.5, "Surfaces rougher than this keep their probe/world reflection", 0.0, 1.0)
    thickness: float = _setting(
        0.2, "Assumed depth of every surface in the depth buffer, in scene units", 0.001, 100.0)
    trace_steps: int = _setting(
        96, "Linear march: most depth-buffer tests per ray", 4, 1024)
    trace_stride: float = _setting(
        1.0, "Linear march: shortest step between depth tests, in pixels", 0.5, 64.0)
    refine_steps: int = _setting(
        6, "Binary search steps that refine a hit between two march steps", 0, 16)
    max_distance: float = _setting(
        100.0, "Longest reflection ray, in scene units", 0.01, 10000.0)
    border_fade: float = _setting(
        0.08, "Fade hits within this fraction of the screen from its border", 0.0, 0.5)
    camera_facing_fade: float = _setting(
        0.5, "Fade rays that point back towards the camera (0: never fade)", 0.0, 1.0)

    def with_overrides(self, overrides):
        """Return a copy with `key=value` strings (from --set) parsed by each field's type."""
        known = {f.name: f for f in fields(self)}
        values = {}
        for text in overrides:
            key, sep, raw = text.partition("=")
            key = key.strip()
            if not sep or key not in known:
                raise SSRError(f"--set {text!r}: expected key=value with key one of {', '.join(sorted(known))}")
            values[key] = _parse_value(known[key], raw.strip())
        return replace(self, **values)


def _parse_value(spec, raw):
    kind = type(spec.default)
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
    low, high = spec.metadata["min"], spec.metadata["max"]
    if kind is not bool and ((low is not None and value < low) or (high is not None and value > high)):
        raise SSRError(f"--set {spec.name}={raw}: must lie in [{low}, {high}]")
    return value


SETTINGS_SCHEMA = fields(ChainSettings)
