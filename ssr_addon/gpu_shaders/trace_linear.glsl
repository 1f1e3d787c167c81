/* Linear raymarch against the depth buffer ("Linear Raymarch" slide).
 *
 * Inputs:  depth_tx (view depth), normal_tx (world normal), roughness_tx.
 * Output:  hit_img = (hit uv, hit distance in view units, confidence); confidence 0 is a miss.
 *
 * The ray is projected to the screen and clipped to it, then marched in equal
 * screen-space steps of at least `trace_stride` pixels along its major axis;
 * depth along the ray is interpolated perspective-correctly (1/w). A step hits
 * when the depth span the ray covers in it overlaps the surface and the
 * `thickness` assumed behind it (a per-step "behind by less than thickness"
 * test misses surfaces where the ray's depth changes fast); a binary search
 * between the last two steps refines the hit. tests/oracles.py mirrors this
 * function step for step. */

struct ScreenRay {
  vec2 start_px, delta_px; /* screen position at t=0 and its change up to t=1 */
  float k0, k1;            /* 1/w at both ends */
  vec3 q0, q1;             /* view position / w at both ends */
};

ScreenRay project_ray(vec3 origin, vec3 direction)
{
  float ray_length = params.march.y;
  float near_z = -params.clip.x;
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
  ray.start_px = (h0.xy * ray.k0 * 0.5 + 0.5) * params.viewport.xy;
  ray.delta_px = (h1.xy * ray.k1 * 0.5 + 0.5) * params.viewport.xy - ray.start_px;
  return ray;
}

/* Largest t in [0,1] that keeps the ray on screen. */
float screen_exit(ScreenRay ray)
{
  float t_exit = 1.0;
  for (int axis = 0; axis < 2; axis++) {
    float delta = ray.delta_px[axis];
    if (delta > 0.0) {
      t_exit = min(t_exit, (params.viewport[axis] - ray.start_px[axis]) / delta);
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

float scene_depth_at(ScreenRay ray, float t)
{
  return texelFetch(depth_tx, texel_at(ray.start_px + ray.delta_px * t), 0).r;
}

/* March from t=0; returns the refined hit t, or -1 for a miss. */
float march_linear(ScreenRay ray)
{
  float t_exit = screen_exit(ray);
  float major_px = max(abs(ray.delta_px.x), abs(ray.delta_px.y)) * t_exit;
  float steps = min(params.march.w, ceil(major_px / params.march.z));
  if (steps < 1.0) {
    return -1.0;
  }
  float dt = t_exit / steps;
  float thickness = params.march.x;
  float ray_front = ray_depth_at(ray, 0.0);
  for (int i = 1; i <= int(steps); i++) {
    float t = dt * float(i);
    float ray_back = ray_depth_at(ray, t);
    float surface = scene_depth_at(ray, t);
    /* The step's depth span [ray_front, ray_back] overlaps the surface's [surface, surface + thickness]. */
    bool hit = ray_back > surface && ray_front < surface + thickness;
    ray_front = ray_back;
    if (hit) {
      float t_front = t - dt, t_behind = t;
      for (int j = 0; j < int(params.shaping.x); j++) {
        float t_mid = 0.5 * (t_front + t_behind);
        if (ray_depth_at(ray, t_mid) > scene_depth_at(ray, t_mid)) {
          t_behind = t_mid;
        }
        else {
          t_front = t_mid;
        }
      }
      return t_behind;
    }
  }
  return -1.0;
}

/* Screen-edge fade ("Edge Fading" slide): 0 at the border, 1 past border_fade. */
float border_fade(vec2 uv)
{
  float distance_to_edge = min(min(uv.x, 1.0 - uv.x), min(uv.y, 1.0 - uv.y));
  return params.shaping.y > 0.0 ? clamp(distance_to_edge / params.shaping.y, 0.0, 1.0) : 1.0;
}

/* Rays heading back to the camera reach what the depth buffer cannot show. */
float camera_facing_fade(vec3 incident, vec3 direction)
{
  float towards_camera = dot(direction, -incident);
  float fade = params.shaping.z;
  return fade > 0.0 ? clamp((1.0 - towards_camera) / fade, 0.0, 1.0) : 1.0;
}

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  hit_img = vec4(0.0);
  float depth = texelFetch(depth_tx, texel, 0).r;
  if (is_background(depth) || texelFetch(roughness_tx, texel, 0).r > params.shaping.w) {
    return;
  }
  vec2 uv = (vec2(texel) + 0.5) * params.viewport.zw;
  vec3 origin = view_position(uv, depth);
  vec3 incident = view_incident(uv);
  vec3 normal = view_normal(texelFetch(normal_tx, texel, 0).xyz);
  vec3 direction = reflect(incident, normal);
  if (dot(direction, normal) <= 0.0) {
    return; /* the shading normal faces away from the camera */
  }
  ScreenRay ray = project_ray(origin, direction);
  float t = march_linear(ray);
  if (t < 0.0) {
    return;
  }
  vec2 hit_px = ray.start_px + ray.delta_px * t;
  vec2 hit_uv = hit_px * params.viewport.zw;
  vec3 hit_position = mix(ray.q0, ray.q1, t) / mix(ray.k0, ray.k1, t);
  vec3 hit_normal = view_normal(texelFetch(normal_tx, texel_at(hit_px), 0).xyz);
  if (dot(hit_normal, direction) > 0.0) {
    return; /* back face: the ray hit the far side of a surface */
  }
  float confidence = border_fade(hit_uv) * camera_facing_fade(incident, direction);
  hit_img = vec4(hit_uv, distance(origin, hit_position), confidence);
}
