/* Cheap rays: linear raymarch against the depth buffer ("Linear Raymarch" slide).
 *
 * The ray is clipped to the screen and marched in equal screen-space steps of
 * at least `trace_stride` pixels along its major axis. A step hits when the
 * depth span the ray covers in it overlaps the surface and the `thickness`
 * assumed behind it (a per-step "behind by less than thickness" test misses
 * surfaces where the ray's depth changes fast); a binary search between the
 * last two steps refines the hit. tests/oracles.py mirrors this step for step. */

/* Returns the hit t, or -1 for a miss; `steps` counts depth tests. */
float march_linear(ScreenRay ray, out float steps_taken)
{
  steps_taken = 0.0;
  float t_exit = screen_exit(ray);
  float major_px = max(abs(ray.delta_px.x), abs(ray.delta_px.y)) * t_exit;
  float steps = min(float(params.trace_steps), ceil(major_px / params.trace_stride));
  if (steps < 1.0) {
    return -1.0;
  }
  float dt = t_exit / steps;
  float thickness = params.thickness;
  float ray_front = ray_depth_at(ray, 0.0);
  for (int i = 1; i <= int(steps); i++) {
    float t = dt * float(i);
    float ray_back = ray_depth_at(ray, t);
    float surface = scene_depth_at(ray, t);
    steps_taken += 1.0;
    /* The sky is infinitely far: nothing is ever behind it. */
    bool hit = ray_back > surface && ray_front < surface + thickness && !is_background(surface);
    ray_front = ray_back;
    if (hit) {
      float t_front = t - dt, t_behind = t;
      for (int j = 0; j < params.refine_steps; j++) {
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
