/* Recorder of one Hi-Z march for hiz_walk.glsl: defines hiz_march_lib.glsl's
 * HIZ_WALK_VISIT hook (so it comes before that file) to keep the visit numbered
 * walk_index + 1. Each fragment of the walk replays the same march and keeps one visit. */

int walk_index;        /* the visit this fragment keeps, counted from 0 (its x) */
int walk_level;
vec2 walk_cell;        /* the level's texel, x right, y up */
float walk_t, walk_t_next;
int walk_outcome;      /* HIZ_VISIT_*; 0: no such visit */

void walk_record(float iteration, int level, vec2 cell, float t, float t_next, int outcome)
{
  if (int(iteration) == walk_index + 1) {
    walk_level = level;
    walk_cell = cell;
    walk_t = t;
    walk_t_next = t_next;
    walk_outcome = outcome;
  }
}

#define HIZ_WALK_VISIT(iteration, level, cell, t, t_next, outcome) \
  walk_record(iteration, level, cell, t, t_next, outcome)
