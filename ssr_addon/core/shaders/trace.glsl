/* Ray generation and tracing, one ray per traced texel ("SSR in Frostbite":
 * rays by roughness class, importance-sampled, traced at half resolution).
 *
 * Inputs:  depth_tx (view depth), normal_tx (world normal), roughness_tx, hiz_tx (min-depth atlas).
 * Outputs: ray_hit_img   = (hit uv, pdf of the ray direction, confidence); pdf 0: no ray traced,
 *                          confidence 0: traced but no trustworthy hit.
 *          ray_dir_img   = (view-space ray direction, hit distance).
 *          ray_stats_img = (ray class: 0 none, 1 cheap, 2 expensive; march iterations;
 *                           highest Hi-Z level reached; RAY_OUTCOME_*: a hit on screen, in the
 *                           guard band around the requested frame (params.frame_rect), or why
 *                           it missed).
 *
 * With half-resolution tracing each texel traces from one pixel of its 2x2
 * quad, params.quad_phase, so all four originate a ray in four iterations
 * (frame_sequence.py). Smooth pixels (roughness below the budget's threshold)
 * get expensive Hi-Z rays, the rest cheap linear rays; ties at the threshold
 * toss a coin of their own, drawn afresh every iteration.
 *
 * Compiled with SHARP_RAYS (the trace_sharp pass), it traces at full resolution, every
 * iteration, from each pixel at most params.sharp_roughness rough, into sharp_ray_hit_img and
 * sharp_ray_dir_img (no stats): a mirror's lobe is narrower than the turn of its neighbours'
 * normals, so half-resolution rays reused from them show their reflections, not its own. */

#ifdef SHARP_RAYS
#  define ray_hit_img sharp_ray_hit_img
#  define ray_dir_img sharp_ray_dir_img
#  define ray_stats_img sharp_ray_stats
vec4 sharp_ray_stats;
#endif

/* A hit from behind on the ray's own surface, this many pixel footprints from its plane, is a
 * graze near the origin; the ray goes on past it at most SELF_HIT_RETRIES times. */
#define SELF_HIT_PX 2.0
#define SELF_HIT_RETRIES 2

float halton(uint index, uint base)
{
  float result = 0.0, fraction = 1.0;
  while (index > 0u) {
    fraction /= float(base);
    result += fraction * float(index % base);
    index /= base;
  }
  return result;
}

/* Point INDEX of the Halton (2, 3) sequence, rotated per pixel (Cranley-Patterson)
 * so neighbours differ. The rotation is fixed per pixel while the index moves,
 * so each pixel's points over time keep the sequence's even spread. */
vec2 sample_point(ivec2 pixel, uint index)
{
  return fract(vec2(halton(index + 1u, 2u), halton(index + 1u, 3u)) + pixel_noise(pixel, 0u));
}

bool is_expensive(float roughness, ivec2 pixel)
{
  float threshold = params.expensive_roughness;
  /* Ties at the threshold (large areas of one roughness) share the rest of the budget. */
  return roughness < threshold ||
         (roughness == threshold && pixel_noise(pixel, params.noise_seed).x < params.expensive_tie_fraction);
}

/* This pixel's point of the frame sequence. A pixel originates a ray every
 * trace_scale^2 iterations, so it steps through the sequence at that rate: its
 * own rays take the sequence's points in order, strata filled evenly.
 * The lobe's outermost LOBE_TAIL of visible normals (gpu_passes.py) is never
 * drawn, as EEVEE's ray generation cuts 2%: those rays leave far off the lobe,
 * so on a smooth surface one of them is a speck of whatever it hit; the resolve
 * weighs the rest by the BRDF, so the reflection is the lobe without its faint
 * tail. */
vec2 lobe_sample(ivec2 pixel)
{
#ifdef SHARP_RAYS
  uint rays_per_pixel = 1u;
#else
  uint rays_per_pixel = uint(params.trace_scale * params.trace_scale);
#endif
  uint index = params.sample_index / rays_per_pixel;
  /* RAY_SAMPLING_RANDOM, for comparison: independent points, no strata (seed 0 is the rotation). */
  vec2 u = params.ray_sampling == RAY_SAMPLING_RANDOM ? pixel_noise(pixel, index + 1u) : sample_point(pixel, index);
  return vec2(u.x * (1.0 - LOBE_TAIL), u.y);
}

/* RAY_SAMPLING_UNIFORM, for comparison: a direction spread evenly over the hemisphere
 * around the normal, blind to the lobe ("Importance Sampling" slides). lobe_sample's
 * u.x < 1 - LOBE_TAIL leaves out the grazing band cos(theta) < LOBE_TAIL (ray_pdf). */
vec3 uniform_hemisphere(vec3 normal, vec2 u)
{
  float cos_theta = 1.0 - u.x, sin_theta = sqrt(max(0.0, 1.0 - u.x * u.x));
  float phi = 2.0 * M_PI * u.y;
  return tangent_frame(normal) * vec3(sin_theta * cos(phi), sin_theta * sin(phi), cos_theta);
}

void main()
{
  ray_hit_img = vec4(0.0);
  ray_dir_img = vec4(0.0);
  ray_stats_img = vec4(0.0);
#ifdef SHARP_RAYS
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  float max_roughness = min(params.max_roughness, params.sharp_roughness);
#else
  ivec2 pixel = ray_origin_pixel(ivec2(gl_FragCoord.xy));
  float max_roughness = params.max_roughness;
#endif
  float roughness = texelFetch(roughness_tx, pixel, 0).r;
  vec3 origin, incident, normal;
  if (roughness > max_roughness || !reflecting_surface(pixel, origin, incident, normal)) {
    return; /* too rough, or no ray from this pixel (surface_ray_lib.glsl) */
  }
  vec3 to_eye = -incident;
  float alpha = ggx_alpha(roughness);
  vec3 direction;
  if (params.use_importance_sampling != 0 && params.ray_sampling == RAY_SAMPLING_UNIFORM) {
    direction = uniform_hemisphere(normal, lobe_sample(pixel));
  }
  else if (params.use_importance_sampling != 0) {
    mat3 frame = tangent_frame(normal);
    direction = reflect(incident, frame * sample_visible_normal(transpose(frame) * to_eye, alpha,
                                                                lobe_sample(pixel)));
  }
  else {
    direction = reflect(incident, normal);
  }
  ray_dir_img.xyz = direction;
  ray_hit_img.z = ray_pdf(normal, to_eye, alpha, direction);
  if (dot(direction, normal) <= 0.0) {
    return; /* sampled below the surface: a ray with no light */
  }

  bool expensive = params.hiz_levels > 0 && is_expensive(roughness, pixel);
  ray_stats_img.x = expensive ? 2.0 : 1.0;
  ScreenRay ray = project_ray(origin, direction);
  float iterations = 0.0, highest_level = 0.0, t;
  vec2 hit_px;
  vec3 hit_normal;
  for (int attempt = 0;; attempt++) {
    float steps, level = 0.0;
    t = expensive ? march_hiz(ray, steps, level) : march_linear(ray, steps);
    iterations += steps;
    highest_level = max(highest_level, level);
    if (t < 0.0) {
      break;
    }
    hit_px = ray_position_px(ray, t);
    hit_normal = view_normal(texelFetch(normal_tx, texel_at(hit_px), 0).xyz);
    vec3 hit_position = ray_view_position(ray, t);
    float footprint = pixel_footprint(-hit_position.z);
    /* Near its origin a ray that leaves its surface at a grazing angle runs within a pixel's
     * depth of it, and the next pixels of that same surface count as hit from behind: where
     * the floor meets a wall, its rays never reached the wall (a dark line along the contact).
     * Such a ray goes on from past that point. */
    bool own_surface = dot(hit_normal, normal) > 0.99 &&
                       abs(dot(normal, hit_position - origin)) < SELF_HIT_PX * footprint;
    if (!(dot(hit_normal, direction) > 0.0 && own_surface) || attempt == SELF_HIT_RETRIES) {
      break;
    }
    ray = project_ray(hit_position + direction * footprint, direction);
  }
  ray_stats_img.yz = vec2(iterations, highest_level);
  if (t < 0.0) {
    ray_stats_img.w = float(miss_outcome(ray, screen_exit(ray)));
    return;
  }
  vec2 hit_uv = hit_px * params.pixel_size;
  if (dot(hit_normal, direction) > 0.0) {
    ray_stats_img.w = float(RAY_OUTCOME_BEHIND); /* back face: the ray hit the far side of a surface */
    return;
  }
  bool in_frame = all(greaterThanEqual(hit_px, params.frame_rect.xy)) && all(lessThan(hit_px, params.frame_rect.zw));
  ray_stats_img.w = float(in_frame ? RAY_OUTCOME_SCREEN : RAY_OUTCOME_GUARD_BAND);
  vec3 hit_position = ray_view_position(ray, t);
  ray_dir_img.w = distance(origin, hit_position);
  ray_hit_img.xy = hit_uv;
  float lobe_px = lobe_spread_px(alpha, ray_dir_img.w, pixel_footprint(-hit_position.z));
  ray_hit_img.w = border_fade(hit_uv, ray.delta_px, lobe_px) * camera_facing_fade(incident, direction);
}
