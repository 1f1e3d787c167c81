"""numpy references for the GPU passes, written from the same description as the GLSL.

Each function mirrors its shader step for step in float32, so tests can demand
agreement hit for hit rather than "looks similar".
"""
import numpy as np

F32 = np.float32


def view_positions(depth, clip_to_view):
    """View-space position of every pixel (image order), as common_lib.glsl view_position()."""
    height, width = depth.shape
    v, u = np.mgrid[0:height, 0:width].astype(F32)
    uv_x = (u + F32(0.5)) / F32(width)
    uv_y = F32(1.0) - (v + F32(0.5)) / F32(height)  # image row 0 is the top: GL uv.y = 1 at top
    ndc = np.stack([uv_x * 2 - 1, uv_y * 2 - 1], axis=-1).astype(F32)
    def unproject(z):
        clip = np.concatenate([ndc, np.full(ndc.shape[:2] + (1,), z, F32), np.ones(ndc.shape[:2] + (1,), F32)], -1)
        point = clip @ clip_to_view.T.astype(F32)
        return point[..., :3] / point[..., 3:4]
    origin = unproject(-1.0)
    direction = unproject(1.0) - origin
    position = origin + direction * ((-depth - origin[..., 2]) / direction[..., 2])[..., None]
    return position.astype(F32), (direction / np.linalg.norm(direction, axis=-1, keepdims=True)).astype(F32)


def trace_linear(depth, normal_view, roughness, view_to_clip, clip_start, clip_end, settings):
    """Hits of trace_linear.glsl: (H, W, 4) = (hit uv, distance, confidence), image order.

    `normal_view` is already in view space (the tests use an identity view matrix).
    """
    height, width = depth.shape
    clip_to_view = np.linalg.inv(view_to_clip.astype(np.float64)).astype(F32)
    positions, incidents = view_positions(depth, clip_to_view)
    result = np.zeros((height, width, 4), F32)
    viewport = np.array([width, height], F32)
    depth_gl = depth[::-1]  # texel (x, y) with y up

    def scene_depth(px):
        texel = np.clip(px.astype(np.int32), 0, np.array([width, height]) - 1)
        return depth_gl[texel[1], texel[0]]

    for row in range(height):
        for col in range(width):
            d = depth[row, col]
            if d >= clip_end or roughness[row, col] > settings.max_roughness:
                continue
            origin, incident = positions[row, col], incidents[row, col]
            normal = normal_view[row, col] / np.linalg.norm(normal_view[row, col])
            direction = (incident - 2 * np.dot(normal, incident) * normal).astype(F32)
            if np.dot(direction, normal) <= 0:
                continue
            ray_length = F32(settings.max_distance)
            if direction[2] > 0:
                ray_length = min(ray_length, F32(0.99) * (F32(-clip_start) - origin[2]) / direction[2])
            end = origin + direction * ray_length
            h0 = view_to_clip @ np.append(origin, 1).astype(F32)
            h1 = view_to_clip @ np.append(end, 1).astype(F32)
            k0, k1 = F32(1) / h0[3], F32(1) / h1[3]
            q0, q1 = origin * k0, end * k1
            start = (h0[:2] * k0 * F32(0.5) + F32(0.5)) * viewport
            delta = (h1[:2] * k1 * F32(0.5) + F32(0.5)) * viewport - start
            t_exit = F32(1)
            for axis in range(2):
                if delta[axis] > 0:
                    t_exit = min(t_exit, (viewport[axis] - start[axis]) / delta[axis])
                elif delta[axis] < 0:
                    t_exit = min(t_exit, -start[axis] / delta[axis])
            t_exit = max(t_exit, F32(0))
            major = max(abs(delta[0]), abs(delta[1])) * t_exit
            steps = min(F32(settings.trace_steps), np.ceil(major / F32(settings.trace_stride)))
            if steps < 1:
                continue
            dt = t_exit / steps

            def ray_depth(t):
                return -((F32(1) - t) * q0[2] + t * q1[2]) / ((F32(1) - t) * k0 + t * k1)

            hit_t = -1.0
            ray_front = ray_depth(F32(0))
            for i in range(1, int(steps) + 1):
                t = dt * F32(i)
                ray_back = ray_depth(t)
                surface = scene_depth(start + delta * t)
                hit = ray_back > surface and ray_front < surface + F32(settings.thickness)
                ray_front = ray_back
                if hit:
                    front, back = t - dt, t
                    for _ in range(settings.refine_steps):
                        mid = F32(0.5) * (front + back)
                        if ray_depth(mid) > scene_depth(start + delta * mid):
                            back = mid
                        else:
                            front = mid
                    hit_t = back
                    break
            if hit_t < 0:
                continue
            hit_px = start + delta * hit_t
            hit_uv = hit_px / viewport
            hit_position = ((1 - hit_t) * q0 + hit_t * q1) / ((1 - hit_t) * k0 + hit_t * k1)
            hit_texel = np.clip(hit_px.astype(np.int32), 0, np.array([width, height]) - 1)
            hit_normal = normal_view[::-1][hit_texel[1], hit_texel[0]]
            if np.dot(hit_normal, direction) > 0:
                continue
            edge = min(hit_uv[0], 1 - hit_uv[0], hit_uv[1], 1 - hit_uv[1])
            fade = np.clip(edge / settings.border_fade, 0, 1) if settings.border_fade > 0 else 1.0
            towards_camera = np.dot(direction, -incident)
            if settings.camera_facing_fade > 0:
                fade *= np.clip((1 - towards_camera) / settings.camera_facing_fade, 0, 1)
            result[row, col] = (hit_uv[0], hit_uv[1], np.linalg.norm(hit_position - origin), fade)
    return result


def composite(combined, specular_color, specular_indirect, reflection):
    """composite.glsl."""
    replaced = specular_color * reflection[..., 3:4] * (reflection[..., :3] - specular_indirect)
    return np.concatenate([np.maximum(combined[..., :3] + replaced, 0), combined[..., 3:4]], -1)
