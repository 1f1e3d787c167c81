/* Expensive rays: hierarchical tracing through the min-depth pyramid
 * ("Hierarchical ray trace" slides: start at the first mip level, climb while
 * the ray passes in front of a whole cell, descend where it may intersect).
 *
 * Cells are squares of 2^level full-resolution pixels. A cell is skipped only
 * when the ray, over its whole extent in the cell, lies in front of the
 * nearest depth in it (the pyramid holds minima, so nothing in the cell can be
 * hit): the tracer therefore finds the first pixel a fine pixel-by-pixel walk
 * would find, thin geometry included. At level 0 a pixel is hit when the
 * ray's depth span in it overlaps [depth, depth + thickness], as in the
 * linear march; the sky is never hit. tests/oracles.py walks every pixel to
 * check this. */

/* What a cell visit did, for the recording hook below (HIZ_VISIT_*, uniforms.HIZ_VISITS):
 * SKIP: in front of the whole cell, skipped, one level up (at most the top);
 * DESCEND: may intersect (level > 0), one level down;
 * BEHIND: level 0, the ray passes behind the pixel's surface;
 * HIT: level 0, hit, the march ends. */

/* Recording hook: HIZ_WALK_VISIT(iteration, level, cell, t, t_next, outcome) runs once per
 * cell visit (iteration counts from 1, as `iterations`; cell is the level's texel, t to
 * t_next the ray's span in it before the visit moves on). Empty, so free, unless a pass
 * defines it before this file (hiz_walk_lib.glsl, for the deck's diagram). */
#ifndef HIZ_WALK_VISIT
#  define HIZ_WALK_VISIT(iteration, level, cell, t, t_next, outcome)
#endif

/* The t at which the ray leaves the cell of `size` pixels containing `cell`. */
float cell_exit(ScreenRay ray, vec2 cell, float size)
{
  float t_cell = 1e30;
  for (int axis = 0; axis < 2; axis++) {
    float delta = ray.delta_px[axis];
    if (delta != 0.0) {
      float boundary = (cell[axis] + (delta > 0.0 ? 1.0 : 0.0)) * size;
      t_cell = min(t_cell, (boundary - ray.start_px[axis]) / delta);
    }
  }
  return t_cell;
}

float hiz_min_depth(int level, vec2 cell)
{
  return atlas_fetch(hiz_tx, params.hiz_level[level], ivec2(cell)).r;
}

/* Returns the hit t, or -1 for a miss; `iterations` counts cell visits,
 * `highest_level` is the coarsest level the ray climbed to. */
float march_hiz(ScreenRay ray, out float iterations, out float highest_level)
{
  float t_exit = screen_exit(ray);
  float major_px = max(abs(ray.delta_px.x), abs(ray.delta_px.y));
  /* A nudge of 1/256 pixel moves a position on a cell boundary into the next cell. */
  float t_nudge = major_px > 0.0 ? (1.0 / 256.0) / major_px : 1.0;
  int top_level = params.hiz_levels - 1;
  float thickness = params.thickness;
  int level = 0;
  /* Leave the origin pixel first: a surface does not reflect itself. */
  float t = cell_exit(ray, floor(ray.start_px), 1.0) + t_nudge;
  iterations = 0.0;
  highest_level = 0.0;
  while (t < t_exit && iterations < float(params.hiz_max_iterations)) {
    iterations += 1.0;
    float size = exp2(float(level));
    vec2 cell = floor(ray_position_px(ray, t) / size);
    float t_next = min(cell_exit(ray, cell, size), t_exit);
    float depth_in = ray_depth_at(ray, t), depth_out = ray_depth_at(ray, t_next);
    float nearest = hiz_min_depth(level, cell);
    if (max(depth_in, depth_out) < nearest) {
      /* Entirely in front of everything in the cell: skip it and climb. */
      HIZ_WALK_VISIT(iterations, level, cell, t, t_next, HIZ_VISIT_SKIP);
      t = t_next + t_nudge;
      level = min(level + 1, top_level);
      highest_level = max(highest_level, float(level));
    }
    else if (level == 0) {
      if (min(depth_in, depth_out) < nearest + thickness && !is_background(nearest)) {
        /* Hit: where the ray crosses the surface depth inside this pixel. */
        float t_surface = depth_out > depth_in ? ray_t_at_depth(ray, nearest) : t;
        HIZ_WALK_VISIT(iterations, level, cell, t, t_next, HIZ_VISIT_HIT);
        return clamp(t_surface, t, t_next);
      }
      HIZ_WALK_VISIT(iterations, level, cell, t, t_next, HIZ_VISIT_BEHIND);
      t = t_next + t_nudge; /* passes behind this pixel's surface */
    }
    else {
      /* May intersect: jump to where the ray reaches the cell's nearest depth
       * (nothing before it can be hit), then look at the finer level. */
      HIZ_WALK_VISIT(iterations, level, cell, t, t_next, HIZ_VISIT_DESCEND);
      if (depth_out > depth_in && depth_in < nearest) {
        t = min(max(t, ray_t_at_depth(ray, nearest)), t_next);
      }
      level -= 1;
    }
  }
  return -1.0;
}
