/* A reflection ray projected to the screen, shared by both tracers.
 * Position on screen is linear in t; depth along the ray is interpolated
 * perspective-correctly: view z / w and 1 / w are both linear in t. */

struct ScreenRay {
  vec2 start_px, delta_px; /* full-resolution screen position at t=0 and its change up to t=1 */
  float k0, k1;            /* 1/w at both ends */
  vec3 q0, q1;             /* view position / w at both ends */
};

ScreenRay project_ray(vec3 origin, vec3 direction)
{
  float ray_length = params.max_distance;
  float near_z = -params.clip_start;
  if (direction.z > 0.0) {
    /* Stop just short of the near plane: points behind the camera do not project. */
    ray_length = min(ray_length, 0.99 * (near_z - origin.z) / direction.z);
  }
  vec3 end = origin + direction * ray_length;
  vec4 h0 = params.view_to_clip * vec4(origin, 1.0);
  vec4 h1 = params.view_to_clip * vec4(end, 1.0);
  ScreenRay ray;
  ray.k0 = 1.0 / h0.w;
  ray.k1 = 1.0 / h1.w;
  ray.q0 = origin * ray.k0;
  ray.q1 = end * ray.k1;
  ray.start_px = (h0.xy * ray.k0 * 0.5 + 0.5) * params.viewport_size;
  ray.delta_px = (h1.xy * ray.k1 * 0.5 + 0.5) * params.viewport_size - ray.start_px;
  return ray;
}

/* Largest t in [0,1] that keeps the ray on screen. */
float screen_exit(ScreenRay ray)
{
  float t_exit = 1.0;
  for (int axis = 0; axis < 2; axis++) {
    float delta = ray.delta_px[axis];
    if (delta > 0.0) {
      t_exit = min(t_exit, (params.viewport_size[axis] - ray.start_px[axis]) / delta);
    }
    else if (delta < 0.0) {
      t_exit = min(t_exit, -ray.start_px[axis] / delta);
    }
  }
  return max(t_exit, 0.0);
}

float ray_depth_at(ScreenRay ray, float t)
{
  return -mix(ray.q0.z, ray.q1.z, t) / mix(ray.k0, ray.k1, t);
}

/* The t at which the ray reaches a given view depth (solves ray_depth_at(t) = depth). */
float ray_t_at_depth(ScreenRay ray, float depth)
{
  return -(ray.q0.z + depth * ray.k0) / ((ray.q1.z - ray.q0.z) + depth * (ray.k1 - ray.k0));
}

vec2 ray_position_px(ScreenRay ray, float t)
{
  return ray.start_px + ray.delta_px * t;
}

vec3 ray_view_position(ScreenRay ray, float t)
{
  return mix(ray.q0, ray.q1, t) / mix(ray.k0, ray.k1, t);
}

float scene_depth_at(ScreenRay ray, float t)
{
  return texelFetch(depth_tx, texel_at(ray_position_px(ray, t)), 0).r;
}

/* Screen-edge fade ("Edge Fading" slide): a hit at UV of a ray running along DIRECTION_PX
 * on screen weighs 0 where the ray leaves the screen and 1 from border_fade (a share of the
 * screen) before that, measured along the ray. Rays that run on past a hit leave the screen
 * there, so the reflection would end in a hard line; a ray running along an edge leaves
 * through another, and its neighbours' rays do too: its hits near that edge are not cut off. */
float border_fade(vec2 uv, vec2 direction_px)
{
  if (params.border_fade <= 0.0) {
    return 1.0;
  }
  vec2 direction = direction_px * params.pixel_size;
  float direction_length = length(direction);
  vec2 room = mix(uv, 1.0 - uv, step(0.0, direction)); /* to the edge it heads for, per axis */
  /* A ray that does not move on screen: the nearest edge. */
  vec2 distance_to_exit = direction_length > 0.0 ? room * direction_length / max(abs(direction), vec2(1e-30)) :
                                                   min(uv, 1.0 - uv);
  return clamp(min(distance_to_exit.x, distance_to_exit.y) / params.border_fade, 0.0, 1.0);
}

/* Rays heading back to the camera reach what the depth buffer cannot show. */
float camera_facing_fade(vec3 incident, vec3 direction)
{
  float towards_camera = dot(direction, -incident);
  float fade = params.camera_facing_fade;
  return fade > 0.0 ? clamp((1.0 - towards_camera) / fade, 0.0, 1.0) : 1.0;
}
