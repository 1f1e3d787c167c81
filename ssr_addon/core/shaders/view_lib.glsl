/* View-space reconstruction from a depth pass, shared by every pass that has a camera
 * (common_lib.glsl's, through params, and the lamp split's, through lamp_block). The depth
 * pass holds distance along the view axis (positive), so a view-space position is the point
 * on the pixel's camera ray at z = -depth; this works for perspective and orthographic
 * cameras alike. */

/* The camera ray through a screen position (uv in [0,1]^2) of a camera whose inverse
 * projection is CLIP_TO_VIEW: its near-plane point and direction. */
void camera_ray_of(mat4 clip_to_view, vec2 uv, out vec3 ray_origin, out vec3 ray_direction)
{
  vec2 ndc = uv * 2.0 - 1.0;
  vec4 near_point = clip_to_view * vec4(ndc, -1.0, 1.0);
  vec4 far_point = clip_to_view * vec4(ndc, 1.0, 1.0);
  ray_origin = near_point.xyz / near_point.w;
  ray_direction = far_point.xyz / far_point.w - ray_origin;
}

/* The point of a camera ray at view depth DEPTH. */
vec3 ray_point_at_depth(vec3 ray_origin, vec3 ray_direction, float depth)
{
  return ray_origin + ray_direction * ((-depth - ray_origin.z) / ray_direction.z);
}

/* The screen position (uv in [0,1]^2 where on screen) of a clip-space point, or vec2(-1) where it
 * lies behind the camera (or is not a number). */
vec2 clip_to_uv(vec4 clip)
{
  return clip.w > 0.0 ? clip.xy / clip.w * 0.5 + 0.5 : vec2(-1.0);
}
