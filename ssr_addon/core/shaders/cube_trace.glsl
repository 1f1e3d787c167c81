/* Depth cube map: what neither the screen nor a planar capture resolved, traced through six
 * 90-degree views from one point among the reflectors ("Beyond the screen", level 3; the
 * deck's cubemap baseline with a depth per texel: distance impostors, Szirmay-Kalos et al.,
 * Eurographics 2005, GPU Gems 3 ch. 17; light field probes, McGuire et al., I3D 2017).
 *
 * A plain cubemap is looked up by direction alone, as if everything lay infinitely far: it
 * shows reflections in the wrong place (no parallax) and the world through walls (no
 * occlusion). With each texel's distance along its face's axis the cube is a depth map seen
 * from its centre: a ray from anywhere is marched through it, at each step comparing how far
 * its point lies along the face axis with what the face shows there. The first step from in
 * front to behind brackets the hit, a secant search refines it; where the point there is far
 * behind the surface the cube shows, the ray went behind that surface's silhouette as seen
 * from the centre, not into it, and the march goes on.
 *
 * Inputs:  ray_hit_tx, ray_dir_tx (the screen trace), planar_hit_tx, ray_outcome_tx (the planar
 *          capture's where it ran, params.capture_levels), depth_tx, normal_tx, roughness_tx,
 *          history_record_tx (the frame), cube_depth_tx, cube_color_tx (the faces in a 3 x 2
 *          atlas: axis distance, colour pyramid).
 * Outputs: capture_hit_img = (radiance, share of the ray the captures resolve), the planar
 *                            capture's with what is left of the ray added (a surface's, or
 *                            the world's where the ray escapes past everything it shows),
 *          ray_outcome_img = (hit distance, 0, 0, RAY_OUTCOME_CUBE where the cube resolved most
 *                            of the ray, the outcome before elsewhere). */

#define CUBE_REFINE_STEPS 6
/* A refined point this many of the cube's texels from the surface it shows is on it. */
#define CUBE_HIT_TEXELS 1.5
/* The first step's length, in pixel footprints at the ray's origin: clear of its own surface. */
#define CUBE_FIRST_STEP_PX 2.0

int cube_face(vec3 direction)
{
  vec3 size = abs(direction);
  int axis = (size.x >= size.y && size.x >= size.z) ? 0 : (size.y >= size.z ? 1 : 2);
  return 2 * axis + (direction[axis] < 0.0 ? 1 : 0);
}

/* How far POINT lies behind what the cube shows in its direction (< 0: in front), and the
 * atlas position (pixels) it falls on. */
float cube_behind(vec3 point, out vec2 atlas_px)
{
  int face = cube_face(point - params.cube_centre.xyz);
  vec3 view = (params.cube_world_to_face[face] * vec4(point, 1.0)).xyz;
  float axis_distance = -view.z;
  float side = params.cube_centre.w;
  vec2 uv = clamp(view.xy / axis_distance * 0.5 + 0.5, vec2(0.5 / side), vec2(1.0 - 0.5 / side));
  atlas_px = (vec2(face % 3, face / 3) + uv) * side;
  return axis_distance - texelFetch(cube_depth_tx, ivec2(atlas_px), 0).r;
}

/* The t of the first surface the ray ORIGIN + t DIRECTION meets in the cube, or -1; ESCAPES
 * where it meets none and ends in view of the centre past everything the cube shows. */
float march_cube(vec3 origin, vec3 direction, float first_step, out vec2 hit_px, out bool escapes)
{
  hit_px = vec2(0.0);
  escapes = false;
  /* Nothing the cube shows lies farther than cube_reach from its centre. */
  float reach = distance(origin, params.cube_centre.xyz) + params.cube_reach;
  float t_max = min(params.max_distance, reach);
  int steps = params.cube_steps;
  float t_front = 0.0;
  vec2 atlas_px;
  bool in_front = cube_behind(origin + direction * first_step, atlas_px) < 0.0;
  for (int i = 1; i <= steps; i++) {
    /* Steps grow linearly, fine near the origin where hits are close: a step that overshoots a
     * surface can land where the cube shows something farther (behind a wall's top, the
     * ceiling), and the surface is missed. */
    float t = first_step + (t_max - first_step) * pow(float(i) / float(steps), 2.0);
    float behind = cube_behind(origin + direction * t, atlas_px);
    if (behind < 0.0) {
      in_front = true;
      t_front = t;
      continue;
    }
    if (!in_front) {
      continue; /* the origin itself is hidden from the centre: wait until the ray comes into view */
    }
    /* Bracketed between t_front (in front) and t (behind): refine with the secant. */
    float t_a = t_front, t_b = t;
    float f_a = cube_behind(origin + direction * t_a, atlas_px), f_b = behind;
    for (int j = 0; j < CUBE_REFINE_STEPS; j++) {
      float t_mid = clamp(t_a - f_a * (t_b - t_a) / (f_b - f_a), t_a, t_b);
      float f_mid = cube_behind(origin + direction * t_mid, atlas_px);
      if (f_mid < 0.0) {
        t_a = t_mid;
        f_a = f_mid;
      }
      else {
        t_b = t_mid;
        f_b = f_mid;
      }
    }
    /* The cube's depths are exact to a texel: no thickness is assumed behind them. */
    float t_hit = clamp(t_a - f_a * (t_b - t_a) / (f_b - f_a), t_a, t_b);
    float f_hit = cube_behind(origin + direction * t_hit, hit_px);
    float texel = 2.0 * distance(origin + direction * t_hit, params.cube_centre.xyz) / params.cube_centre.w;
    if (abs(f_hit) <= CUBE_HIT_TEXELS * texel) {
      return t_hit;
    }
    in_front = false; /* behind a silhouette seen from the centre: go on until the ray reappears */
  }
  escapes = in_front && t_max == reach;
  return -1.0;
}

/* The atlas pixel where the cube shows the world in DIRECTION (world space), or vec2(-1) where
 * it shows a surface there. */
vec2 world_shown_at(vec3 direction)
{
  int face = cube_face(direction);
  vec3 view = mat3(params.cube_world_to_face[face]) * direction;
  float side = params.cube_centre.w;
  vec2 uv = clamp(view.xy / -view.z * 0.5 + 0.5, vec2(0.5 / side), vec2(1.0 - 0.5 / side));
  vec2 atlas_px = (vec2(face % 3, face / 3) + uv) * side;
  return is_background(texelFetch(cube_depth_tx, ivec2(atlas_px), 0).r) ? atlas_px : vec2(-1.0);
}

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  vec4 captured = (params.capture_levels & CAPTURE_LEVEL_PLANAR) != 0 ? texelFetch(planar_hit_tx, texel, 0) :
                                                                         vec4(0.0);
  vec4 outcome = texelFetch(ray_outcome_tx, texel, 0);
  capture_hit_img = captured;
  ray_outcome_img = outcome;
  vec4 hit = texelFetch(ray_hit_tx, texel, 0);
  float rest = 1.0 - captured.a - hit.w;
  if (!(hit.z > 0.0) || outcome.w == float(RAY_OUTCOME_NONE) || rest <= 0.0) {
    return; /* no ray, or nothing of it left to resolve */
  }
  ivec2 pixel = ray_origin_pixel(texel);
  float depth = texelFetch(depth_tx, pixel, 0).r;
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  vec3 origin = (params.view_to_world * vec4(view_position(uv, depth), 1.0)).xyz;
  vec3 view_ray = texelFetch(ray_dir_tx, texel, 0).xyz;
  vec3 direction = mat3(params.view_to_world) * view_ray;
  vec2 hit_px;
  bool escapes;
  float t = march_cube(origin, direction, CUBE_FIRST_STEP_PX * pixel_footprint(depth), hit_px, escapes);
  /* A ray past everything the cube shows that runs on over the world there reads the world in
   * its direction, nearer to a path trace's than EEVEE's probe (planar_trace.glsl says more). */
  bool world = t < 0.0 && escapes && params.probe_reflection != 0;
  if (world) {
    hit_px = world_shown_at(direction);
    world = hit_px.x >= 0.0;
  }
  if (t < 0.0 && !world) {
    return;
  }
  /* The world lies infinitely far: its cone covers as many texels as at one unit from the centre. */
  float hit_distance = world ? 1.0 : t;
  float centre_distance = world ? 1.0 : distance(origin + direction * t, params.cube_centre.xyz);
  vec3 world_normal = texelFetch(normal_tx, pixel, 0).xyz;
  float roughness = texelFetch(roughness_tx, pixel, 0).r;
  float rays_averaged = float(params.resolve_samples) * accumulated_iterations(pixel);
  float solid_angle = ray_solid_angle(hit.z, rays_averaged, dot(view_normal(world_normal), -view_incident(uv)),
                                      ggx_alpha(roughness));
  float level = 0.0;
  if (params.use_cone_filter != 0 && params.use_importance_sampling != 0) {
    level = cone_level(hit_distance, solid_angle, 2.0 * centre_distance / params.cube_centre.w,
                       params.cube_color_levels);
  }
  int lower = int(floor(level));
  int upper = min(lower + 1, params.cube_color_levels - 1);
  vec2 atlas_uv = hit_px / (vec2(3.0, 2.0) * params.cube_centre.w);
  vec3 radiance = pyramid_sample(cube_color_tx, params.cube_color_level[lower], params.cube_color_level[upper],
                                 level, atlas_uv);
  float share = captured.a + rest;
  capture_hit_img = vec4((captured.rgb * captured.a + radiance * rest) / share, share);
  if (rest >= 0.5) {
    ray_outcome_img = vec4(world ? params.max_distance : t, 0.0, 0.0, float(RAY_OUTCOME_CUBE));
  }
}
