"""What a user sees over the frames of an animation, rendered through the CLI.

- A still camera over 8 frames converges towards a long still of the same frame and
  holds steady.
- A frame of an animation with a moving object is no worse against Cycles than a
  still of that frame, and leaves no dark streaks behind the object.
"""
import numpy as np
import pytest

from conftest import rgb
from ssr_addon import bench

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
    """The wet street (roughness from a noise texture), camera still: frames 1-8 and a
    256-iteration still of frame 8."""
    animation = render_scene("wet_street", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                             "--frames", f"{FRAMES[0]}-{FRAMES[1]}")
    still = render_scene("wet_street", "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                         "--frames", str(FRAMES[1]), "--set", "accumulate_frames=256")
    passes = still.passes(FRAMES[1])
    mask = bench.reflective_mask(passes["Roughness.V"], rgb(passes, "Specular Color")) & \
        (passes["SSR Confidence.V"] > 0.05)
    assert mask.sum() > 300, "the street must show reflections"
    return animation, still, mask


def test_a_still_camera_converges_over_eight_frames(static_shot):
    """The temporal filter loses no ray: by frame 8 the error against a long still falls at least as
    fast as averaging the iterations traced so far allows, sqrt(first frame's / all of them) for
    independent noise. The first frame traces a quad cycle (4 iterations), each later one a single
    iteration, so that is sqrt(4 / 11) = 0.60, the issue's goal; 5 % above it is sampling luck,
    not a leak. The broken sequence of the last round made the error grow."""
    animation, still, mask = static_shot
    target = still.final(FRAMES[1])
    errors = [bench.relative_mae(target, animation.final(frame), mask) for frame in range(FRAMES[0], FRAMES[1] + 1)]
    iterations = np.cumsum([entry["iterations"] for entry in animation.report["frames"]])
    averaging_bound = np.sqrt(iterations[0] / iterations[-1])
    print("error against the long still, frames 1-8:", [round(e, 4) for e in errors],
          f"ratio {errors[-1] / errors[0]:.3f}, averaging alone {averaging_bound:.3f}")
    assert len(iterations) == FRAMES[1] - FRAMES[0] + 1
    assert errors[-1] <= 1.05 * averaging_bound * errors[0], errors


def frame_to_frame_changes(static_shot):
    """Mean change of what SSR shows between consecutive frames, relative to the image's level
    (the engine's part of a still shot is the same every frame)."""
    animation, _, mask = static_shot
    shown = [reflection_shown(animation, frame)[mask] for frame in range(FRAMES[0], FRAMES[1] + 1)]
    level = image_level(animation, FRAMES[1], mask)
    return [float(np.abs(b - a).mean() / level) for a, b in zip(shown, shown[1:])]


def test_a_still_camera_settles(static_shot):
    """Averaging n frames, the n-th changes the picture by about 1/n of one frame's noise: from
    frame 7 to 8 by under half as much as from 1 to 2 (about a fifth, in theory). The broken
    sequence of the last round changed it 1-2.5 % every frame, for ever."""
    changes = frame_to_frame_changes(static_shot)
    print("frame-to-frame change, frames 1-8:", [round(c, 4) for c in changes])
    assert changes[-1] <= 0.5 * changes[0], changes


@pytest.mark.xfail(strict=True, reason="goal of the 'Right before new' issue, not met yet: the wet street's "
                   "change is still above 1 % per frame at frames 4-8 (the bright windows in its rough puddles)")
def test_a_still_camera_holds_steady(static_shot):
    changes = frame_to_frame_changes(static_shot)[3:]
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
