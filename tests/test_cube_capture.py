"""The depth cube map level: a closed box room whose walls leave the frame, mirrored in its floor.

The cube is ray cast from its centre (what blender.cube_capture draws), and each floor
pixel's mirror ray is intersected with the room in numpy: where the hit is in view of the
cube's centre, the cube must find it within one of its texels (parallax), and no ray may
pass through a wall to what lies beyond (occlusion: the room is closed, there is no sky).
"""
import numpy as np

from gpu_harness import synthetic_inputs
from synthetic import intersect_boxes, perspective, pixel_rays
from ssr_addon.core.captures import CubeCapture, cube_atlas, cube_face_views
from ssr_addon.core.inputs import BACKGROUND_DEPTH
from ssr_addon.core.settings import preset
from ssr_addon.core.uniforms import RAY_OUTCOMES

WIDTH, HEIGHT = 200, 120
FLOOR_Y = -1.0
ROOM = ((-5.0, FLOOR_Y, -12.0), (5.0, 4.0, 3.0))
PILLAR = ((1.0, FLOOR_Y, -7.0), (2.0, 4.0, -6.0))  # floor to ceiling: some of the room hides behind it
CENTRE = (-1.0, 1.0, -4.0)
SIDE = 128
# Each wall of the room its own colour (by the axis and side its inward normal points), the pillar grey.
WALL_COLOURS = {(0, 1): (0.9, 0.2, 0.2), (0, -1): (0.2, 0.9, 0.2), (1, 1): (0.3, 0.3, 0.3), (1, -1): (0.9, 0.9, 0.2),
                (2, 1): (0.2, 0.2, 0.9), (2, -1): (0.9, 0.2, 0.9)}
PILLAR_COLOUR = (0.6, 0.6, 0.6)
SKY_COLOUR = (0.3, 0.5, 0.8)


def camera_to_world():
    pitch = np.radians(-30.0)
    rotation = np.array([[1, 0, 0], [0, np.cos(pitch), -np.sin(pitch)], [0, np.sin(pitch), np.cos(pitch)]])
    matrix = np.eye(4)
    matrix[:3, :3], matrix[:3, 3] = rotation, (0.0, 2.0, 0.0)
    return matrix


def room_hits(origins, directions, open_ceiling=False):
    """(t, colour, inward normal) of rays from inside the room: the nearest of the room's walls
    (from inside) and the pillar; with OPEN_CEILING, a ray through the ceiling escapes to the
    world (t BACKGROUND_DEPTH, SKY_COLOUR, no normal)."""
    low, high = (np.asarray(corner, np.float64) for corner in ROOM)
    with np.errstate(divide="ignore", invalid="ignore"):
        t_planes = np.stack([(low - origins) / directions, (high - origins) / directions], -1)
    t_planes = np.where(t_planes > 1e-6, t_planes, np.inf)
    t_axis = t_planes.min(-1)
    axis = np.argmin(t_axis, -1)
    t_wall = np.take_along_axis(t_axis, axis[..., None], -1)[..., 0]
    sign = -np.sign(np.take_along_axis(directions, axis[..., None], -1)[..., 0])  # the inward normal's
    colour = np.zeros(t_wall.shape + (3,))
    normal = np.zeros(t_wall.shape + (3,))
    for (wall_axis, wall_sign), wall_colour in WALL_COLOURS.items():
        on = (axis == wall_axis) & (sign == wall_sign)
        colour[on] = wall_colour
        normal[on, wall_axis] = wall_sign
    if open_ceiling:
        sky = (axis == 1) & (sign == -1)
        t_wall = np.where(sky, BACKGROUND_DEPTH, t_wall)
        colour[sky], normal[sky] = SKY_COLOUR, 0.0
    t_pillar, pillar, pillar_normal = intersect_boxes(origins, directions, [PILLAR], t_wall)
    hit = pillar >= 0
    colour[hit], normal[hit] = PILLAR_COLOUR, pillar_normal[hit]
    return np.where(hit, t_pillar, t_wall), colour, normal


def ray_cast_cube(open_ceiling=False):
    projection = perspective(SIDE, SIDE, fov_y_degrees=90.0)
    views = cube_face_views(CENTRE)
    radiance, depth = [], []
    for view in views:
        to_world = np.linalg.inv(view)
        rays = pixel_rays(SIDE, SIDE, projection) @ to_world[:3, :3].T  # view z = -1: t is the axis distance
        t, colour, _ = room_hits(np.broadcast_to(CENTRE, rays.shape), rays, open_ceiling)
        radiance.append(np.concatenate([colour, np.ones_like(t[..., None])], -1))
        depth.append(t)
    return CubeCapture(cube_atlas(radiance), cube_atlas(depth).astype(np.float32), CENTRE, views)


def frame(open_ceiling=False):
    projection = perspective(WIDTH, HEIGHT)
    to_world = camera_to_world()
    rays = pixel_rays(WIDTH, HEIGHT, projection) @ to_world[:3, :3].T
    origins = np.broadcast_to(to_world[:3, 3], rays.shape)
    t, colour, normal = room_hits(origins, rays, open_ceiling)
    floor = normal[..., 1] == 1.0
    radiance = np.concatenate([colour, np.ones_like(t[..., None])], -1).astype(np.float32)
    points = origins + rays * t[..., None]
    mirrored = rays * (1.0, -1.0, 1.0)
    mirrored /= np.linalg.norm(mirrored, axis=-1, keepdims=True)
    t_mirror, mirror_colour, _ = room_hits(points, mirrored, open_ceiling)
    hit_points = points + mirrored * t_mirror[..., None]
    return (projection, t.astype(np.float32), normal.astype(np.float32), np.where(floor, 0.0, 1.0).astype(np.float32),
            radiance, floor, points, mirrored, t_mirror, mirror_colour, hit_points)


def seen_from_centre(points, open_ceiling=False):
    """Whether the cube's centre sees each of POINTS itself, not something in front of it."""
    to_points = points - np.asarray(CENTRE)
    distance = np.linalg.norm(to_points, axis=-1)
    t, _, _ = room_hits(np.broadcast_to(CENTRE, points.shape), to_points / distance[..., None], open_ceiling)
    return t > distance - 1e-3


def traced_room(open_ceiling=False):
    """frame(OPEN_CEILING) and (ray outcome, reflection) of its mirror floor's rays, one iteration
    of each pixel's own mirror ray traced through the screen and the room's cube."""
    from ssr_addon.core.chain import ChainState, run_chain
    from ssr_addon.core.gpu_backend import download
    traced = frame(open_ceiling)
    projection, depth, normal, roughness, radiance = traced[:5]
    settings = preset("balanced").with_overrides(["half_resolution=false", "use_importance_sampling=false",
                                                  "accumulate_iterations=1", "noise_threshold=0"])
    inputs = synthetic_inputs(depth, normal, roughness, projection, radiance, (1.0, 1.0),
                              view_matrix=np.linalg.inv(camera_to_world()).astype(np.float32))
    inputs.cube = ray_cast_cube(open_ceiling)
    inputs.textures.update(inputs.cube.textures())
    state = ChainState.still()
    state.begin_frame(0)
    outputs = run_chain(inputs, settings, state)
    return traced, download(outputs["ray_outcome"]), download(outputs["reflection"])


def test_cube_finds_each_wall_hit_with_parallax_and_occlusion(gpu_backend):
    (projection, depth, normal, roughness, radiance, floor, points, mirrored, t_exact, expected,
     hit_points), outcome, reflection = traced_room()
    by_cube = floor & (outcome[..., 3] == RAY_OUTCOMES["cube"])
    assert by_cube.sum() > 0.3 * floor.sum(), "the walls leave the frame: the cube resolves much of the floor"

    # Parallax: a hit the centre can see is found within one of the cube's texels.
    visible = seen_from_centre(hit_points)
    found = points + mirrored * outcome[..., :1]
    error = np.linalg.norm(found - hit_points, axis=-1)
    texel = 2.0 * np.linalg.norm(hit_points - np.asarray(CENTRE), axis=-1) / SIDE
    judged = by_cube & visible
    assert judged.sum() > 1000
    assert (error[judged] <= texel[judged]).mean() > 0.98, np.quantile(error[judged] / texel[judged], [0.5, 0.98])

    # Occlusion: no ray goes through a wall or the pillar to something farther.
    assert (outcome[..., 0][by_cube] <= t_exact[by_cube] + texel[by_cube]).mean() > 0.995
    # Every floor ray the centre can see the hit of is resolved (no sky shows: there is none).
    assert (reflection[..., 3][floor & visible] > 0.99).mean() > 0.98
    shown = reflection[..., :3] / np.maximum(reflection[..., 3:], 1e-6)
    colour_error = np.abs(shown - expected).max(-1)
    assert (colour_error[judged] < 0.05).mean() > 0.95


def test_a_ray_out_through_an_open_ceiling_shows_the_world_the_cube_shows(gpu_backend):
    """The same room without its ceiling: a floor ray that leaves through the opening, past all
    the cube shows, reads the world in its direction from the cube (the world is infinitely far:
    the centre sees it in the same direction), not the probe's; the walls stay where they were.
    Judged where the centre sees the whole ray out of the room (behind the pillar as the centre
    sees it, a ray may as well meet something there)."""
    (_, _, _, _, _, floor, points, mirrored, t_exact, expected, _), outcome, reflection = \
        traced_room(open_ceiling=True)
    in_view = np.ones_like(floor)
    for t in np.linspace(0.05, 2.0 * np.linalg.norm(np.subtract(*ROOM)), 64):
        in_view &= seen_from_centre(points + mirrored * t, open_ceiling=True)
    escapes = floor & (t_exact >= BACKGROUND_DEPTH) & in_view
    assert escapes.sum() > 0.1 * floor.sum()
    by_cube = outcome[..., 3] == RAY_OUTCOMES["cube"]
    assert (by_cube[escapes] & (reflection[..., 3][escapes] > 0.99)).mean() > 0.95
    shown = reflection[..., :3] / np.maximum(reflection[..., 3:], 1e-6)
    assert (np.abs(shown - SKY_COLOUR).max(-1)[escapes] < 0.02).mean() > 0.95
    walls = floor & by_cube & (t_exact < BACKGROUND_DEPTH)
    assert walls.sum() > 1000 and (np.abs(shown - expected).max(-1)[walls] < 0.05).mean() > 0.9
