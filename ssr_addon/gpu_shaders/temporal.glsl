/* Temporal filter ("Temporal Reprojection" slides): blend this frame's
 * reflections with the history, found by reprojecting the ray's hit point
 * (the reflection's virtual image behind the surface) rather than the
 * reflecting surface, so reflections do not smear under camera motion:
 *   x_prev = P_{t-1} V_{t-1} x_world.
 *
 * Inputs:  reflection_tx, reflection_hit_tx (this frame's resolve, premultiplied), depth_tx,
 *          history_tx (last frame's output: premultiplied radiance, confidence),
 *          history_count_tx (frames accumulated in it).
 * Outputs: filtered_img (premultiplied radiance, confidence), count_img (frames accumulated, 0, 0, 0).
 *
 * History is clamped to the range of this frame's 3x3 neighbourhood, which
 * rejects stale history (disocclusion, moving objects) at the cost of some
 * noise; a still's iterations share one camera and scene, so theirs is not. Each pixel averages up to params.temporal.x frames: 1 / (1 - temporal_weight)
 * in an animation, all the iterations of an accumulated still. */

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  vec4 current = texelFetch(reflection_tx, pixel, 0);
  filtered_img = current;
  count_img = vec4(1.0, 0.0, 0.0, 0.0);
  float depth = texelFetch(depth_tx, pixel, 0).r;
  if (params.temporal.z <= 0.0 || is_background(depth)) {
    return;
  }
  vec2 uv = (vec2(pixel) + 0.5) * params.viewport.zw;
  vec3 surface = view_position(uv, depth);
  vec3 point = surface;
  float hit_distance = texelFetch(reflection_hit_tx, pixel, 0).x;
  if (params.temporal.y > 0.0 && hit_distance > 0.0) {
    /* The virtual image: as far behind the surface, along the camera ray, as the hit is in front. */
    point = surface + view_incident(uv) * hit_distance;
  }
  vec4 previous_clip = params.previous_world_to_clip * (params.view_to_world * vec4(point, 1.0));
  if (previous_clip.w <= 0.0) {
    return;
  }
  vec2 previous_uv = previous_clip.xy / previous_clip.w * 0.5 + 0.5;
  if (any(lessThan(previous_uv, vec2(0.0))) || any(greaterThan(previous_uv, vec2(1.0)))) {
    return; /* off screen last frame: no history */
  }
  vec4 history = textureLod(history_tx, previous_uv, 0.0);
  if (params.temporal.z < 2.0) {
    vec4 low = current, high = current;
    for (int y = -1; y <= 1; y++) {
      for (int x = -1; x <= 1; x++) {
        ivec2 neighbour = clamp(pixel + ivec2(x, y), ivec2(0), ivec2(params.viewport.xy) - 1);
        vec4 value = texelFetch(reflection_tx, neighbour, 0);
        low = min(low, value);
        high = max(high, value);
      }
    }
    history = clamp(history, low, high);
  }
  float history_count = textureLod(history_count_tx, previous_uv, 0.0).x;
  float count = min(history_count + 1.0, params.temporal.x);
  filtered_img = mix(history, current, 1.0 / count);
  count_img = vec4(count, 0.0, 0.0, 0.0);
}
