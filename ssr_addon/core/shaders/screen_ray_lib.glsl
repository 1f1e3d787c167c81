/* A reflection ray projected to the screen, shared by both tracers.
 * Position on screen is linear in t; depth along the ray is interpolated
 * perspective-correctly: view z / w and 1 / w are both linear in t.
 *
 * The screen is the frame's unless a pass that marches another view (a capture's) defines
 * SCREEN_VIEW_TO_CLIP, SCREEN_SIZE and SCREEN_DEPTH_TX before this file; positions and
 * directions are then in that view's space. */
#ifndef SCREEN_VIEW_TO_CLIP
#  define SCREEN_VIEW_TO_CLIP params.view_to_clip
#  define SCREEN_SIZE params.viewport_size
#  define SCREEN_DEPTH_TX depth_tx
#endif
/* Depth tests along a ray that missed, to tell one that passed behind a surface from one
 * that left the frame or escaped (RAY_OUTCOME_*). */
#define BEHIND_SAMPLES 24

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
  vec4 h0 = SCREEN_VIEW_TO_CLIP * vec4(origin, 1.0);
  vec4 h1 = SCREEN_VIEW_TO_CLIP * vec4(end, 1.0);
  ScreenRay ray;
  ray.k0 = 1.0 / h0.w;
  ray.k1 = 1.0 / h1.w;
  ray.q0 = origin * ray.k0;
  ray.q1 = end * ray.k1;
  ray.start_px = (h0.xy * ray.k0 * 0.5 + 0.5) * SCREEN_SIZE;
  ray.delta_px = (h1.xy * ray.k1 * 0.5 + 0.5) * SCREEN_SIZE - ray.start_px;
  return ray;
}

/* Largest t in [0,1] that keeps the ray on screen. */
float screen_exit(ScreenRay ray)
{
  float t_exit = 1.0;
  for (int axis = 0; axis < 2; axis++) {
    float delta = ray.delta_px[axis];
    if (delta > 0.0) {
      t_exit = min(t_exit, (SCREEN_SIZE[axis] - ray.start_px[axis]) / delta);
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

/* The texel of the screen under a position in its pixels, kept on it. */
ivec2 screen_texel_at(vec2 position_px)
{
  return clamp(ivec2(floor(position_px)), ivec2(0), ivec2(SCREEN_SIZE) - 1);
}

float scene_depth_at(ScreenRay ray, float t)
{
  return texelFetch(SCREEN_DEPTH_TX, screen_texel_at(ray_position_px(ray, t)), 0).r;
}

/* Whether the ray runs behind what the screen shows, by more than the thickness, somewhere
 * before T_END: what it would have hit there the screen may not show. */
bool passes_behind(ScreenRay ray, float t_end)
{
  for (int i = 1; i <= BEHIND_SAMPLES; i++) {
    float t = t_end * float(i) / float(BEHIND_SAMPLES);
    float surface = scene_depth_at(ray, t);
    if (!is_background(surface) && ray_depth_at(ray, t) > surface + params.thickness) {
      return true;
    }
  }
  return false;
}

/* Why a ray that found nothing on screen missed (RAY_OUTCOME_*), its march ended at T_END. */
int miss_outcome(ScreenRay ray, float t_end)
{
  if (passes_behind(ray, t_end)) {
    return RAY_OUTCOME_BEHIND;
  }
  return screen_exit(ray) < 1.0 ? RAY_OUTCOME_LEFT_FRAME : RAY_OUTCOME_ESCAPED;
}

/* Width, in units of GGX alpha, of the linear ramp that spreads like a glossy lobe's reflected
 * directions: they spread 5.3 alpha between their 10th and 90th percentiles, which a linear
 * ramp covers over 0.8 of its width. */
#define LOBE_RAMP_PER_ALPHA 6.7

/* How far, in pixels of the screen, a lobe of GGX ALPHA spreads its rays' hits HIT_DISTANCE
 * away, where a pixel is FOOTPRINT across; 0 where rays run along the mirror direction
 * (importance sampling off). */
float lobe_spread_px(float alpha, float hit_distance, float footprint)
{
  if (params.use_importance_sampling == 0) {
    return 0.0;
  }
  return LOBE_RAMP_PER_ALPHA * alpha * hit_distance / max(footprint, 1e-30);
}

/* Screen-edge fade ("Edge Fading" slide): a hit at UV of a ray running along DIRECTION_PX
 * on screen weighs 0 where the ray leaves the screen and 1 from border_fade (a share of the
 * screen) before that, measured along the ray. Rays that run on past a hit leave the screen
 * there, so the reflection would end in a hard line; a ray running along an edge leaves
 * through another, and its neighbours' rays do too: its hits near that edge are not cut off.
 * A glossy lobe's rays, LOBE_PX across on screen (lobe_spread_px; 0 for a mirror), already
 * leave over that spread, so the share of the lobe still on screen falls smoothly by itself;
 * ramps in sequence widen in quadrature, so each ray fades over only what its lobe lacks of
 * border_fade (fading it over all of it took a 0.12-rough floor's lobe down to 0.61 at the
 * frame's edge, where the lobe keeps 0.80 on screen). */
float border_fade(vec2 uv, vec2 direction_px, float lobe_px)
{
  if (params.border_fade <= 0.0) {
    return 1.0;
  }
  vec2 direction = direction_px / SCREEN_SIZE;
  float direction_length = length(direction);
  vec2 room = mix(uv, 1.0 - uv, step(0.0, direction)); /* to the edge it heads for, per axis */
  /* A ray that does not move on screen: the nearest edge. */
  vec2 distance_to_exit = direction_length > 0.0 ? room * direction_length / max(abs(direction), vec2(1e-30)) :
                                                   min(uv, 1.0 - uv);
  /* The lobe's spread in the same units, along the ray (a ray that does not move: a row's height). */
  float lobe = direction_length > 0.0 ? lobe_px * direction_length / length(direction_px) : lobe_px / SCREEN_SIZE.y;
  float ramp = sqrt(max(params.border_fade * params.border_fade - lobe * lobe, 0.0));
  return clamp(min(distance_to_exit.x, distance_to_exit.y) / max(ramp, 1e-6), 0.0, 1.0);
}

/* Rays heading back to the camera reach what the depth buffer cannot show. */
float camera_facing_fade(vec3 incident, vec3 direction)
{
  float towards_camera = dot(direction, -incident);
  float fade = params.camera_facing_fade;
  return fade > 0.0 ? clamp((1.0 - towards_camera) / fade, 0.0, 1.0) : 1.0;
}
