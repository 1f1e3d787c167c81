"""End to end on the mirror-floor scene: geometry, accuracy against Cycles, finite outputs."""
import glob
import os

import numpy as np
import pytest

from conftest import SCENES, read_exr
from synthetic import mirror_image

pytestmark = [pytest.mark.blender, pytest.mark.slow]

RESOLUTION = "320x180"


@pytest.fixture(scope="module")
def mirror_geometry():
    """Camera matrices of the mirror scene and its marker, read in this process."""
    import runpy
    from ssr_addon.blender.scene_io import camera_matrices, load_scene
    path = os.path.join(SCENES, "mirror_floor.py")
    scene = load_scene(path)
    view, projection = camera_matrices(scene, 320, 180)
    marker = runpy.run_path(path)["MARKER_CENTER"]
    return view, projection, np.array(marker)


def project(point, view, projection, width=320, height=180):
    """Pixel position (x right, y down, continuous) of a world-space point."""
    clip = projection @ view @ np.append(point, 1.0)
    ndc = clip[:2] / clip[3]
    return np.array([(ndc[0] * 0.5 + 0.5) * width, (0.5 - ndc[1] * 0.5) * height])


def marker_centroid(image):
    """Centroid (x, y) of the bright orange pixels (the emissive marker or its mirror image)."""
    mask = (image[..., 0] > 1.0) & (image[..., 0] > 3 * image[..., 2])
    rows, cols = np.nonzero(mask)
    assert len(rows) > 10, "no marker pixels found"
    return np.array([cols.mean() + 0.5, rows.mean() + 0.5]), mask


def test_marker_reflection_lands_on_the_analytic_mirror_image(render_scene, mirror_geometry):
    view, projection, marker = mirror_geometry
    ssr = render_scene("mirror_floor", "ssr", "--resolution", RESOLUTION).final()
    none = render_scene("mirror_floor", "none", "--resolution", RESOLUTION).final()
    marker_px = project(marker, view, projection)
    mirrored_px = project(mirror_image(marker, axis=2), view, projection)

    # The projection convention is right: the marker itself is where it should be.
    direct, _ = marker_centroid(np.where(np.arange(180)[:, None, None] < marker_px[1] + 15, none, 0))
    assert np.linalg.norm(direct - marker_px) < 2.0

    # Its reflection, present only with SSR, sits on the analytic mirror image.
    below_floor_line = np.arange(180)[:, None, None] > (marker_px[1] + mirrored_px[1]) / 2
    reflection, _ = marker_centroid(np.where(below_floor_line, ssr - none, 0))
    assert np.linalg.norm(reflection - mirrored_px) < 2.0, (reflection, mirrored_px)
    x, y = mirrored_px.astype(int)
    assert none[y, x, 0] < 0.5, "without SSR the mirror shows no marker there"
    assert ssr[y, x, 0] > 2.0


def test_ssr_is_closer_to_cycles_than_probe_only(render_scene):
    ssr_run = render_scene("mirror_floor", "ssr", "--resolution", RESOLUTION)
    none = render_scene("mirror_floor", "none", "--resolution", RESOLUTION).final()
    reference = render_scene("mirror_floor", "cycles", "--resolution", RESOLUTION, "--samples", "64").final()
    passes = ssr_run.passes()
    reflective = (passes["Roughness.V"] < 0.2) & (passes["Specular Color.R"] > 0.5)
    assert reflective.mean() > 0.2

    def error(image):
        return np.sqrt(np.mean((image[reflective] - reference[reflective]) ** 2))
    ssr_error, none_error = error(ssr_run.final()), error(none)
    print(f"reflective-region RMSE vs Cycles: ssr {ssr_error:.4f}, none {none_error:.4f}")
    assert ssr_error < 0.7 * none_error


def test_every_output_is_finite_and_complete(render_scene):
    folders = [render_scene("mirror_floor", method, "--resolution", RESOLUTION).folder
               for method in ("ssr", "none")]
    for folder in folders:
        names = sorted(os.listdir(folder))
        assert names == [".ssr_records", "frame_0001.exr", "frame_0001.passes.exr", "frame_0001.png", "report.json"]
        for path in glob.glob(os.path.join(folder, "*.exr")):
            for name, channel in read_exr(path).items():
                assert np.isfinite(channel).all(), f"{path}: {name} has NaN/Inf"


def test_passes_exr_holds_inputs_and_intermediates(render_scene):
    passes = render_scene("mirror_floor", "ssr", "--resolution", RESOLUTION).passes()
    for layer in ("Combined.R", "Depth.Z", "Normal.X", "Roughness.V", "Specular Color.R",
                  "Specular Indirect.R", "SSR Reflection.R", "SSR Confidence.V", "SSR Hit.U", "SSR Hit.V"):
        assert layer in passes
    confidence = passes["SSR Confidence.V"]
    assert 0.0 <= confidence.min() and confidence.max() <= 1.0
    assert (confidence > 0.5).mean() > 0.03  # the mirror shows the cubes and the marker
