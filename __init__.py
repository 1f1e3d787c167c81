"""Extension entry point: Blender loads the repository root as the add-on package."""
from .ssr_addon import register, unregister  # noqa: F401
