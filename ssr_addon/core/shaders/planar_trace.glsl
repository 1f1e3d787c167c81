/* Planar capture: what a large flat reflector shows, traced in a view of its own ("Beyond the
 * screen", level 2; the deck's planar reflections baseline, and EEVEE 5.0's planar probes,
 * eevee_ray_trace_planar_comp.glsl, which are traced before the screen like this).
 *
 * The capture is the scene rendered from the frame's camera mirrored in the reflector's plane,
 * the reflector hidden: seen from there, everything the reflector mirrors lies in front,
 * including what the frame's camera cannot see (the underside of a sphere over a mirror
 * floor) and what lies outside the frame. A ray that leaves the reflector is marched through
 * that view's depth like a screen ray (screen_ray_lib.glsl, linear_march_lib.glsl, with the
 * screen redefined below) and its hit read from the capture's colour pyramid as a cone, as the
 * resolve reads screen hits. Its hit replaces the screen's, which may be a surface that only
 * hides the true hit from the camera, unless both found the same surface: then the screen's
 * stands, lit as the frame lights it (EEVEE lights the capture's view anew, and its
 * screen-space light there differs: the walls of a corridor mirrored in its floor came out
 * darker than the frame shows them). A capture path traced over an EEVEE frame
 * (params.capture_light_stands) stands there too: it carries the indirect light EEVEE's frame
 * lacks, the reflector's own among it, and sees the hit along the ray, as a reflection does.
 * A capture drawn for another view (params.capture_from_this_view 0: a moving view in the 3D
 * View traces the held view's) is held to more: other_views_hit_holds.
 *
 * Inputs:  ray_hit_tx, ray_dir_tx, ray_stats_tx (the screen trace), depth_tx, normal_tx,
 *          roughness_tx, history_record_tx (the frame), capture_depth_tx, capture_normal_tx,
 *          capture_color_tx (the capture: view depth, world normal, colour pyramid atlas).
 * Outputs: planar_hit_img = (radiance of the hit, share of the ray it resolves: 0 for a ray
 *                            it did not take, the capture's edge fade for one it hit, 1 for
 *                            one that escapes over the world the capture shows),
 *          ray_outcome_img = (hit distance, 0, 0, RAY_OUTCOME_*: PLANAR where it hit, the
 *                            screen trace's outcome elsewhere). */

/* PLANE_TOLERANCE_PX and PLANE_NORMAL_COS (core.captures, defined with this pass): rays from
 * pixels that close to the plane, with a normal that close to its, leave the reflector. */

/* The screen and the capture found the same surface where their hits lie this many of the
 * frame's pixel footprints apart along the ray, with normals this close, and the screen's hit
 * is inside a surface, not on a silhouette: its pixel's colour there mixes in what lies
 * behind, which the capture sees past (a ring round a sphere mirrored in the floor). */
#define SAME_HIT_PX 4.0
#define SAME_HIT_NORMAL_COS 0.9

bool on_silhouette(ivec2 texel)
{
  float depth = texelFetch(depth_tx, texel, 0).r;
  float tolerance = SAME_HIT_PX * pixel_footprint(depth);
  ivec2 last = ivec2(params.viewport_size) - 1;
  float left = texelFetch(depth_tx, clamp(texel - ivec2(1, 0), ivec2(0), last), 0).r;
  float right = texelFetch(depth_tx, clamp(texel + ivec2(1, 0), ivec2(0), last), 0).r;
  float below = texelFetch(depth_tx, clamp(texel - ivec2(0, 1), ivec2(0), last), 0).r;
  float above = texelFetch(depth_tx, clamp(texel + ivec2(0, 1), ivec2(0), last), 0).r;
  /* Across a surface depth runs nearly straight from pixel to pixel; across a silhouette it jumps. */
  return abs(left + right - 2.0 * depth) > tolerance || abs(below + above - 2.0 * depth) > tolerance;
}

/* The screen trace ended on a surface (its confidence there may have faded to 0). */
bool screen_ended_on_surface(float screen_outcome)
{
  return screen_outcome == float(RAY_OUTCOME_SCREEN) || screen_outcome == float(RAY_OUTCOME_GUARD_BAND);
}

/* Where along the ray the screen's hit (SCREEN_HIT: uv, confidence) lies, -1 where it has none
 * that counts (no surface, or faded to nothing); TOLERANCE: how near another hit must lie to be
 * the same, SAME_HIT_PX of the frame's pixel footprints there. */
float screen_hit_distance(vec4 screen_hit, float screen_outcome, vec3 view_origin, vec3 view_ray,
                          out float tolerance)
{
  tolerance = 0.0;
  if (!screen_ended_on_surface(screen_outcome) || !(screen_hit.w > 0.0)) {
    return -1.0;
  }
  float screen_distance = texelFetch(ray_dir_tx, ivec2(gl_FragCoord.xy), 0).w;
  tolerance = SAME_HIT_PX * pixel_footprint(-(view_origin + view_ray * screen_distance).z);
  return screen_distance;
}

/* Whether the screen's hit (SCREEN_HIT: uv, confidence; at SCREEN_DISTANCE along the ray, within
 * TOLERANCE: screen_hit_distance) is the capture's, at CAPTURE_DISTANCE with CAPTURE_WORLD_NORMAL. */
bool screen_found_it(vec4 screen_hit, float screen_distance, float tolerance, float capture_distance,
                     vec3 capture_world_normal)
{
  if (screen_distance < 0.0) {
    return false;
  }
  ivec2 screen_texel = texel_at(screen_hit.xy * params.viewport_size);
  vec3 screen_normal = texelFetch(normal_tx, screen_texel, 0).xyz;
  return abs(screen_distance - capture_distance) <= tolerance &&
         dot(normalize(screen_normal), normalize(capture_world_normal)) > SAME_HIT_NORMAL_COS &&
         !on_silhouette(screen_texel);
}

/* Whether the frame's camera sees past VIEW_POINT (its view space): the surface it shows there lies
 * farther along its view axis than the point, by more than the thickness and SAME_HIT_PX pixel
 * footprints. */
bool frame_sees_past(vec3 view_point)
{
  vec2 uv = clip_to_uv(params.view_to_clip * vec4(view_point, 1.0));
  if (any(lessThan(uv, vec2(0.0))) || any(greaterThanEqual(uv, vec2(1.0)))) {
    return false;
  }
  float shown = texelFetch(depth_tx, texel_at(uv * params.viewport_size), 0).r;
  return -view_point.z < shown - params.thickness - SAME_HIT_PX * pixel_footprint(-view_point.z);
}

/* A capture drawn for another view: its camera no longer mirrors the frame's, so a mirror's rays
 * no longer run along its view rays, and where one passes just behind a surface the capture
 * shows, its march can end there, on a surface that only hides the ray from that camera (a wet
 * street's window reflections went dark 20 degrees into an orbit). Its hit (VIEW_HIT, in the
 * frame's view space, at CAPTURE_DISTANCE along the ray) holds where the frame's camera does not
 * see past it, as no surface lies where a camera sees through, and, where the screen hit something
 * too (SCREEN_DISTANCE, TOLERANCE: screen_hit_distance), only if it is the nearer: a surface hidden
 * from the frame's camera that the screen's march ran past. */
bool other_views_hit_holds(float screen_distance, float tolerance, vec3 view_hit, float capture_distance)
{
  if (frame_sees_past(view_hit)) {
    return false;
  }
  return screen_distance < 0.0 || capture_distance < screen_distance - tolerance;
}

vec3 capture_radiance(vec2 hit_uv, float hit_depth, float hit_distance, float solid_angle)
{
  float level = 0.0;
  if (params.use_cone_filter != 0 && params.use_importance_sampling != 0) {
    float texel_size = pixel_footprint_of(params.capture_view_to_clip, params.capture_size.y, hit_depth);
    level = cone_level(hit_distance, solid_angle, texel_size, params.capture_color_levels);
  }
  int lower = int(floor(level));
  int upper = min(lower + 1, params.capture_color_levels - 1);
  if (lower > 0) {
    return pyramid_sample(capture_color_tx, params.capture_color_level[lower], params.capture_color_level[upper],
                          level, hit_uv);
  }
  vec3 sharp = texel_colour(capture_color_tx, params.capture_color_level[0], hit_uv);
  return mix(sharp, atlas_sample(capture_color_tx, params.capture_color_level[upper], hit_uv).rgb, level);
}

/* The capture's pixel where it shows the world in DIRECTION (its view space): the world is
 * infinitely far, so that is the direction's vanishing point. vec2(-1) where the capture does
 * not look that way or shows a surface there. */
vec2 world_shown_at(vec3 direction)
{
  vec2 px = clip_to_uv(params.capture_view_to_clip * vec4(direction, 0.0)) * params.capture_size;
  if (any(lessThan(px, vec2(0.0))) || any(greaterThanEqual(px, params.capture_size)) ||
      !is_background(texelFetch(capture_depth_tx, ivec2(px), 0).r))
  {
    return vec2(-1.0);
  }
  return px;
}

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  vec4 screen_stats = texelFetch(ray_stats_tx, texel, 0);
  planar_hit_img = vec4(0.0);
  ray_outcome_img = vec4(0.0, 0.0, 0.0, screen_stats.w);
  vec4 hit = texelFetch(ray_hit_tx, texel, 0);
  if (!(hit.z > 0.0) || screen_stats.x == 0.0) {
    return; /* no ray from here */
  }
  ivec2 pixel = ray_origin_pixel(texel);
  float depth = texelFetch(depth_tx, pixel, 0).r;
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  vec3 view_origin = view_position(uv, depth);
  vec3 view_ray = texelFetch(ray_dir_tx, texel, 0).xyz;
  vec3 origin = (params.view_to_world * vec4(view_origin, 1.0)).xyz;
  vec3 direction = mat3(params.view_to_world) * view_ray;
  vec3 world_normal = texelFetch(normal_tx, pixel, 0).xyz;
  vec3 plane_normal = params.capture_plane.xyz;
  float height = dot(plane_normal, origin) + params.capture_plane.w;
  if (abs(height) > PLANE_TOLERANCE_PX * pixel_footprint(depth) ||
      dot(normalize(world_normal), plane_normal) < PLANE_NORMAL_COS || dot(direction, plane_normal) <= 0.0)
  {
    return; /* not a ray off the reflector */
  }
  vec3 capture_origin = (params.capture_world_to_view * vec4(origin, 1.0)).xyz;
  vec3 capture_direction = mat3(params.capture_world_to_view) * direction;
  ScreenRay ray = project_ray(capture_origin, capture_direction);
  float roughness = texelFetch(roughness_tx, pixel, 0).r;
  float rays_averaged = float(params.resolve_samples) * accumulated_iterations(pixel);
  float solid_angle = ray_solid_angle(hit.z, rays_averaged, dot(view_normal(world_normal), -view_incident(uv)),
                                      ggx_alpha(roughness));
  float steps;
  float t = march_linear(ray, steps);
  if (t < 0.0) {
    /* Nothing the capture shows lies on the ray. Where it stays in the capture's view and runs
     * on over the world, it escapes, and the world stands in its direction as the capture
     * shows it: nearer to a path trace's world than EEVEE's probe (mirror_floor's sky came out
     * 1.5-4.6 % dark through it, by channel). Where the screen hit something, that stands; and a
     * path tracer's own reflection of the world (params.probe_reflection 0) is exact. */
    vec2 world_px = world_shown_at(capture_direction);
    if (params.probe_reflection == 0 || screen_ended_on_surface(screen_stats.w) || world_px.x < 0.0 ||
        miss_outcome(ray, 1.0) != RAY_OUTCOME_ESCAPED)
    {
      return; /* the screen's outcome stands */
    }
    /* At any distance along the ray the cone covers as many texels as at one unit, where the
     * point lies as deep as the direction's cosine to the view axis. */
    float cosine = -normalize(capture_direction).z;
    planar_hit_img = vec4(capture_radiance(world_px / params.capture_size, cosine, 1.0, solid_angle), 1.0);
    ray_outcome_img = vec4(params.max_distance, 0.0, 0.0, float(RAY_OUTCOME_PLANAR));
    return;
  }
  vec2 hit_px = ray_position_px(ray, t);
  ivec2 hit_texel = screen_texel_at(hit_px);
  vec3 hit_world_normal = texelFetch(capture_normal_tx, hit_texel, 0).xyz;
  vec3 hit_normal = mat3(params.capture_world_to_view) * hit_world_normal;
  if (dot(hit_normal, capture_direction) > 0.0) {
    return; /* the far side of a surface */
  }
  vec3 hit_position = ray_view_position(ray, t);
  float hit_distance = distance(capture_origin, hit_position);
  float tolerance;
  float screen_distance = screen_hit_distance(hit, screen_stats.w, view_origin, view_ray, tolerance);
  bool same_surface = params.capture_light_stands == 0 &&
                      screen_found_it(hit, screen_distance, tolerance, hit_distance, hit_world_normal);
  if (same_surface && (hit.w >= 1.0 || params.probe_reflection == 0)) {
    return;
  }
  if (!same_surface && params.capture_from_this_view == 0 &&
      !other_views_hit_holds(screen_distance, tolerance, view_origin + normalize(view_ray) * hit_distance,
                             hit_distance))
  {
    return; /* the screen's outcome stands */
  }
  vec2 hit_uv = hit_px / params.capture_size;
  vec3 radiance = capture_radiance(hit_uv, -hit_position.z, hit_distance, solid_angle);
  /* A mirror's ray runs along the capture camera's own ray through its hit: moving less than a
   * pixel on the capture, it cannot leave it, and the edge fade (for rays that run on past their
   * hit) would only leave the frame's edge rows to the probe. */
  float lobe_px = lobe_spread_px(ggx_alpha(roughness), hit_distance,
                                 pixel_footprint_of(params.capture_view_to_clip, params.capture_size.y,
                                                    -hit_position.z));
  float fade = length(ray.delta_px) >= 1.0 ? border_fade(hit_uv, ray.delta_px, lobe_px) : 1.0;
  if (same_surface) {
    /* The screen's hit stands as far as it is not faded (near the screen's edge, or towards the
     * camera); the capture, which sees the same surface clear of both, takes the rest from the
     * probe (a path tracer's own reflection, exact, keeps it). */
    planar_hit_img = vec4(radiance, min(1.0 - hit.w, fade));
    return;
  }
  planar_hit_img = vec4(radiance, fade);
  ray_outcome_img = vec4(hit_distance, 0.0, 0.0, float(RAY_OUTCOME_PLANAR));
}
