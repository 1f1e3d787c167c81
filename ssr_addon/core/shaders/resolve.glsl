/* Colour resolve with neighbour ray reuse ("Weighing Neighbors", "Sparse Ray
 * Tracing" and "Filtered Importance Sampling" slides): at full resolution, or
 * (params.resolve_scale 2, the sparse slide's comparison) at the traced size,
 * each texel resolving the pixel its ray started from; resolve_upscale.glsl then
 * scales that up.
 *
 * Inputs:  ray_hit_tx, ray_dir_tx (traced rays), sharp_ray_hit_tx, sharp_ray_dir_tx (the full-resolution
 *          rays of the smoothest pixels, trace_sharp; read where params.sharp_roughness >= 0),
 *          depth_tx, normal_tx, roughness_tx,
 *          color_tx (colour pyramid atlas; level 0 is the lit scene), history_record_tx
 *          (iterations the temporal history holds, history_lib.glsl), capture_hit_tx
 *          (what the captures found for each ray, read where params.capture_levels has any).
 * Outputs: resolved_img     = (reflected radiance * confidence, confidence),
 *          reflection_hit_img = (mean hit distance, mean hit uv of the screen's hits, weighted as the
 *                               radiance; the captures' share of the reflection).
 *
 * A pixel at most sharp_roughness rough traced a ray of its own this iteration. Where the rays
 * it would reuse leave part of its lobe uncovered, its own ray alone is the estimate, hit or
 * miss: the ratio estimator normalises each iteration's weights, so rays from beside a narrow
 * lobe (a curved mirror's turned normals; a floor's neighbours at a low resolution, where a
 * texel turns the ray further than a 0.12-rough lobe is wide) still weigh in full, and a still
 * averaging such iterations settles on their blur of the reflection. Each ray drawn from a
 * lobe weighs its Smith masking, about one, so reused rays that weigh less between them than
 * REUSE_COVERAGE of as many rays of its own miss part of it. With captures, its own ray stands
 * only where it found its hit on screen unfaded and no capture took the nearest traced ray:
 * the captures trace only the traced rays (its own hit may be one the camera does not see).
 * Otherwise the reused rays are its estimate, as for every other pixel.
 * Every other pixel reuses the rays of its own and neighbouring traced texels with the
 * ratio estimator  L = sum(L_k f_s(l_k) cos / p_k) / sum(f_s(l_k) cos / p_k),
 * where l_k runs from this pixel to ray k's hit and p_k is the pdf ray k was
 * drawn with. The FG factor is applied by the composite. Rays that missed
 * count in the denominator only through the confidence: confidence is the
 * share of the BRDF weight whose rays found a trustworthy hit.
 *
 * Firefly guard (params.use_firefly_guard; Karis 2014, EEVEE's denoiser): the
 * hits' colours are averaged tone-mapped, c / (1 + s max(c)), and mapped back, so
 * one bright ray among dim ones cannot dominate a pixel. Its strength s is one over
 * the iterations the temporal history averages at the pixel: full on a frame without
 * history, fading as the history converges to the unguarded mean. */

/* Neighbours whose ray left a surface turned further than this from this pixel's (78 degrees:
 * another surface, a wall beside the floor, not the curve of this one) are not reused. */
#define SAME_SURFACE_COS 0.2

/* Reused rays that weigh less than this share of as many rays drawn from the pixel's own lobe
 * leave part of it uncovered (see above): at three quarters, a 0.15-rough floor at 160x90
 * settles 3.1 % off its lobe integral (reusing: 5.3 %; its own ray only where the reused ones
 * weigh under one: 4.3 %), and at 640x360, where reuse covers the lobe, 1.4 % (its own ray
 * alone: 2.7 %). */
#define REUSE_COVERAGE 0.75

vec3 tonemap(vec3 color, float strength)
{
  return color / (1.0 + strength * max(max(color.r, color.g), color.b));
}

vec3 tonemap_inverse(vec3 color, float strength)
{
  return color / max(1.0 - strength * max(max(color.r, color.g), color.b), 1e-4);
}

const ivec2 NEIGHBOURS[9] = ivec2[9](ivec2(0, 0), ivec2(1, 0), ivec2(0, 1), ivec2(1, 1), ivec2(-1, 0),
                                     ivec2(0, -1), ivec2(-1, 1), ivec2(1, -1), ivec2(-1, -1));

/* Colour of a ray's hit as a cone: the pyramid level whose texel matches the
 * patch the sample stands for, SOLID_ANGLE steradians seen at the hit distance. */
vec3 hit_radiance(vec2 hit_uv, float hit_distance, float solid_angle)
{
  float level = 0.0;
  if (params.use_cone_filter != 0 && params.use_importance_sampling != 0) {
    float hit_depth = texelFetch(depth_tx, texel_at(hit_uv * params.viewport_size), 0).r;
    level = cone_level(hit_distance, solid_angle, pixel_footprint(hit_depth), params.color_levels);
  }
  int lower = int(floor(level));
  int upper = min(lower + 1, params.color_levels - 1);
  if (lower > 0) {
    return pyramid_sample(color_tx, params.color_level[lower], params.color_level[upper], level, hit_uv);
  }
  /* A sharp hit reads the surface it hit, not what lies beside it on screen. */
  vec3 sharp = surface_sample(color_tx, params.color_level[0], normal_tx, hit_uv * params.viewport_size,
                              params.viewport_size);
  return mix(sharp, atlas_sample(color_tx, params.color_level[upper], hit_uv).rgb, level);
}

/* The ratio estimator's sums over a set of rays (see above). */
struct RayEstimate {
  vec3 radiance;        /* sum of hit weight * (tone-mapped) radiance */
  float weight;         /* sum of f_s cos / p, misses included */
  float hit_weight;     /* the share of it whose rays found a hit (screen or capture) */
  float screen_weight;  /* the screen's share */
  float capture_weight; /* the captures' share */
  float distance;       /* sum of screen hit weight * hit distance */
  vec2 hit_uv;          /* sum of screen hit weight * hit uv */
};

#define REUSED_RAYS 0
#define OWN_RAY 1

RayEstimate no_estimate()
{
  return RayEstimate(vec3(0.0), 0.0, 0.0, 0.0, 0.0, 0.0, vec2(0.0));
}

void main()
{
  ivec2 pixel = params.resolve_scale > 1 ? ray_origin_pixel(ivec2(gl_FragCoord.xy)) : ivec2(gl_FragCoord.xy);
  resolved_img = vec4(0.0);
  reflection_hit_img = vec4(0.0);
  float depth = texelFetch(depth_tx, pixel, 0).r;
  float roughness = texelFetch(roughness_tx, pixel, 0).r;
  float max_roughness = params.max_roughness;
  if (is_background(depth) || roughness > max_roughness) {
    return;
  }
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  vec3 position = view_position(uv, depth);
  vec3 to_eye = -view_incident(uv);
  vec3 normal = view_normal(texelFetch(normal_tx, pixel, 0).xyz);
  float alpha = ggx_alpha(roughness);

  int scale = params.trace_scale;
  ivec2 own_texel = pixel / scale;
  /* Mirror the neighbour pattern towards this pixel's side of its quad, so the
   * first four rays are the four nearest. */
  ivec2 side = scale > 1 ? (pixel - own_texel * scale) * 2 - 1 : ivec2(1);
  ivec2 trace_size = ivec2(params.trace_size);
  bool own_ray = false;
  vec4 own_hit = vec4(0.0);
  if (roughness <= params.sharp_roughness) {
    own_hit = texelFetch(sharp_ray_hit_tx, pixel, 0);
    bool captured = params.capture_levels != 0 && texelFetch(capture_hit_tx, own_texel, 0).a > 0.0;
    own_ray = own_hit.z > 0.0 && !captured && (own_hit.w >= 1.0 || params.capture_levels == 0);
  }
  int ray_count = params.resolve_samples;
  float iterations = accumulated_iterations(pixel);
  /* The history averages a bright ray's excess over the iterations it holds, so the guard needs
   * to compress only that share: at full strength it would keep a lamp's glint dim forever. */
  float guard = params.use_firefly_guard != 0 ? 1.0 / iterations : 0.0;
  float n_dot_v = dot(normal, to_eye);

  /* The sums of the rays it reuses, and of its own ray. */
  RayEstimate sums[2] = RayEstimate[2](no_estimate(), no_estimate());
  for (int k = own_ray ? -1 : 0; k < ray_count; k++) {
    bool is_own = k < 0; /* this pixel's own ray (trace_sharp) */
    int set = is_own ? OWN_RAY : REUSED_RAYS;
    ivec2 texel = clamp(own_texel + NEIGHBOURS[max(k, 0)] * side, ivec2(0), trace_size - 1);
    vec4 hit = is_own ? own_hit : texelFetch(ray_hit_tx, texel, 0);
    if (!(hit.z > 0.0)) {
      continue; /* no ray was traced there (sky, rough or back-facing pixel) */
    }
    /* A ray stands for this pixel's lobe only if it left the same surface: one from the wall
     * beside a floor pixel saw what the wall reflects (the floor, darkening the contact). */
    vec3 origin_normal = texelFetch(normal_tx, ray_origin_pixel(texel), 0).xyz;
    if (k > 0 && dot(view_normal(origin_normal), normal) < SAME_SURFACE_COS) {
      continue;
    }
    vec4 ray = is_own ? texelFetch(sharp_ray_dir_tx, pixel, 0) : texelFetch(ray_dir_tx, texel, 0);
    vec3 direction = ray.xyz;
    float hit_distance = 0.0;
    /* A capture's hit stands in for the screen's share it takes (planar_trace.glsl). */
    vec4 captured = params.capture_levels != 0 && !is_own ? texelFetch(capture_hit_tx, texel, 0) : vec4(0.0);
    float screen_share = min(hit.w, 1.0 - captured.a);
    if (screen_share > 0.0) {
      float hit_depth = texelFetch(depth_tx, texel_at(hit.xy * params.viewport_size), 0).r;
      vec3 to_hit = view_position(hit.xy, hit_depth) - position;
      hit_distance = length(to_hit);
      direction = to_hit / max(hit_distance, 1e-6);
    }
    float weight = ggx_brdf_cos(normal, to_eye, direction, alpha) / hit.z;
    sums[set].weight += weight;
    if (screen_share > 0.0 && weight > 0.0) {
      float hit_weight = weight * screen_share;
      /* A ray stands for one of the rays of its set (own: one; reused: N) of every iteration the
       * history averages here. */
      float rays_averaged = is_own ? iterations : float(ray_count) * iterations;
      vec3 radiance = hit_radiance(hit.xy, hit_distance, ray_solid_angle(hit.z, rays_averaged, n_dot_v, alpha));
      sums[set].radiance += hit_weight * tonemap(radiance, guard);
      sums[set].hit_weight += hit_weight;
      sums[set].screen_weight += hit_weight;
      sums[set].distance += hit_weight * hit_distance;
      sums[set].hit_uv += hit_weight * hit.xy;
    }
    if (captured.a > 0.0 && weight > 0.0) {
      float hit_weight = weight * captured.a;
      sums[set].radiance += hit_weight * tonemap(captured.rgb, guard);
      sums[set].hit_weight += hit_weight;
      sums[set].capture_weight += hit_weight;
    }
  }
  bool covered = sums[REUSED_RAYS].weight >= REUSE_COVERAGE * float(ray_count);
  RayEstimate estimate = sums[own_ray && !covered ? OWN_RAY : REUSED_RAYS];
  /* Written so that NaN, should any reach here, counts as "no reflection". */
  if (!(estimate.hit_weight > 0.0 && estimate.weight > 0.0)) {
    return;
  }
  /* Confidence fades to zero over the top fifth of [0, max_roughness] so the
   * switch to the probe/world reflection leaves no seam (max_roughness 0: mirrors only). */
  float roughness_fade = max_roughness > 0.0 ?
                             1.0 - smoothstep(0.8 * max_roughness, max_roughness, roughness) : 1.0;
  float confidence = estimate.hit_weight / estimate.weight * roughness_fade;
  vec3 radiance = estimate.radiance / estimate.hit_weight;
  radiance = tonemap_inverse(radiance, guard);
  resolved_img = vec4(radiance * confidence, confidence);
  /* The screen's hits only: a capture's have no place on screen to reproject. */
  reflection_hit_img = estimate.screen_weight > 0.0 ?
                           vec4(estimate.distance, estimate.hit_uv, 0.0) / estimate.screen_weight : vec4(0.0);
  reflection_hit_img.w = estimate.capture_weight / estimate.hit_weight;
}
