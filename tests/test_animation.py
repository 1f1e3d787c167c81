"""What a user sees over the frames of an animation, rendered through the CLI.

- A still camera over 8 frames is as close to a long still of the same frame as a
  still render of it, and holds steady.
- A frame of an animation with a moving object is no worse against Cycles than a
  still of that frame, and leaves no dark streaks behind the object.
"""
import numpy as np
import pytest

from conftest import rgb
from lab import bench

pytestmark = [pytest.mark.blender, pytest.mark.slow]

RESOLUTION = "160x90"
EEVEE_SAMPLES = "4"
FRAMES = (1, 8)


def image_level(scene_output, frame, mask):
    return float(np.abs(scene_output.final(frame)[mask]).mean())


def reflection_shown(scene_output, frame):
    """What SSR adds to the image: final - combined (the engine's part of a still scene is fixed)."""
    return scene_output.final(frame) - rgb(scene_output.passes(frame), "Combined")


@pytest.fixture(scope="module")
def static_shot(render_scene):
    """The wet street (roughness from a noise texture), camera still: frames 1-8, a
    256-iteration still of frame 8, and a still at the same settings of the same picture
    with other samples: frame 7 (nothing moves; a frame's number picks its samples, and a
    still of frame 8 would share the long still's first iterations)."""
    animation = render_scene("wet_street", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                             "--frames", f"{FRAMES[0]}-{FRAMES[1]}")
    still = render_scene("wet_street", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                         "--frames", str(FRAMES[1] - 1))
    long_still = render_scene("wet_street", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                              "--frames", str(FRAMES[1]), "--set", "accumulate_iterations=256")
    passes = long_still.passes(FRAMES[1])
    mask = bench.reflective_mask(passes["Roughness.V"], rgb(passes, "Specular Color")) & \
        (passes["SSR Confidence.V"] > 0.05)
    assert mask.sum() > 300, "the street must show reflections"
    return animation, still, long_still, mask


def test_a_still_camera_converges_over_eight_frames(static_shot):
    """Every frame of a still shot is at least as close to a long still as a still render of
    it (5 % for sampling luck), and the error never grows over the frames (likewise). That
    is the issue's "frame 8 at most 0.6x frame 1's" once frame 1 renders like a still. The
    broken sequence of the last round made the error grow, 0.033 to 0.042; the one after it
    traced one ray a frame and reached 0.6x frame 1's only by frame 8, at 7x a still's error."""
    animation, still, long_still, mask = static_shot
    target = long_still.final(FRAMES[1])
    errors = [bench.relative_mae(target, animation.final(frame), mask) for frame in range(FRAMES[0], FRAMES[1] + 1)]
    still_error = bench.relative_mae(target, still.final(FRAMES[1] - 1), mask)
    print("error against the long still, frames 1-8:", [round(e, 4) for e in errors],
          f"a still: {still_error:.4f}")
    assert max(errors) <= 1.05 * still_error, errors
    assert errors[-1] <= 1.05 * errors[0], errors


def frame_to_frame_changes(static_shot):
    """Mean change of what SSR shows between consecutive frames, relative to the image's level
    (the engine's part of a still shot is the same every frame)."""
    animation, _, _, mask = static_shot
    shown = [reflection_shown(animation, frame)[mask] for frame in range(FRAMES[0], FRAMES[1] + 1)]
    level = image_level(animation, FRAMES[1], mask)
    return [float(np.abs(b - a).mean() / level) for a, b in zip(shown, shown[1:])]


def test_a_still_camera_holds_steady(static_shot):
    """The issue's goal: a still shot flickers by under 1 % from any frame to the next. The
    sequence before this changed 5.5 % from frame 1 to 2 and still 2.4-3 % at frames 4-8 (the
    bright windows in the rough puddles); the broken one 1-2.5 % every frame, for ever."""
    changes = frame_to_frame_changes(static_shot)
    print("frame-to-frame change, frames 1-8:", [round(c, 4) for c in changes])
    assert max(changes) <= 0.01, changes


@pytest.fixture(scope="module")
def rolling_ball(render_scene):
    """A ball rolling across a dark glossy floor: frames 1-6 as an animation, frame 6 as a
    still, and Cycles' frame 6."""
    frame = 6
    animation = render_scene("rolling_ball", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                             "--frames", f"1-{frame}")
    still = render_scene("rolling_ball", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                         "--frames", str(frame))
    reference = render_scene("rolling_ball", "cycles", "--resolution", RESOLUTION, "--samples", "128",
                             "--frames", str(frame))
    passes = still.passes(frame)
    mask = bench.reflective_mask(passes["Roughness.V"], rgb(passes, "Specular Color"))
    assert mask.sum() > 1000, "the floor must fill a good part of the frame"
    return frame, animation.final(frame), still.final(frame), reference.final(frame), mask


def test_an_animated_frame_is_no_worse_than_a_still_of_it(rolling_ball):
    frame, animated, still, reference, mask = rolling_ball
    animated_error = bench.relative_mae(reference, animated, mask)
    still_error = bench.relative_mae(reference, still, mask)
    animated_flip = bench.flip_error(reference, animated, mask)
    still_flip = bench.flip_error(reference, still, mask)
    print(f"frame {frame} against Cycles: animation {animated_error:.4f} (FLIP {animated_flip:.4f}), "
          f"still {still_error:.4f} (FLIP {still_flip:.4f})")
    assert animated_error <= 1.05 * still_error
    assert animated_flip <= 1.05 * still_flip


def test_a_moving_object_leaves_no_dark_streaks(rolling_ball):
    """History the ball left behind must not darken the floor: no pixel of the animated frame
    is darker than the still by more than 0.05 (the issue counted 418 at 160x90)."""
    _, animated, still, _, mask = rolling_ball
    darker = (still - animated).max(-1) > 0.05
    print("pixels darker than the still by > 0.05:", int(darker.sum()))
    assert darker.sum() <= 0.001 * darker.size
