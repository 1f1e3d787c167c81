/* Parameters shared by every pass, one std140 uniform block (`params`).
 * Only mat4 and vec4 members, so the Python side (shaders.pack_params) packs it
 * without padding rules. */
#define MAX_PYRAMID_LEVELS 16

struct SSRParams {
  mat4 view_to_clip;            /* camera projection */
  mat4 clip_to_view;            /* its inverse */
  mat4 world_to_view;           /* camera view matrix */
  mat4 view_to_world;           /* its inverse */
  mat4 previous_world_to_clip;  /* last frame's view-projection, for temporal reprojection */
  vec4 viewport;       /* full resolution: width, height, 1/width, 1/height */
  vec4 trace_viewport; /* traced rays: width, height, pixels per ray along each axis (1 or 2), 0 */
  vec4 clip;           /* clip_start, clip_end (depth at or past it is background), 0, 0 */
  vec4 frame;          /* frame index (Halton), expensive-ray roughness, its tie fraction, Hi-Z levels */
  vec4 march;          /* thickness, max_distance, trace_stride (px), trace_steps */
  vec4 shaping;        /* refine_steps, border_fade, camera_facing_fade, max_roughness */
  vec4 stages;         /* use_importance_sampling, resolve_samples, use_cone_filter, hiz_max_iterations */
  vec4 temporal;       /* most frames averaged, reproject the hit (1) or the surface (0),
                        * history (0 none, 1 clamped to this frame, 2 a still's own: unclamped), colour levels */
  vec4 hiz_level[MAX_PYRAMID_LEVELS];   /* min-depth pyramid atlas: x, y offset, width, height */
  vec4 color_level[MAX_PYRAMID_LEVELS]; /* colour pyramid atlas, likewise */
};
