/* One Hi-Z ray's walk through the min-depth pyramid, recorded for the deck's
 * "Hierarchical ray trace" (Hi-Z) slides: start at level 0, climb a level each
 * time the ray passes in front of a whole cell, descend where it may intersect,
 * stop at the hit. The march is hiz_march_lib.glsl's own march_hiz, the ray
 * trace.glsl's mirror ray (surface_ray_lib.glsl); hiz_walk_lib.glsl records it.
 *
 * Inputs:  depth_tx (view depth), normal_tx (world normal), hiz_tx (min-depth atlas),
 *          walk_pixel (push constant: the ray's pixel, x right, y up).
 * Drawn into an N x 1 target: fragment x = i replays the march and keeps visit i,
 *   walk_img      = (level, cell x, cell y, HIZ_VISIT_* outcome)
 *   walk_span_img = (t entering the cell, t leaving it, ray depth at both)
 *   walk_ray_img  = (the cell's min depth, 0, 0, 0)
 * and every fragment past the last visit (the sentinel) writes
 *   walk_img      = (-1, hit pixel x, hit pixel y, WALK_END_*)  (pixel -1 on a miss)
 *   walk_span_img = (hit t or -1, ray depth at the hit, iterations, highest level)
 *   walk_ray_img  = (ray start in pixels xy, its screen delta up to t = 1 xy).
 * No ray from the pixel (see reflecting_surface): every fragment writes the sentinel
 * with WALK_END_NO_RAY and nothing else. */

void main()
{
  walk_index = int(gl_FragCoord.x);
  walk_outcome = 0;
  walk_img = vec4(-1.0, -1.0, -1.0, WALK_END_NO_RAY);
  walk_span_img = vec4(-1.0, 0.0, 0.0, 0.0);
  walk_ray_img = vec4(0.0);

  vec3 origin, incident, normal;
  if (!reflecting_surface(walk_pixel, origin, incident, normal)) {
    return;
  }
  vec3 direction = reflect(incident, normal);
  if (dot(direction, normal) <= 0.0) {
    return;
  }
  ScreenRay ray = project_ray(origin, direction);
  float iterations, highest_level;
  float t = march_hiz(ray, iterations, highest_level);
  if (walk_index < int(iterations)) {
    walk_img = vec4(float(walk_level), walk_cell, float(walk_outcome));
    walk_span_img = vec4(walk_t, walk_t_next, ray_depth_at(ray, walk_t), ray_depth_at(ray, walk_t_next));
    walk_ray_img = vec4(hiz_min_depth(walk_level, walk_cell), 0.0, 0.0, 0.0);
    return;
  }
  bool hit = t >= 0.0;
  walk_img = vec4(-1.0, hit ? vec2(texel_at(ray_position_px(ray, t))) : vec2(-1.0),
                  hit ? WALK_END_HIT : WALK_END_MISS);
  walk_span_img = vec4(t, hit ? ray_depth_at(ray, t) : 0.0, iterations, highest_level);
  walk_ray_img = vec4(ray.start_px, ray.delta_px);
}
