"""The deck's closing slides: performance at 1600x900 beside Frostbite's numbers, and the limits
of screen space (hidden geometry, edge cutoff, edge fading)."""
import os
from dataclasses import replace

from ..bench.charts import chart_stage_costs
from ..bench.stability import seam_strength
from ..bench.speed import COPY_PASS_LARGE, chain_stage_ms, copy_pass_ms, queued_copy_pass_ms, queued_frame_ms, \
    upscaled_passes
from ssr_addon.core.gpu_backend import describe_gpu
from ssr_addon.core.layers import exr_channels
from ssr_addon.core.settings import ChainSettings
from .intro import MIRROR
from .section import section

# "Performance" slide: PS4, 1600x900, half-resolution rays, 4 resolve samples, < 20 % HQ rays.
DECK_TOTAL_MS, DECK_RESOLVE_MS = 2.19, 0.8
PS4_COPY_PASS_MS = 0.13  # a 1600x900 RGBA copy on the PS4's 176 GB/s: the deck's numbers in copy passes
OCCLUDED = "stability_occluded"  # a board near the camera hides what the floor should reflect
EDGE = "stability_edge_cutoff"   # pillars that run out of the top of the frame


def performance(context):
    frames = 2 if context.quick else 8
    passes = upscaled_passes(context.scene(MIRROR), COPY_PASS_LARGE)
    # One iteration a frame, as the deck's benchmark traces once per frame (and without a
    # still's first-frame accumulation, minutes at this size on a software renderer).
    settings = replace(ChainSettings(), accumulate_iterations=1, noise_threshold=0.0)
    stages, inputs, state = chain_stage_ms(passes, settings, frames)
    copy_ms = copy_pass_ms(COPY_PASS_LARGE)
    queued_ms = queued_frame_ms(inputs, settings, state, frames)
    copies = {stage: ms / copy_ms for stage, ms in stages.items() if ms > 0.0}
    numbers = {"copy_ms": round(copy_ms, 2), "total_ms": round(sum(stages.values()), 1),
               "total_copies": round(sum(copies.values()), 1),
               "resolve_copies": round(copies.get("resolve", 0.0), 1),
               "queued_copies": round(queued_ms / queued_copy_pass_ms(COPY_PASS_LARGE), 1),
               "deck_copies": round(DECK_TOTAL_MS / PS4_COPY_PASS_MS, 1),
               "deck_resolve_copies": round(DECK_RESOLVE_MS / PS4_COPY_PASS_MS, 1)}
    renderer = describe_gpu()["renderer"]
    chart_stage_costs(copies, {"Frostbite total": numbers["deck_copies"],
                               "Frostbite resolve": numbers["deck_resolve_copies"]},
                      os.path.join(context.out_dir, "performance.png"),
                      f"Balanced chain per stage at 1600x900 on {renderer}, in full-screen copy passes")
    return section("Performance", [("Cost per stage in copy passes", "performance.png", "chart")],
                   numbers,
                   "The balanced preset at 1600x900 (half-resolution rays, 4 resolve samples, one iteration "
                   "a frame), each stage "
                   "timed as a multiple of a full-screen copy pass measured in the same run "
                   f"({{copy_ms}} ms on {renderer}), so the numbers carry across machines. Ours: "
                   "{total_copies} copy passes a frame ({total_ms} ms), {queued_copies} with one GPU wait "
                   "a frame instead of one per stage; the resolve {resolve_copies}. Frostbite's 2.19 ms and "
                   "0.8 ms resolve on a PS4, where a copy takes about 0.13 ms, are {deck_copies} and "
                   "{deck_resolve_copies} copy passes.")


def limits(context):
    ssr = context.render(OCCLUDED, fallback="off")
    cutoff, = context.chain(EDGE, border_fade=0.0, fallback="off")
    fading = context.render(EDGE, fallback="off")
    edge = context.reference(EDGE)
    numbers = {"hidden_flip": context.error(OCCLUDED, ssr)["flip"],
               "hidden_fallback_flip": context.error(OCCLUDED, context.render(OCCLUDED, "NONE"))["flip"],
               "border_fade": ChainSettings().border_fade,
               **{f"{name}_seam": round(seam_strength(render.final, exr_channels(render.images.layers), edge.image,
                                                      edge.mask), 2)
                  for name, render in (("cutoff", cutoff), ("fading", fading))}}
    return section("However, screen space reflection is not perfect", [
        ("Hidden geometry: SSR", context.save("limits_hidden_ssr.png", ssr.final)),
        ("Hidden geometry: Cycles", context.save("limits_hidden_cycles.png", context.reference(OCCLUDED).image)),
        ("Edge cutoff (no fading)", context.save("limits_edge_cutoff.png", cutoff.final)),
        ("Edge fading", context.save("limits_edge_fading.png", fading.final)),
        ("Edge: Cycles", context.save("limits_edge_cycles.png", context.reference(EDGE).image))], numbers,
        "The depth buffer holds only what the camera sees. The board hides the middle of the glowing "
        "panel, so the floor in front of it cannot reflect that part: SSR leaves it to the world "
        "reflection (FLIP against Cycles {hidden_flip}, {hidden_fallback_flip} with no SSR at all). "
        "Pillars leave the top of the frame, and so do the rays of the floor pixels that reflect their "
        "tops: cut off, the reflection ends in a hard line where they leave it; faded out over the last "
        "{border_fade} of the screen before the rays leave it, it hands over gradually to the world "
        "reflection. Here the floor's last rows reflect the pillars just below the frame's top, so the "
        "cut falls about on the frame's bottom edge, and the fade costs the reflection its last rows: the "
        "seam's strength (the bench's stability measure: 0 a smooth fade, 1 a one-pixel cut) is "
        "{cutoff_seam} cut off and {fading_seam} faded.")


# Each failure of screen space beside the level of the fallback hierarchy that fixes it:
# (label, scene, the level).
BEYOND_THE_SCREEN = (("Edge cutoff", EDGE, "guard_band"), ("Hidden geometry", OCCLUDED, "cube"),
                     ("Off-screen content", "steel_room", "planar"))


def beyond_the_screen(context):
    images, numbers = [], {}
    for label, name, level in BEYOND_THE_SCREEN:
        reference = context.reference(name)
        for key, render in (("screen", context.render(name, fallback="off")),
                            (level, context.render(name, fallback=level))):
            numbers[f"{name}_{key}_flip"] = context.error(name, render)["flip"]
            numbers[f"{name}_{key}_s"] = round(render.wall_ms / 1000.0, 1)
            images.append((f"{label}: {'screen alone' if key == 'screen' else level.replace('_', ' ')}",
                           context.save(f"beyond_{name}_{key}.png", render.final)))
        images.append((f"{label}: Cycles", context.save(f"beyond_{name}_cycles.png", reference.image)))
    edge, hidden, room = (name for _, name, _ in BEYOND_THE_SCREEN)
    return section("Beyond the screen", images, numbers,
                   "Each level of the fallback hierarchy after the screen trace, on the failure it fixes, with "
                   "FLIP against Cycles on the reflective pixels and the frame's seconds. Edge cutoff: the frame "
                   "rendered with a guard band, so the pillars' tops just above it are traced "
                   f"(FLIP {{{edge}_screen_flip}} screen alone, {{{edge}_guard_band_flip}} with the band; "
                   f"{{{edge}_screen_s}} s, {{{edge}_guard_band_s}} s). Hidden geometry: a depth cube map "
                   "from a point in free space sees the panel behind the board "
                   f"({{{hidden}_screen_flip}}, {{{hidden}_cube_flip}}; {{{hidden}_screen_s}} s, "
                   f"{{{hidden}_cube_s}} s). Off-screen content: the closed room's ceiling lies above the frame, "
                   "and a planar capture of the floor (the scene seen from the camera mirrored in it) shows "
                   f"it ({{{room}_screen_flip}}, {{{room}_planar_flip}}; {{{room}_screen_s}} s, "
                   f"{{{room}_planar_s}} s).")
