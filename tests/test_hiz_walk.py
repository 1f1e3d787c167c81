"""The recorded Hi-Z walk (hiz_walk.py, the `hiz_walk` pass) is the tracer's own march: it ends
where the numpy pixel-by-pixel oracle and the trace pass end, takes as many steps as the trace
pass counts, and skips only cells the ray passes in front of, measured on the depth buffer itself."""
from types import SimpleNamespace

import numpy as np
import pytest

from gpu_harness import CLIP_END, CLIP_START, run_synthetic_chain, synthetic_inputs
from oracles import ScreenRay, march_pixel_walk, min_pyramid, view_positions
from synthetic import perspective, raycast
from ssr_addon.core.settings import ChainSettings

F32 = np.float32
# Mirror rays at full resolution, every ray expensive, no fades: a trace hit is a confident hit.
SETTINGS = ChainSettings(use_hiz=True, thickness=0.5, use_importance_sampling=False, half_resolution=False,
                         use_temporal=False, resolve_samples=1, hiz_max_iterations=1024, border_fade=0.0,
                         camera_facing_fade=0.0)


def corridor_with_plank(width=80, height=48):
    """synthetic.corridor (floor, back wall, a box, a one-pixel pole) and a plank floating above the
    floor: mirror rays from the floor in front of it pass behind it on their way to the wall."""
    projection = perspective(width, height)
    boxes = [((-3.0, -1.0, -9.0), (3.0, 3.0, -8.0)),      # back wall
             ((-1.6, -1.0, -5.5), (-0.4, 0.2, -4.5)),     # box on the floor
             ((0.9, -1.0, -4.05), (0.94, 1.2, -3.95)),    # thin pole
             ((-0.2, 0.5, -4.2), (0.6, 0.7, -4.0))]       # floating plank
    depth, normal = raycast(width, height, projection, boxes, floor_y=-1.0)
    return depth, normal, projection


def oracle_ray(scene, pixel):
    """The numpy ray of PIXEL (column, row), built from oracles.py, not from the shader."""
    depth, normal, projection = scene.depth, scene.normal, scene.projection
    column, row = pixel
    positions, incidents = view_positions(depth, np.linalg.inv(projection.astype(np.float64)).astype(F32))
    incident = incidents[row, column]
    surface_normal = normal[row, column] / np.linalg.norm(normal[row, column])
    direction = (incident - 2 * np.dot(surface_normal, incident) * surface_normal).astype(F32)
    viewport = np.array(depth.shape[::-1], F32)
    return ScreenRay(positions[row, column], direction, projection, viewport, CLIP_START, SETTINGS.max_distance)


def oracle_hit_pixel(scene, pixel):
    """(column, row) where the brute-force pixel walk stops, or None."""
    height, width = scene.depth.shape
    depth_gl = scene.depth[::-1]

    def scene_depth(px):
        texel = np.clip(np.floor(px).astype(np.int32), 0, np.array([width, height]) - 1)
        return depth_gl[texel[1], texel[0]]
    ray = oracle_ray(scene, pixel)
    t = march_pixel_walk(ray, scene_depth, SETTINGS, CLIP_END)
    if t < 0:
        return None
    x, y = np.clip(np.floor(ray.position(t)).astype(int), 0, [width - 1, height - 1])
    return int(x), int(height - 1 - y)


@pytest.fixture(scope="module")
def scene(gpu_backend):
    """The corridor, traced by the chain, and the walks of a few floor pixels: the longest confident
    hit, the longest hit on the pole, the longest hit on the wall through the plank's columns (it
    passes behind the plank) and the longest walk that hits nothing."""
    from lab.hiz_walk import hiz_walk
    depth, normal, projection = corridor_with_plank()
    height, width = depth.shape
    arrays, _ = run_synthetic_chain(depth, normal, np.zeros_like(depth), projection, SETTINGS)
    inputs = synthetic_inputs(depth, normal, np.zeros_like(depth), projection)
    stats, ray_hit = arrays["ray_stats"], arrays["ray_hit"]
    floor = np.all(np.isclose(normal, (0, 1, 0)), axis=-1) & (stats[..., 0] == 2)
    hit = floor & (ray_hit[..., 3] > 0)
    rows, columns = np.nonzero(hit)
    hit_columns = np.floor(ray_hit[rows, columns, 0] * width).astype(int)
    hit_rows = height - 1 - np.floor(ray_hit[rows, columns, 1] * height).astype(int)
    reach = np.abs(hit_columns - columns) + np.abs(hit_rows - rows)
    pole_column = np.nonzero(((normal[..., 2] > 0.99) & (depth > 3.9) & (depth < 4.0)).any(axis=0))[0][0]
    on_pole = np.nonzero(hit_columns == pole_column)[0]
    pole = on_pole[reach[on_pole].argmax()]
    plank = (normal[..., 2] > 0.99) & (np.abs(depth - 4.0) < 0.01)
    plank_rows, plank_columns = np.nonzero(plank)
    # Through the plank's columns, from below it to the wall above it.
    behind = np.nonzero(np.isin(columns, plank_columns) & (rows > plank_rows.max()) &
                        (hit_rows < plank_rows.min()))[0]
    behind = behind[reach[behind].argmax()]
    missed = np.where(floor & (ray_hit[..., 3] == 0), stats[..., 1], 0)  # the longest walk to no hit
    miss_row, miss_column = np.unravel_index(missed.argmax(), missed.shape)
    pixels = {"long": (int(columns[reach.argmax()]), int(rows[reach.argmax()])),
              "pole": (int(columns[pole]), int(rows[pole])), "behind": (int(columns[behind]), int(rows[behind])),
              "miss": (int(miss_column), int(miss_row))}
    walks = {name: hiz_walk(inputs, SETTINGS, pixel) for name, pixel in pixels.items()}
    return SimpleNamespace(depth=depth, normal=normal, projection=projection, arrays=arrays, inputs=inputs,
                           pixels=pixels, walks=walks, levels=len(min_pyramid(depth[::-1])))


def test_walk_ends_where_the_pixel_walk_oracle_and_the_trace_pass_end(scene):
    height, width = scene.depth.shape
    assert all(scene.walks[name].status == "hit" for name in ("long", "pole", "behind"))
    assert scene.walks["miss"].status == "miss"
    for name, walk in scene.walks.items():
        column, row = walk.pixel
        assert walk.hit_pixel == oracle_hit_pixel(scene, walk.pixel), name
        assert walk.linear_hit_pixel == walk.hit_pixel, name  # the same march held at level 0
        ray_hit = scene.arrays["ray_hit"][row, column]
        if ray_hit[3] > 0:
            traced = (int(ray_hit[0] * width), height - 1 - int(ray_hit[1] * height))
            assert walk.hit_pixel == traced, name
        else:
            assert walk.status == "miss", name
        assert (walk.visits[-1].outcome == "hit") == (walk.status == "hit"), name


def test_walk_takes_the_steps_the_trace_pass_counts(scene):
    for name, walk in scene.walks.items():
        column, row = walk.pixel
        _, iterations, highest_level, _ = scene.arrays["ray_stats"][row, column]
        assert walk.iterations == len(walk.visits) == iterations > 0, name
        assert walk.highest_level == highest_level, name
        assert [visit.iteration for visit in walk.visits] == list(range(1, walk.iterations + 1))
    assert scene.walks["long"].highest_level >= 3, "a long ray should climb the pyramid"
    assert any(visit.outcome == "behind" for visit in scene.walks["behind"].visits)


def test_levels_change_one_step_at_a_time(scene):
    top = scene.levels - 1
    for name, walk in scene.walks.items():
        visits = walk.visits
        assert visits[0].level == 0, name
        assert max(visit.level for visit in visits) == walk.highest_level, name
        for visit, following in zip(visits, visits[1:]):
            assert abs(following.level - visit.level) <= 1, name
            expected = {"skip": min(visit.level + 1, top), "descend": visit.level - 1, "behind": 0}
            assert following.level == expected[visit.outcome], (name, visit)
        assert all(visit.outcome != "hit" for visit in visits[:-1]), name


def test_skipped_cells_lie_wholly_behind_the_ray(scene):
    """Every skipped cell holds nothing the ray could hit: its depths, read straight from the
    depth buffer, are all beyond the numpy ray's depth where it enters and leaves the cell."""
    height, width = scene.depth.shape
    depth_gl = scene.depth[::-1]
    skipped = 0
    for name, walk in scene.walks.items():
        ray = oracle_ray(scene, walk.pixel)
        for visit in walk.visits:
            if visit.outcome != "skip":
                continue
            x0, y0, x1, y1 = visit.pixel_bounds()
            middle = ray.position(F32(0.5) * (F32(visit.t) + F32(visit.t_next)))
            assert x0 <= middle[0] < x1 and y0 <= middle[1] < y1, (name, visit)  # the ray is in the cell
            nearest = depth_gl[y0:min(y1, height), x0:min(x1, width)].min()
            assert visit.cell_depth == nearest, (name, visit)
            assert max(ray.depth(F32(visit.t)), ray.depth(F32(visit.t_next))) < nearest, (name, visit)
            skipped += 1
    assert skipped >= 10


def test_pixel_tests_count_the_pixels_a_linear_walk_crosses(scene):
    """A 4-connected line from the origin pixel to the hit crosses one pixel per step in x or y."""
    walk = scene.walks["long"]
    steps = abs(walk.hit_pixel[0] - walk.pixel[0]) + abs(walk.hit_pixel[1] - walk.pixel[1])
    assert steps - 2 <= walk.pixel_tests <= steps  # a ray through a pixel corner skips one
    assert walk.iterations < walk.pixel_tests / 2, "the hierarchy should save most of the tests"


def test_diagram_is_written(scene, tmp_path):
    import matplotlib.image
    from lab.slides.hiz_diagram import draw_hiz_walk
    for name, walk in scene.walks.items():
        path = tmp_path / f"{name}.png"
        summary = draw_hiz_walk(walk, scene.depth, str(path))
        assert path.stat().st_size > 10_000
        assert matplotlib.image.imread(str(path)).shape[1] == 900
        assert summary["iterations"] == walk.iterations and summary["pixel_tests"] == walk.pixel_tests
        assert summary["hit_pixel"] == walk.hit_pixel
        assert f"{walk.iterations} cell visits instead of {walk.pixel_tests} pixel tests" == summary["caption"]


def test_a_pixel_of_the_world_gives_no_ray(scene, tmp_path):
    from lab.hiz_walk import hiz_walk
    from lab.slides.hiz_diagram import draw_hiz_walk
    walk = hiz_walk(scene.inputs, SETTINGS, (0, 0))  # the top-left corner sees the sky
    assert walk.status == "no ray" and walk.visits == [] and walk.hit_pixel is None
    draw_hiz_walk(walk, scene.depth, str(tmp_path / "none.png"))
    assert (tmp_path / "none.png").stat().st_size > 0
