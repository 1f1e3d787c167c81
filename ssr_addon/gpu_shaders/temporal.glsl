/* Temporal filter ("Temporal Reprojection" slides): blend this frame's
 * reflections with the history, found by reprojecting the ray's hit point
 * (the reflection's virtual image behind the surface) rather than the
 * reflecting surface, so reflections do not smear under camera motion:
 *   x_prev = P_{t-1} V_{t-1} x_world.
 *
 * Inputs:  reflection_tx, reflection_hit_tx (this frame's resolve, premultiplied), depth_tx,
 *          motion_tx (Vector pass: pixels to the previous frame),
 *          history_tx (last frame's output: premultiplied radiance, confidence),
 *          history_count_tx (frames accumulated in it).
 * Outputs: filtered_img (premultiplied radiance, confidence), count_img (frames accumulated, 0, 0, 0).
 *
 * History is clamped to the range of this frame's 3x3 neighbourhood, which
 * rejects stale history (disocclusion, moving objects) at the cost of some
 * noise; a still's iterations share one camera and scene, so theirs is not. Each pixel averages up to params.temporal.x frames: 1 / (1 - temporal_weight)
 * in an animation, all the iterations of an accumulated still. */

/* Where a view-space point of this frame was on screen in the previous frame (uv), or -1. */
vec2 previous_screen_position(vec3 view_point)
{
  vec4 previous_clip = params.previous_world_to_clip * (params.view_to_world * vec4(view_point, 1.0));
  return previous_clip.w > 0.0 ? previous_clip.xy / previous_clip.w * 0.5 + 0.5 : vec2(-1.0);
}

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
  vec2 previous_uv;
  vec4 hit = texelFetch(reflection_hit_tx, pixel, 0);
  if (params.temporal.z >= 2.0) {
    previous_uv = uv; /* a still's earlier iteration: same camera, same instant */
  }
  else if (params.temporal.y > 0.0 && hit.x > 0.0) {
    /* The virtual image: as far behind the surface, along the camera ray, as the hit is in
     * front of it, moved by the camera... */
    vec3 virtual_point = view_position(uv, depth) + view_incident(uv) * hit.x;
    previous_uv = previous_screen_position(virtual_point);
    /* ...and by what the hit object itself did: the Vector pass at the hit, less the
     * camera's share of it. Exact for motion parallel to the mirror, an approximation
     * otherwise; the neighbourhood clamp catches the rest. */
    float hit_depth = texelFetch(depth_tx, texel_at(hit.yz * params.viewport.xy), 0).r;
    vec2 camera_flow = previous_screen_position(view_position(hit.yz, hit_depth)) - hit.yz;
    vec2 hit_flow = texelFetch(motion_tx, texel_at(hit.yz * params.viewport.xy), 0).xy * params.viewport.zw;
    previous_uv += hit_flow - camera_flow;
  }
  else {
    /* The reflecting surface, camera and object motion both: the Vector pass itself. */
    previous_uv = uv + texelFetch(motion_tx, pixel, 0).xy * params.viewport.zw;
  }
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
