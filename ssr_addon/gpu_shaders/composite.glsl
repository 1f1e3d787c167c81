/* Composite: put traced reflections where the engine had only probe/world reflections.
 *
 * Inputs:  combined_tx (the engine's image), specular_color_tx (its pre-integrated
 *          specular reflectance, the FG term), specular_indirect_tx (the reflected
 *          light that came from probes and the world), reflection_tx (SSR:
 *          premultiplied radiance, confidence).
 * Output:  final_img.
 *
 * The engine's image is a sum of passes:
 *   combined = diffuse_color * diffuse_light + specular_color * (lamp_specular + indirect_specular)
 *            + emission + environment (+ transmission, volumes...).
 * SSR estimates indirect specular light, so with confidence c:
 *   final = combined + specular_color * (c * ssr - c * indirect_specular).
 * Diffuse light, emission, the world seen directly and lamp highlights pass
 * through untouched; where c is 0 the probe/world reflection stays. */

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  vec4 combined = texelFetch(combined_tx, texel, 0);
  vec4 reflection = texelFetch(reflection_tx, texel, 0);
  vec3 specular_color = texelFetch(specular_color_tx, texel, 0).rgb;
  vec3 indirect = texelFetch(specular_indirect_tx, texel, 0).rgb;
  vec3 replaced = specular_color * (reflection.rgb - reflection.a * indirect);
  final_img = vec4(max(combined.rgb + replaced, vec3(0.0)), combined.a);
}
