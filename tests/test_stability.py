"""Stability where screen-space reflections fail: the minimal scenes test_scenes/stability_*.py.

Each case renders a short animation through the CLI (frames in order, so the
temporal history builds up) at a small resolution, and is measured with the
bench's functions (lab.bench), which chart the same numbers; the limits
asserted here are the bench's constants. The probe/world fallback is the
Combined layer of the same render (EEVEE without SSR), the reference a Cycles
render per frame where something moves, of the first frame otherwise.
"""
import numpy as np
import pytest

from conftest import rgb
from lab import bench
from ssr_addon.core.settings import ChainSettings

pytestmark = [pytest.mark.blender, pytest.mark.slow]

RESOLUTION = "160x90"
FRAMES = list(range(bench.STABILITY_FRAMES[0], bench.STABILITY_FRAMES[1] + 1))
# EEVEE's per-sample cost dominates on a software GPU; what is tested here is the chain, not antialiasing.
EEVEE_SAMPLES = "4"
REFERENCE_SAMPLES = "64"
CASES = bench.stability_cases()
STATIC_CASES = [case for case, motion in CASES.items() if motion is None]
# Built around a fade (screen border, rays towards the camera): every frame has one to measure.
FADING_CASES = ("stability_edge_cutoff", "stability_toward_camera")


def frame_range(frames):
    return f"{frames[0]}-{frames[-1]}"


def reference_frames(render_scene, case):
    """frame -> (Cycles image, reflective mask); static cases use their first frame throughout."""
    moving = CASES[case] is not None
    reference = render_scene(case, "cycles", "--resolution", RESOLUTION, "--samples", REFERENCE_SAMPLES,
                             "--frames", frame_range(FRAMES if moving else FRAMES[:1]))

    def reference_frame(frame):
        frame = frame if moving else FRAMES[0]
        passes = reference.passes(frame)
        return reference.final(frame), bench.reflective_mask(passes["Roughness.V"], rgb(passes, "Specular Color"))
    return reference_frame


def ssr_run(render_scene, case, *extra):
    return render_scene(case, "ssr", "--resolution", RESOLUTION, "--samples", EEVEE_SAMPLES,
                        "--frames", frame_range(FRAMES), *extra)


@pytest.fixture(scope="module")
def evaluated(render_scene):
    """evaluated(case, *cli_args) -> bench.evaluate_case over FRAMES, cached per argument set."""
    cache = {}

    def evaluate(case, *extra):
        if (case, extra) not in cache:
            ours = ssr_run(render_scene, case, *extra)
            seen = {entry["frame"]: np.array(entry["brightest_seen"]) for entry in ours.report["frames"]}
            cache[case, extra] = bench.evaluate_case(
                FRAMES, lambda frame: (ours.final(frame), ours.passes(frame)),
                reference_frames(render_scene, case), seen.get)
        return cache[case, extra]
    return evaluate


def test_every_case_models_its_motion():
    assert len(CASES) == 7
    assert sorted(motion for motion in CASES.values() if motion) == ["camera", "object"]


@pytest.mark.parametrize("case", CASES)
def test_frames_are_finite_and_within_the_energy_bound(evaluated, case):
    result = evaluated(case)
    assert result["finite"], f"{case}: NaN or Inf in the final image or the passes"
    worst = max(result["energy_excess"])
    assert worst <= bench.ENERGY_TOLERANCE, \
        f"{case}: a pixel exceeds the energy bound by {worst:.3%} (per frame: {result['energy_excess']})"


def test_energy_measure_flags_light_from_nowhere(render_scene):
    """Adding a second full-strength reflection of the brightest radiance breaks the bound it checks."""
    case, frame = "stability_occluded", FRAMES[0]  # a mirror floor reflecting a bright panel
    ours = ssr_run(render_scene, case)
    final, passes = ours.final(frame), ours.passes(frame)
    brightest = rgb(passes, "Combined").reshape(-1, 3).max(axis=0)
    assert bench.energy_excess(final, passes, brightest) <= bench.ENERGY_TOLERANCE
    brighter = final + rgb(passes, "Specular Color") * brightest
    assert bench.energy_excess(brighter, passes, brightest) > bench.ENERGY_TOLERANCE


@pytest.mark.parametrize("case", CASES)
def test_no_hard_seam_where_ssr_fades_into_the_fallback(evaluated, case):
    seams = evaluated(case)["seam"]
    if case in FADING_CASES:
        assert None not in seams, f"{case} is built around a fade, yet some frames have none: {seams}"
    measured = [seam for seam in seams if seam is not None]
    assert all(seam < bench.SEAM_LIMIT for seam in measured), f"{case}: seam strength per frame {seams}"


def test_seam_measure_sees_a_one_pixel_cut(render_scene):
    """The edge-cutoff frame with its border fade replaced by a one-pixel cut must read as a seam.
    Screen space alone: a guard band moves the fade out of the frame."""
    case, frame = "stability_edge_cutoff", FRAMES[0]
    ours = ssr_run(render_scene, case, "--set", "fallback=off")
    final, passes = ours.final(frame), ours.passes(frame)
    reference, mask = reference_frames(render_scene, case)(frame)
    confidence = passes["SSR Confidence.V"]
    fading = mask & (confidence > 0.02) & (confidence < 0.98)
    assert fading.sum() > 20, "the border fade is where the cut goes"
    cut = np.where(confidence > 0.5, 1.0, 0.0).astype(np.float32)
    # The composite blends final = combined + c D: the same difference D, in full or not at all.
    difference = (final - rgb(passes, "Combined")) / np.maximum(confidence, 1e-3)[..., None]
    cut_final = final + (cut - confidence)[..., None] * difference
    cut_passes = dict(passes, **{"SSR Confidence.V": cut})
    faded = bench.seam_strength(final, passes, reference, mask)
    cut_off = bench.seam_strength(cut_final, cut_passes, reference, mask)
    assert faded < bench.SEAM_LIMIT < cut_off, (faded, cut_off)


@pytest.mark.parametrize("case", CASES)
def test_never_much_worse_than_the_probe_fallback(evaluated, case):
    result = evaluated(case)
    assert None not in result["flip_ssr"], f"{case}: no reflective pixels to compare"
    for frame, ours, fallback in zip(FRAMES, result["flip_ssr"], result["flip_fallback"]):
        assert ours <= fallback + bench.FALLBACK_MARGIN, \
            f"{case} frame {frame}: FLIP {ours:.4f} against the fallback's {fallback:.4f}"


@pytest.mark.parametrize("case", STATIC_CASES)
def test_reflections_hold_still_under_a_static_camera(evaluated, case):
    change = bench.flicker(evaluated(case))
    assert change is not None, f"{case}: the reflective pixels are black"
    assert change < bench.FLICKER_LIMIT, f"{case}: reflection layer changes {change:.2%} per frame"


def test_temporal_filter_reduces_flicker(evaluated):
    case = "stability_thin"  # thin geometry: the stochastic march hits it in some frames only
    on = evaluated(case, *(() if ChainSettings().use_temporal else ("--set", "use_temporal=true")))
    off = evaluated(case, "--set", "use_temporal=false")
    flicker_on, flicker_off = bench.flicker(on), bench.flicker(off)
    assert flicker_on < flicker_off, (flicker_on, flicker_off)


def test_hit_point_reprojection_ghosts_less_than_surface_reprojection(evaluated):
    """Where the history does the work: one iteration a frame (noise_threshold off; by default a
    frame converges on its own, and what it reprojects weighs little)."""
    case = "stability_moving_camera"
    one_iteration = ("--set", "noise_threshold=0")
    hit = evaluated(case, *one_iteration, "--set", "temporal_reprojection=hit")
    surface = evaluated(case, *one_iteration, "--set", "temporal_reprojection=surface")
    # the first frame has no history, so it cannot ghost
    hit_error, surface_error = (np.mean(run["flip_ssr"][1:]) for run in (hit, surface))
    assert hit_error < surface_error, (hit_error, surface_error)
