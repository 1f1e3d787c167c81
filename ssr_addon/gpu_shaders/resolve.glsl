/* Colour resolve ("use color of intersection point as reflection color").
 *
 * Inputs:  hit_tx (from the trace), radiance_tx (the lit scene), roughness_tx.
 * Output:  reflection_img = (reflected radiance, confidence).
 *
 * Confidence fades to zero over the top fifth of [0, max_roughness] so the
 * switch from SSR to the probe/world reflection leaves no seam. */

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  vec4 hit = texelFetch(hit_tx, texel, 0);
  float max_roughness = params.shaping.w;
  float roughness = texelFetch(roughness_tx, texel, 0).r;
  float roughness_fade = 1.0 - smoothstep(0.8 * max_roughness, max_roughness, roughness);
  float confidence = hit.w * roughness_fade;
  vec3 radiance = confidence > 0.0 ? textureLod(radiance_tx, hit.xy, 0.0).rgb : vec3(0.0);
  reflection_img = vec4(radiance, confidence);
}
