/* Where a reflection ray starts: a pixel's surface seen from the camera (trace.glsl's
 * ray set-up, shared with hiz_walk.glsl).
 *
 * Reads depth_tx (view depth) and normal_tx (world normal). False where the pixel
 * gives no ray: the world, an unfilled pixel, or a shading normal facing away from
 * the camera. Else origin (view position), incident (unit view direction towards the
 * surface) and normal (unit view normal). */
bool reflecting_surface(ivec2 pixel, out vec3 origin, out vec3 incident, out vec3 normal)
{
  origin = incident = normal = vec3(0.0);
  float depth = texelFetch(depth_tx, pixel, 0).r;
  if (is_background(depth)) {
    return false;
  }
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  origin = view_position(uv, depth);
  incident = view_incident(uv);
  vec3 world_normal = texelFetch(normal_tx, pixel, 0).xyz;
  if (!(dot(world_normal, world_normal) > 0.25)) {
    return false; /* no surface here (the world, or an unfilled pixel) */
  }
  normal = view_normal(world_normal);
  return dot(normal, -incident) > 0.0;
}
