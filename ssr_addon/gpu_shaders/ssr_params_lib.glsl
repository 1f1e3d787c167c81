/* Parameters shared by every pass, one std140 uniform block (`params`).
 * Only mat4 and vec4 members, so the Python side packs it without padding rules. */
struct SSRParams {
  mat4 view_to_clip;   /* camera projection */
  mat4 clip_to_view;   /* its inverse */
  mat4 world_to_view;  /* camera view matrix: world-space normals into view space */
  vec4 viewport;       /* traced target: width, height, 1/width, 1/height */
  vec4 clip;           /* clip_start, clip_end (depth at or past it is background), 0, 0 */
  vec4 march;          /* thickness, max_distance, trace_stride (px), trace_steps */
  vec4 shaping;        /* refine_steps, border_fade, camera_facing_fade, max_roughness */
};
