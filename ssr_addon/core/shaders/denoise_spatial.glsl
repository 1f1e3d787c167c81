/* Edge-aware spatial filter after the resolve: not in the Frostbite deck, which
 * leans on the temporal filter alone; this is the bilateral pass of EEVEE's
 * denoiser and FidelityFX SSSR's edge-avoiding filter (after Stachowiak,
 * "Stochastic All The Things", SEED 2018).
 *
 * Inputs:  resolved_tx (resolve: premultiplied radiance, confidence),
 *          reflection_hit_tx (mean hit distance, mean hit uv), depth_tx, normal_tx, roughness_tx,
 *          history_record_tx (iterations the temporal history holds, history_lib.glsl).
 * Output:  spatial_img (premultiplied radiance, confidence).
 *
 * Each pixel averages a 5x5 grid of neighbours spread over the screen footprint
 * of its own GGX lobe at its hit distance (alpha * distance, at most
 * params.denoise_radius pixels), so the filter never blurs wider than the
 * surface's roughness already blurs the reflection, narrowed by the square root
 * of the iterations the history averages (it stands for one iteration's noise). Taps count by a Gaussian
 * in screen distance times how well they share this pixel's plane, normal and
 * roughness, so the filter stops at edges. Mirror-like pixels (the lobe under
 * half a pixel) pass through untouched. Averaging premultiplied values fills
 * a pixel whose own rays missed from neighbours that hit, weighted by
 * their confidence. */

float lobe_radius_px(float roughness, float hit_distance, float depth)
{
  float alpha = ggx_alpha(roughness);
  return min(alpha * hit_distance / pixel_footprint(depth), params.denoise_radius);
}

void main()
{
  ivec2 pixel = ivec2(gl_FragCoord.xy);
  vec4 center = texelFetch(resolved_tx, pixel, 0);
  spatial_img = center;
  float depth = texelFetch(depth_tx, pixel, 0).r;
  float roughness = texelFetch(roughness_tx, pixel, 0).r;
  if (is_background(depth) || roughness > params.max_roughness) {
    return;
  }
  float hit_distance = texelFetch(reflection_hit_tx, pixel, 0).x;
  float radius = lobe_radius_px(roughness, hit_distance, depth) / sqrt(accumulated_iterations(pixel));
  if (!(radius >= 0.5)) {
    return;
  }
  vec2 uv = (vec2(pixel) + 0.5) * params.pixel_size;
  vec3 position = view_position(uv, depth);
  vec3 normal = view_normal(texelFetch(normal_tx, pixel, 0).xyz);
  float footprint = pixel_footprint(depth);
  float spacing = radius / 2.0;

  vec4 sum = vec4(0.0);
  float weight_sum = 0.0;
  for (int y = -2; y <= 2; y++) {
    for (int x = -2; x <= 2; x++) {
      vec2 offset = vec2(x, y) * spacing;
      ivec2 tap = texel_at(vec2(pixel) + 0.5 + offset);
      float tap_depth = texelFetch(depth_tx, tap, 0).r;
      float tap_roughness = texelFetch(roughness_tx, tap, 0).r;
      if (is_background(tap_depth) || tap_roughness > params.max_roughness) {
        continue;
      }
      vec2 tap_uv = (vec2(tap) + 0.5) * params.pixel_size;
      vec3 tap_normal = view_normal(texelFetch(normal_tx, tap, 0).xyz);
      float plane_distance = abs(dot(normal, view_position(tap_uv, tap_depth) - position));
      float weight = exp(-dot(offset, offset) / (2.0 * spacing * spacing)) *
                     exp(-plane_distance / footprint) *
                     pow(max(dot(normal, tap_normal), 0.0), 32.0) *
                     exp(-abs(tap_roughness - roughness) * 20.0);
      vec4 value = texelFetch(resolved_tx, tap, 0);
      if (weight > 0.0 && is_finite(value)) {
        sum += weight * value;
        weight_sum += weight;
      }
    }
  }
  if (weight_sum > 0.0) {
    spatial_img = sum / weight_sum;
  }
}
