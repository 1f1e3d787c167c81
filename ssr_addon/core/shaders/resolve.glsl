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
 * Each pixel reuses the rays of its own and neighbouring traced texels with the
 * ratio estimator  L = sum(L_k f_s(l_k) cos / p_k) / sum(f_s(l_k) cos / p_k),
 * where l_k runs from this pixel to ray k's hit and p_k is the pdf ray k was
 * drawn with. The FG factor is applied by the composite. Rays that missed
 * count in the denominator only through the confidence: confidence is the
 * share of the BRDF weight whose rays found a trustworthy hit.
 *
 * A pixel at most sharp_roughness rough traced a ray of its own this iteration, drawn from its own
 * lobe, and weighs it with the rays it reuses by the balance heuristic of multiple importance
 * sampling (Veach 1997): every ray counts as drawn from all of their lobes at once, with pdf
 * sum_j p_j(l), each lobe seen from the pixel its ray left. Rays from beside a narrow lobe (a curved
 * mirror's turned normals; a floor's neighbours at a low resolution, where a texel turns the ray
 * further than a 0.12-rough lobe is wide) then weigh as little as they cover of it, where alone
 * the ratio estimator would normalise them to full weight and a still would settle on their
 * blur; where the lobes overlap all of them share the estimate, with less noise than its own ray
 * alone (a 0.15-rough floor settles 3.2 % off its lobe integral at 160x90 and 1.0 % at 640x360;
 * reusing alone, 5.3 % at 160x90). With captures, its own ray counts only where it found its hit
 * on screen unfaded and no capture took the nearest traced ray: the captures trace only the
 * traced rays (its own hit may be one the camera does not see).
 *
 * Firefly guard (params.use_firefly_guard; Karis 2014, EEVEE's denoiser): the
 * hits' colours are averaged tone-mapped, c / (1 + s max(c)), and mapped back, so
 * one bright ray among dim ones cannot dominate a pixel. Its strength s is one over
 * the iterations the temporal history averages at the pixel: full on a frame without
 * history, fading as the history converges to the unguarded mean. */

/* Neighbours whose ray left a surface turned further than this from this pixel's (78 degrees:
 * another surface, a wall beside the floor, not the curve of this one) are not reused. */
#define SAME_SURFACE_COS 0.2

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
  vec3 sharp = texel_colour(color_tx, params.color_level[0], hit_uv);
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

/* The lobe a ray was drawn from: the surface of the pixel it left, in view space. */
struct Lobe {
  vec3 origin;
  vec3 normal;
  vec3 to_eye;
  float alpha;
};

Lobe lobe_at(ivec2 pixel)
{
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  return Lobe(view_position(uv, texelFetch(depth_tx, pixel, 0).r),
              view_normal(texelFetch(normal_tx, pixel, 0).xyz), -view_incident(uv),
              ggx_alpha(texelFetch(roughness_tx, pixel, 0).r));
}

/* Its own ray and at most 9 reused ones. */
#define MAX_RAYS 10

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

  /* The rays it weighs: its own first, where it has one, then those it reuses. */
  ivec2 ray_texels[MAX_RAYS];
  ivec2 ray_origins[MAX_RAYS];
  int rays = 0;
  for (int k = own_ray ? -1 : 0; k < ray_count; k++) {
    ivec2 texel = clamp(own_texel + NEIGHBOURS[max(k, 0)] * side, ivec2(0), trace_size - 1);
    if (k >= 0 && !(texelFetch(ray_hit_tx, texel, 0).z > 0.0)) {
      continue; /* no ray was traced there (sky, rough or back-facing pixel) */
    }
    ivec2 origin = k < 0 ? pixel : ray_origin_pixel(texel);
    /* A ray stands for this pixel's lobe only if it left the same surface: one from the wall
     * beside a floor pixel saw what the wall reflects (the floor, darkening the contact). */
    vec3 origin_normal = texelFetch(normal_tx, origin, 0).xyz;
    if (k > 0 && dot(view_normal(origin_normal), normal) < SAME_SURFACE_COS) {
      continue;
    }
    ray_texels[rays] = texel;
    ray_origins[rays] = origin;
    rays++;
  }
  /* Only a pixel with its own ray weighs the rays by all of their lobes. */
  Lobe lobes[MAX_RAYS];
  for (int j = 0; own_ray && j < rays; j++) {
    lobes[j] = lobe_at(ray_origins[j]);
  }

  RayEstimate estimate = RayEstimate(vec3(0.0), 0.0, 0.0, 0.0, 0.0, 0.0, vec2(0.0));
  for (int i = 0; i < rays; i++) {
    bool is_own = own_ray && i == 0; /* this pixel's own ray (trace_sharp) */
    ivec2 texel = ray_texels[i];
    vec4 hit = is_own ? own_hit : texelFetch(ray_hit_tx, texel, 0);
    vec4 ray = is_own ? texelFetch(sharp_ray_dir_tx, pixel, 0) : texelFetch(ray_dir_tx, texel, 0);
    vec3 direction = ray.xyz;
    float hit_distance = 0.0;
    vec3 hit_position = vec3(0.0);
    /* A capture's hit stands in for the screen's share it takes (planar_trace.glsl). */
    vec4 captured = params.capture_levels != 0 && !is_own ? texelFetch(capture_hit_tx, texel, 0) : vec4(0.0);
    float screen_share = min(hit.w, 1.0 - captured.a);
    if (screen_share > 0.0) {
      float hit_depth = texelFetch(depth_tx, texel_at(hit.xy * params.viewport_size), 0).r;
      hit_position = view_position(hit.xy, hit_depth);
      vec3 to_hit = hit_position - position;
      hit_distance = length(to_hit);
      direction = to_hit / max(hit_distance, 1e-6);
    }
    /* With its own ray, every ray counts as drawn from all of their lobes (balance heuristic),
     * each towards the hit from the pixel it left. */
    float pdf = hit.z;
    if (own_ray) {
      pdf = 0.0;
      for (int j = 0; j < rays; j++) {
        Lobe lobe = lobes[j];
        vec3 from_lobe = screen_share > 0.0 ? normalize(hit_position - lobe.origin) : direction;
        /* An importance-sampled ray below its surface has no light (trace.glsl): no lobe sends a
         * hit there. Mirror rays weigh by the BRDF alone. */
        bool drawn = dot(lobe.normal, from_lobe) > 0.0 || params.use_importance_sampling == 0;
        pdf += drawn ? ray_pdf(lobe.normal, lobe.to_eye, lobe.alpha, from_lobe) : 0.0;
      }
    }
    float weight = pdf > 0.0 ? ggx_brdf_cos(normal, to_eye, direction, alpha) / pdf : 0.0;
    estimate.weight += weight;
    if (screen_share > 0.0 && weight > 0.0) {
      float hit_weight = weight * screen_share;
      /* A ray stands for one of the rays drawn with its pdf (with its own ray, all of them: one
       * per iteration) of every iteration the history averages here. */
      float rays_averaged = own_ray ? iterations : float(ray_count) * iterations;
      vec3 radiance = hit_radiance(hit.xy, hit_distance, ray_solid_angle(pdf, rays_averaged, n_dot_v, alpha));
      estimate.radiance += hit_weight * tonemap(radiance, guard);
      estimate.hit_weight += hit_weight;
      estimate.screen_weight += hit_weight;
      estimate.distance += hit_weight * hit_distance;
      estimate.hit_uv += hit_weight * hit.xy;
    }
    if (captured.a > 0.0 && weight > 0.0) {
      float hit_weight = weight * captured.a;
      estimate.radiance += hit_weight * tonemap(captured.rgb, guard);
      estimate.hit_weight += hit_weight;
      estimate.capture_weight += hit_weight;
    }
  }
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
