/* Helpers shared by the passes: view-space reconstruction from the depth pass.
 * The depth pass holds distance along the view axis (positive), so a view-space
 * position is the point on the pixel's camera ray at z = -depth; this works for
 * perspective and orthographic cameras alike. */

/* The texel under a screen position in pixels, kept inside the traced target. */
ivec2 texel_at(vec2 position_px)
{
  return clamp(ivec2(position_px), ivec2(0), ivec2(params.viewport.xy) - 1);
}

bool is_background(float depth)
{
  return depth >= params.clip.y;
}

/* Camera ray through a screen position (uv in [0,1]^2): near-plane point and direction. */
void camera_ray(vec2 uv, out vec3 ray_origin, out vec3 ray_direction)
{
  vec2 ndc = uv * 2.0 - 1.0;
  vec4 near_point = params.clip_to_view * vec4(ndc, -1.0, 1.0);
  vec4 far_point = params.clip_to_view * vec4(ndc, 1.0, 1.0);
  ray_origin = near_point.xyz / near_point.w;
  ray_direction = far_point.xyz / far_point.w - ray_origin;
}

vec3 view_position(vec2 uv, float depth)
{
  vec3 origin, direction;
  camera_ray(uv, origin, direction);
  return origin + direction * ((-depth - origin.z) / direction.z);
}

vec3 view_incident(vec2 uv)
{
  vec3 origin, direction;
  camera_ray(uv, origin, direction);
  return normalize(direction);
}

vec3 view_normal(vec3 world_normal)
{
  return normalize(mat3(params.world_to_view) * world_normal);
}
