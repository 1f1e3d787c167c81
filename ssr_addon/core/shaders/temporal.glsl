/* Temporal filter ("Temporal Reprojection" slides): blend this frame's
 * reflections with the history, found by reprojecting the ray's hit point
 * (the reflection's virtual image behind the surface) rather than the
 * reflecting surface, so reflections do not smear under camera motion:
 *   x_prev = P_{t-1} V_{t-1} x_world.
 *
 * Inputs:  spatial_tx (this frame's, spatially filtered, premultiplied), reflection_hit_tx
 *          (mean hit distance and uv, the captures' share), depth_tx, normal_tx, roughness_tx, motion_tx (Vector pass: pixels to the previous frame),
 *          radiance_tx and previous_radiance_tx (the lit scene now and in the history's frame),
 *          history_tx (last output: premultiplied radiance, confidence), history_record_tx (its record),
 *          history_moments_tx (its moments).
 * Outputs: reflection_img (premultiplied radiance, confidence),
 *          history_record_img (frames accumulated; where the history was read, in pixels;
 *                     motion seen: the larger Vector-pass length at the pixel and at its hit),
 *          history_moments_img (the mean over the history of each iteration's squared luminance;
 *                     the last iteration's virtual image of its hit, in world space).
 *
 * Where the camera did not move a pixel (its history lies exactly where it is)
 * but the light at its hit is not what it was (an animated lamp or material,
 * which the Vector pass does not show), the history is stale: the pixel starts
 * afresh, and its frame converges like a still. A pixel holds still when the
 * camera did not move it and the Vector pass shows no motion at it or at its
 * hit, now or in the history (which records the motion it saw). Such a
 * pixel's history is still right: it keeps averaging, unclipped, like a
 * still's iterations, so a still shot converges to what a long still shows
 * and then holds steady. Anything else in an
 * animation (HISTORY_MODE_ANIMATION) clips the history to this frame's 3x3
 * neighbourhood, mean +- 1.25 standard deviations (Salvi's variance
 * clipping), which rejects stale history (disocclusion, moving objects), and
 * averages at most history_frames = 1 / (1 - temporal_weight). The box is
 * one iteration's: a few heavy-tailed rays, whose mean falls below the truth
 * more often than above it, so it clips good history down (a camera moving
 * over an unchanged street came out darker than no history at all). Where the
 * history saw the same reflected point (the virtual image it recorded within
 * SAME_REFLECTION_PX pixel footprints of this pixel's), its upper side
 * reaches at least the history's own noise, the spread of one iteration's
 * luminance over the frames it holds; elsewhere (another surface, a
 * disocclusion, a moving reflection) the box is as tight as before. Recording the
 * motion in the history catches what a still pixel cannot show by itself: the
 * floor a moving ball uncovers, the reflection of the place the ball left. A
 * still's own iterations (HISTORY_MODE_STILL) share one camera and scene. A view
 * moved over a still scene (HISTORY_MODE_VIEW: the live view while the artist
 * navigates) has no stale light, but what screen space shows changes as the view
 * moves: content sweeps over the screen's edge and behind what is in front, and a
 * lagging history kept that (an orbit at 1 degree a view, unclipped, came out
 * worse than no history on the wet street's last views). Where the surface and its
 * hit moved by under a pixel (VIEW_STEADY_PX) and the last view saw both, that
 * change is under a pixel too: on a flat reflector, where hit-point reprojection is
 * exact, rougher than a mirror (MIRROR_ROUGHNESS), the history keeps averaging
 * unclipped, so a slowly moving view settles instead of boiling with one
 * iteration's noise. Elsewhere it is clipped as an animation's: a mirror's one
 * iteration is near converged, and the clip keeps its reflection sharp where an
 * unclipped history blurs with each bilinear reprojection (rolling_ball's floor
 * came out brighter than no history); a ball's reflection smeared unclipped.
 * Non-finite history or input is dropped, never blended. */

#define VARIANCE_CLIP_GAMMA 1.25
/* Surfaces at most this rough are near converged after one iteration: their reflection is
 * sharp enough that each bilinear reprojection of an unclipped history blurs it. */
#define MIRROR_ROUGHNESS 0.1
/* Hit-point reprojection reads the history within half a pixel of a planar mirror's image
 * (test_frame_sequence); a virtual image a footprint away is another reflected point. */
#define SAME_REFLECTION_PX 1.0
/* Largest change of the light at a hit between frames that still counts as the same light:
 * EEVEE renders an unchanged scene the same every frame, Cycles with its seed animated does not. */
#define RADIANCE_TOLERANCE 0.05
/* A view moved over a still scene by less than this here (camera_motion marks what the last view
 * did not see with a motion far larger): what the screen shows changed by less than a pixel. */
#define VIEW_STEADY_PX 1.0
/* Neighbouring normals at least this close (cosine; 1.8 degrees) make a flat reflector. */
#define FLAT_COSINE 0.9995

/* Where a view-space point of this frame was on screen in the previous frame (uv), or -1. */
vec2 previous_screen_position(vec3 view_point)
{
  return clip_to_uv(params.previous_world_to_clip * (params.view_to_world * vec4(view_point, 1.0)));
}

/* HIT: the resolve's (mean hit distance, mean hit uv) of this pixel. */
vec2 reprojected_uv(ivec2 pixel, vec2 uv, float depth, vec4 hit)
{
  if (params.history_mode == HISTORY_MODE_STILL) {
    return uv; /* a still's earlier iteration: same camera, same instant */
  }
  if (params.reproject_hit != 0 && hit.x > 0.0) {
    /* The virtual image: as far behind the surface, along the camera ray, as the hit is in
     * front of it, moved by the camera... */
    vec3 virtual_point = view_position(uv, depth) + view_incident(uv) * hit.x;
    vec2 previous_uv = previous_screen_position(virtual_point);
    /* ...and by what the hit object itself did: the Vector pass at the hit, less the
     * camera's share of it. Exact for motion parallel to the mirror, an approximation
     * otherwise; the variance clip catches the rest. */
    ivec2 hit_texel = texel_at(hit.yz * params.viewport_size);
    float hit_depth = texelFetch(depth_tx, hit_texel, 0).r;
    vec2 camera_flow = previous_screen_position(view_position(hit.yz, hit_depth)) - hit.yz;
    vec2 hit_flow = texelFetch(motion_tx, hit_texel, 0).xy * params.pixel_size;
    return previous_uv + hit_flow - camera_flow;
  }
  /* The reflecting surface, camera and object motion both: the Vector pass itself. */
  return uv + texelFetch(motion_tx, pixel, 0).xy * params.pixel_size;
}

float luminance(vec3 color)
{
  return dot(color, vec3(0.2126, 0.7152, 0.0722)); /* Rec. 709 */
}

/* HISTORY clipped to this iteration's neighbourhood, the box's upper side at least
 * HISTORY_NOISE (0: the plain box). */
vec4 variance_clip(ivec2 pixel, vec4 history, float history_noise)
{
  vec4 mean = vec4(0.0), square = vec4(0.0);
  for (int y = -1; y <= 1; y++) {
    for (int x = -1; x <= 1; x++) {
      ivec2 neighbour = clamp(pixel + ivec2(x, y), ivec2(0), ivec2(params.viewport_size) - 1);
      vec4 value = texelFetch(spatial_tx, neighbour, 0);
      value = is_finite(value) ? value : vec4(0.0);
      mean += value;
      square += value * value;
    }
  }
  mean /= 9.0;
  vec4 deviation = sqrt(max(square / 9.0 - mean * mean, 0.0));
  vec4 lower = mean - VARIANCE_CLIP_GAMMA * deviation;
  vec4 upper = mean + VARIANCE_CLIP_GAMMA * deviation;
  if (!(history_noise > 0.0)) {
    return clamp(history, lower, upper);
  }
  upper.rgb = mean.rgb + VARIANCE_CLIP_GAMMA * max(deviation.rgb, vec3(history_noise));
  /* The radiance is premultiplied: it follows its clipped confidence first, so the wider box
   * never lets more light through per unit of confidence than the history had. */
  float confidence = clamp(history.a, lower.a, upper.a);
  vec3 radiance = history.a > 0.0 ? history.rgb * (confidence / history.a) : history.rgb;
  return vec4(clamp(radiance, lower.rgb, upper.rgb), confidence);
}

/* The reflector is flat around PIXEL (its four neighbours' normals agree with its own), where
 * hit-point reprojection is exact: a planar mirror's virtual image. On a curved one (a ball) it
 * is an approximation that only the clip corrects. */
bool flat_reflector(ivec2 pixel)
{
  vec3 normal = texelFetch(normal_tx, pixel, 0).xyz;
  const ivec2 offsets[4] = ivec2[4](ivec2(1, 0), ivec2(-1, 0), ivec2(0, 1), ivec2(0, -1));
  for (int index = 0; index < 4; index++) {
    ivec2 neighbour = clamp(pixel + offsets[index], ivec2(0), ivec2(params.viewport_size) - 1);
    if (!(dot(texelFetch(normal_tx, neighbour, 0).xyz, normal) >= FLAT_COSINE)) {
      return false;
    }
  }
  return true;
}

/* Screen motion in pixels at the pixel or its hit, the larger (0 where nothing moves). */
float motion_seen(ivec2 pixel, vec4 hit)
{
  float motion = length(texelFetch(motion_tx, pixel, 0).xy);
  if (hit.x > 0.0) {
    motion = max(motion, length(texelFetch(motion_tx, texel_at(hit.yz * params.viewport_size), 0).xy));
  }
  return is_finite(vec4(motion)) ? motion : 1e6; /* unknown motion: assume it moves */
}

/* The light at the pixel's hit is what the history saw (the camera held the pixel: the same texel). */
bool hit_light_unchanged(vec4 hit)
{
  if (!(hit.x > 0.0)) {
    return true; /* no hit: the reflection is the fallback's, which SSR does not show */
  }
  ivec2 hit_texel = texel_at(hit.yz * params.viewport_size);
  vec3 now = texelFetch(radiance_tx, hit_texel, 0).rgb;
  vec3 before = texelFetch(previous_radiance_tx, hit_texel, 0).rgb;
  vec3 change = abs(now - before);
  return all(lessThanEqual(change, RADIANCE_TOLERANCE * max(now, before) + 1e-6));
}

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  vec4 current = texelFetch(spatial_tx, pixel, 0);
  current = is_finite(current) ? current : vec4(0.0);
  vec4 hit = texelFetch(reflection_hit_tx, pixel, 0);
  float motion = motion_seen(pixel, hit);
  reflection_img = current;
  history_record_img = vec4(1.0, 0.0, 0.0, motion);
  float depth = texelFetch(depth_tx, pixel, 0).r;
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  float squared_luminance = luminance(current.rgb) * luminance(current.rgb);
  vec3 view_virtual_point = view_position(uv, depth) + view_incident(uv) * (hit.x > 0.0 ? hit.x : 0.0);
  vec3 virtual_point = (params.view_to_world * vec4(view_virtual_point, 1.0)).xyz;
  history_moments_img = vec4(squared_luminance, virtual_point);
  if (params.history_mode == HISTORY_MODE_NONE || is_background(depth)) {
    return;
  }
  vec2 previous_uv = reprojected_uv(pixel, uv, depth, hit);
  if (!(all(greaterThanEqual(previous_uv, vec2(0.0))) && all(lessThanEqual(previous_uv, vec2(1.0))))) {
    return; /* off screen last frame (or not a number): no history */
  }
  vec4 history = textureLod(history_tx, previous_uv, 0.0);
  vec4 history_record = textureLod(history_record_tx, previous_uv, 0.0);
  float history_count = history_record.x;
  if (!is_finite(history) || !(history_count >= 1.0)) {
    return;
  }
  bool camera_held_it = all(lessThan(abs(previous_uv - uv) * params.viewport_size, vec2(0.01)));
  if (params.history_mode == HISTORY_MODE_ANIMATION && camera_held_it && !hit_light_unchanged(hit)) {
    return;
  }
  /* A reflection the captures resolved has no hit on screen whose motion shows: where they were
   * captured afresh (something in them moved), it is clipped like a moving one. */
  bool captures_moved = params.captures_changed != 0 && hit.w > 0.0;
  bool holds_still = params.history_mode == HISTORY_MODE_STILL ||
                     (camera_held_it && max(motion, history_record.w) < 0.01 && !captures_moved);
  /* Only the view moved, by under a pixel at a flat glossy reflector and its hit, both of which
   * the last view saw: the reprojected history saw the same light, so it keeps averaging, unclipped. */
  bool view_steady = params.history_mode == HISTORY_MODE_VIEW && motion < VIEW_STEADY_PX &&
                     texelFetch(roughness_tx, pixel, 0).r > MIRROR_ROUGHNESS && flat_reflector(pixel);
  vec4 history_moments = textureLod(history_moments_tx, previous_uv, 0.0);
  if (!holds_still && !view_steady) {
    bool same_reflection = hit.x > 0.0 && distance(history_moments.yzw, virtual_point) <
                                              SAME_REFLECTION_PX * pixel_footprint(-view_virtual_point.z);
    float history_luminance = luminance(history.rgb);
    float history_noise = sqrt(max(history_moments.x - history_luminance * history_luminance, 0.0));
    history = variance_clip(pixel, history, same_reflection ? history_noise : 0.0);
  }
  float most_frames = holds_still ? STATIC_HISTORY_FRAMES : params.history_frames;
  float count = min(history_count + 1.0, most_frames);
  reflection_img = mix(history, current, 1.0 / count);
  history_moments_img = vec4(mix(history_moments.x, squared_luminance, 1.0 / count), virtual_point);
  history_record_img = vec4(count, previous_uv * params.viewport_size, motion);
}
