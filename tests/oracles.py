"""numpy references for the GPU passes, written from the same description as the GLSL.

Each function mirrors its shader step for step in float32, so tests can demand
agreement hit for hit rather than "looks similar".
"""
import math

import numpy as np

from ssr_addon.core.ggx import ggx_alpha

F32 = np.float32


def view_positions(depth, clip_to_view):
    """View-space position and incident direction of every pixel (image order), as common_lib.glsl."""
    height, width = depth.shape
    v, u = np.mgrid[0:height, 0:width].astype(F32)
    uv_x = (u + F32(0.5)) / F32(width)
    uv_y = F32(1.0) - (v + F32(0.5)) / F32(height)  # image row 0 is the top: GL uv.y = 1 at top
    ndc = np.stack([uv_x * 2 - 1, uv_y * 2 - 1], axis=-1).astype(F32)

    def unproject(z):
        ones = np.ones(ndc.shape[:2] + (1,), F32)
        point = np.concatenate([ndc, ones * F32(z), ones], -1) @ clip_to_view.T.astype(F32)
        return point[..., :3] / point[..., 3:4]
    origin = unproject(-1.0)
    direction = unproject(1.0) - origin
    position = origin + direction * ((-depth - origin[..., 2]) / direction[..., 2])[..., None]
    return position.astype(F32), (direction / np.linalg.norm(direction, axis=-1, keepdims=True)).astype(F32)


class ScreenRay:
    """screen_ray_lib.glsl: a view-space ray projected to the screen, t in [0, 1]."""

    def __init__(self, origin, direction, view_to_clip, viewport, clip_start, max_distance):
        ray_length = F32(max_distance)
        if direction[2] > 0:
            ray_length = min(ray_length, F32(0.99) * (F32(-clip_start) - origin[2]) / direction[2])
        end = origin + direction * ray_length
        h0 = view_to_clip @ np.append(origin, 1).astype(F32)
        h1 = view_to_clip @ np.append(end, 1).astype(F32)
        self.k0, self.k1 = F32(1) / h0[3], F32(1) / h1[3]
        self.q0, self.q1 = origin * self.k0, end * self.k1
        self.viewport = viewport
        self.start = (h0[:2] * self.k0 * F32(0.5) + F32(0.5)) * viewport
        self.delta = (h1[:2] * self.k1 * F32(0.5) + F32(0.5)) * viewport - self.start

    def exit(self):
        t_exit = F32(1)
        for axis in range(2):
            if self.delta[axis] > 0:
                t_exit = min(t_exit, (self.viewport[axis] - self.start[axis]) / self.delta[axis])
            elif self.delta[axis] < 0:
                t_exit = min(t_exit, -self.start[axis] / self.delta[axis])
        return max(t_exit, F32(0))

    def depth(self, t):
        return -((F32(1) - t) * self.q0[2] + t * self.q1[2]) / ((F32(1) - t) * self.k0 + t * self.k1)

    def t_at_depth(self, depth):
        return -(self.q0[2] + depth * self.k0) / ((self.q1[2] - self.q0[2]) + depth * (self.k1 - self.k0))

    def position(self, t):
        return self.start + self.delta * t

    def view_position(self, t):
        return ((1 - t) * self.q0 + t * self.q1) / ((1 - t) * self.k0 + t * self.k1)


def march_linear(ray, scene_depth, settings, clip_end):
    """linear_march_lib.glsl: fixed screen-space steps, span-overlap test, binary refinement."""
    t_exit = ray.exit()
    major = max(abs(ray.delta[0]), abs(ray.delta[1])) * t_exit
    steps = min(F32(settings.trace_steps), np.ceil(major / F32(settings.trace_stride)))
    if steps < 1:
        return -1.0
    dt = t_exit / steps
    ray_front = ray.depth(F32(0))
    for i in range(1, int(steps) + 1):
        t = dt * F32(i)
        ray_back = ray.depth(t)
        surface = scene_depth(ray.position(t))
        hit = ray_back > surface and ray_front < surface + F32(settings.thickness) and surface < clip_end
        ray_front = ray_back
        if hit:
            front, back = t - dt, t
            for _ in range(settings.refine_steps):
                mid = F32(0.5) * (front + back)
                if ray.depth(mid) > scene_depth(ray.position(mid)):
                    back = mid
                else:
                    front = mid
            return back
    return -1.0


def _cell_exit(ray, cell, size):
    t_cell = F32(1e30)
    for axis in range(2):
        if ray.delta[axis] != 0:
            boundary = (cell[axis] + (1 if ray.delta[axis] > 0 else 0)) * size
            t_cell = min(t_cell, (F32(boundary) - ray.start[axis]) / ray.delta[axis])
    return t_cell


def march_pixel_walk(ray, scene_depth, settings, clip_end):
    """Brute force for the Hi-Z tracer: visit every pixel the ray crosses, in order, and stop
    at the first whose depth span overlaps [depth, depth + thickness] (hiz_march_lib.glsl
    restricted to level 0)."""
    t_exit = ray.exit()
    major = max(abs(ray.delta[0]), abs(ray.delta[1]))
    nudge = F32(1.0 / 256.0) / major if major > 0 else F32(1)
    t = _cell_exit(ray, np.floor(ray.start), 1) + nudge
    while t < t_exit:
        cell = np.floor(ray.position(t))
        t_next = min(_cell_exit(ray, cell, 1), t_exit)
        depth_in, depth_out = ray.depth(t), ray.depth(t_next)
        surface = scene_depth(cell + F32(0.5))
        if (max(depth_in, depth_out) >= surface and min(depth_in, depth_out) < surface + F32(settings.thickness)
                and surface < clip_end):
            t_surface = ray.t_at_depth(surface) if depth_out > depth_in else t
            return min(max(t_surface, t), t_next)
        t = t_next + nudge
    return -1.0


def distance_on_screen(uv, direction):
    """How far (in uv) the screen line from UV along DIRECTION runs before it leaves the unit
    square: found by bisection on "still inside", not by the shader's per-axis division."""
    step = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    inside, outside = 0.0, 2.0  # the screen's diagonal is under 2
    for _ in range(60):
        middle = (inside + outside) / 2
        point = np.asarray(uv, np.float64) + middle * step
        inside, outside = (middle, outside) if np.all((point >= 0) & (point <= 1)) else (inside, middle)
    return inside


# trace.glsl's: a hit from behind on the ray's own surface this close to its plane is a graze.
SELF_HIT_PX, SELF_HIT_RETRIES = 2.0, 2


def trace_mirror_rays(depth, normal_view, roughness, view_to_clip, clip_start, clip_end, settings, march):
    """trace.glsl with mirror rays at full resolution: (H, W, 4) = (hit uv, distance, confidence).

    `normal_view` is already in view space (the tests use an identity view matrix).
    """
    height, width = depth.shape
    clip_to_view = np.linalg.inv(view_to_clip.astype(np.float64)).astype(F32)
    positions, incidents = view_positions(depth, clip_to_view)
    result = np.zeros((height, width, 4), F32)
    viewport = np.array([width, height], F32)
    depth_gl = depth[::-1]  # texel (x, y) with y up

    def scene_depth(px):
        texel = np.clip(np.floor(px).astype(np.int32), 0, np.array([width, height]) - 1)
        return depth_gl[texel[1], texel[0]]

    for row in range(height):
        for col in range(width):
            if depth[row, col] >= clip_end or roughness[row, col] > settings.max_roughness:
                continue
            origin, incident = positions[row, col], incidents[row, col]
            normal = normal_view[row, col] / np.linalg.norm(normal_view[row, col])
            direction = (incident - 2 * np.dot(normal, incident) * normal).astype(F32)
            if np.dot(direction, normal) <= 0:
                continue
            ray = ScreenRay(origin, direction, view_to_clip, viewport, clip_start, settings.max_distance)
            for attempt in range(SELF_HIT_RETRIES + 1):
                t = march(ray, scene_depth, settings, clip_end)
                if t < 0:
                    break
                hit_px = ray.position(t)
                hit_texel = np.clip(np.floor(hit_px).astype(np.int32), 0, np.array([width, height]) - 1)
                hit_normal = normal_view[::-1][hit_texel[1], hit_texel[0]]
                hit_position = ray.view_position(t)
                footprint = F32(2.0) / (view_to_clip[1, 1] * F32(height)) * -hit_position[2]
                # A graze of the ray's own surface near its origin: it goes on past that point.
                grazes = (np.dot(hit_normal, direction) > 0 and np.dot(hit_normal, normal) > 0.99
                          and abs(np.dot(normal, hit_position - origin)) < SELF_HIT_PX * footprint)
                if not grazes:
                    break
                ray = ScreenRay(hit_position + direction * footprint, direction, view_to_clip, viewport, clip_start,
                                settings.max_distance)
            if t < 0:
                continue
            hit_uv = hit_px / viewport
            if np.dot(hit_normal, direction) > 0:
                continue
            on_screen_for = distance_on_screen(hit_uv, ray.delta / viewport)
            fade = np.clip(on_screen_for / settings.border_fade, 0, 1) if settings.border_fade > 0 else 1.0
            if settings.camera_facing_fade > 0:
                fade *= np.clip((1 - np.dot(direction, -incident)) / settings.camera_facing_fade, 0, 1)
            result[row, col] = (hit_uv[0], hit_uv[1], np.linalg.norm(ray.view_position(t) - origin), fade)
    return result


def reduction_pyramid(image_gl, reduce):
    """pyramid_downsample.glsl: levels down to 1x1, ceil halving (GL row order), each texel
    REDUCE (np.nanmin, np.nanmean) of the 2x2 texels it covers, fewer on an odd edge."""
    levels = [image_gl]
    while max(levels[-1].shape[:2]) > 1:
        source = levels[-1]
        height, width = math.ceil(source.shape[0] / 2), math.ceil(source.shape[1] / 2)
        padded = np.full((height * 2, width * 2) + source.shape[2:], np.nan, F32)
        padded[:source.shape[0], :source.shape[1]] = source
        levels.append(reduce(padded.reshape(height, 2, width, 2, *source.shape[2:]), axis=(1, 3)))
    return levels


def min_pyramid(depth_gl):
    """pyramid_downsample.glsl with REDUCE_MIN."""
    return reduction_pyramid(depth_gl, np.nanmin)


def ggx_normal_cdf(cos_theta_h, alpha):
    """P(angle between h and n < theta) for GGX normals weighted by cos: tan^2 / (alpha^2 + tan^2)."""
    tan2 = (1 - cos_theta_h ** 2) / np.maximum(cos_theta_h ** 2, 1e-12)
    return tan2 / (alpha ** 2 + tan2)


def visible_normal_pdf(n_dot_v, n_dot_h, alpha):
    """ggx_lib.glsl visible_normal_pdf: G1(v) D(h) / (4 n.v)."""
    a2 = alpha * alpha
    d = a2 / (np.pi * (n_dot_h ** 2 * (a2 - 1) + 1) ** 2)
    g1 = 2 * n_dot_v / (n_dot_v + np.sqrt(a2 + (1 - a2) * n_dot_v ** 2))
    return g1 * d / (4 * n_dot_v)


def hammersley(count):
    """dfg_table.glsl hammersley(): (i + 0.5) / N and the radical inverse of i in base 2."""
    index = np.arange(count, dtype=np.uint32)
    bits = index.copy()
    bits = (bits << 16) | (bits >> 16)
    bits = ((bits & 0x55555555) << 1) | ((bits & 0xAAAAAAAA) >> 1)
    bits = ((bits & 0x33333333) << 2) | ((bits & 0xCCCCCCCC) >> 2)
    bits = ((bits & 0x0F0F0F0F) << 4) | ((bits & 0xF0F0F0F0) >> 4)
    bits = ((bits & 0x00FF00FF) << 8) | ((bits & 0xFF00FF00) >> 8)
    return (index + 0.5) / count, bits.astype(np.float64) * 2.0 ** -32


def dfg_table(size, u1, u2):
    """(A, B) of the GGX directional albedo F0 * A + B at texel centres (n.v along x, roughness along
    y), integrated over the sample points (u1, u2) drawn from D(h) cos(theta_h), as dfg_table.glsl."""
    centres = (np.arange(size) + 0.5) / size
    return np.stack([_dfg_row(centres, roughness, u1, u2) for roughness in centres])


def _dfg_row(n_dot_v, roughness, u1, u2):
    n_dot_v = n_dot_v[:, None]
    alpha = float(ggx_alpha(roughness))
    cos_theta = np.sqrt((1 - u1) / (1 + (alpha ** 2 - 1) * u1))[None]
    sin_theta = np.sqrt(1 - cos_theta ** 2)
    phi = 2 * np.pi * u2[None]
    h_x, h_z = sin_theta * np.cos(phi), cos_theta
    v_dot_h = np.sqrt(1 - n_dot_v ** 2) * h_x + n_dot_v * h_z
    n_dot_l = 2 * v_dot_h * h_z - n_dot_v
    valid = (n_dot_l > 0) & (v_dot_h > 0)
    a2 = alpha ** 2
    lambda_v = np.sqrt(a2 + (1 - a2) * n_dot_v ** 2)
    lambda_l = np.sqrt(a2 + (1 - a2) * np.clip(n_dot_l, 0, 1) ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        g2 = 2 * n_dot_v * n_dot_l / (n_dot_l * lambda_v + n_dot_v * lambda_l)
        visibility = np.where(valid, g2 * v_dot_h / (h_z * n_dot_v), 0)
    fresnel = (1 - np.clip(v_dot_h, 0, 1)) ** 5
    return np.stack([np.mean((1 - fresnel) * visibility, -1), np.mean(fresnel * visibility, -1)], -1)
