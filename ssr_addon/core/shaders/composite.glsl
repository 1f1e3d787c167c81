/* Composite: put traced reflections where the engine had only probe/world reflections.
 *
 * Inputs:  combined_tx (the engine's image), specular_color_tx (the engine's own
 *          specular weight of the light it reflected), specular_indirect_tx (that
 *          light where it came from probes and the world), reflection_tx (SSR:
 *          premultiplied radiance, confidence), f0_tx, dfg_tx (the FG table),
 *          depth_tx, normal_tx, roughness_tx.
 * Output:  final_img.
 *
 * The engine's image is a sum of passes:
 *   combined = diffuse_color * diffuse_light + specular_color * (lamp_specular + indirect_specular)
 *            + emission + environment (+ transmission, volumes...).
 * SSR estimates indirect specular light L, which the slides' estimator
 * multiplies by the pre-integrated FG = F0 * A + B (without an F0 pass, a viewport
 * capture's, EEVEE's own specular_color, which pre-integrates it alike), so with confidence c:
 *   final = combined + c * FG * L - c * specular_color * indirect_specular.
 * Diffuse light, emission, the world seen directly and lamp highlights pass
 * through untouched; where c is 0 the probe/world reflection stays.
 *
 * indirect_specular is everything SSR can stand in for, lamps excepted (blender/render_passes.py):
 *   EEVEE:  Specular Light less the lamps' highlights (probes and the world);
 *   Cycles: Glossy Indirect (other surfaces) plus the part of Glossy Direct that is
 *           not lamps the camera cannot see: reflected emissive surfaces and the world,
 *           which Cycles counts as direct light (one bounce to an emitter). SSR's rays
 *           fetch the emissive surfaces' Combined, so leaving them in would count the
 *           reflection of an on-screen emitter twice. */

vec3 fg_term(vec3 f0, float n_dot_v, float roughness)
{
  vec2 scale_bias = dfg_lookup(n_dot_v, roughness);
  return f0 * scale_bias.x + scale_bias.y;
}

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  vec4 combined = texelFetch(combined_tx, texel, 0);
  vec4 reflection = texelFetch(reflection_tx, texel, 0);
  final_img = combined;
  if (!(reflection.a > 0.0)) {
    return; /* no reflection (NaN included): the engine's image as it is */
  }
  vec2 uv = (vec2(texel) + 0.5) * params.pixel_size;
  vec3 normal = view_normal(texelFetch(normal_tx, texel, 0).xyz);
  float n_dot_v = clamp(dot(normal, -view_incident(uv)), 0.0, 1.0);
  vec3 specular_color = texelFetch(specular_color_tx, texel, 0).rgb;
  vec3 fg = params.fg_from_specular_color != 0 ?
                specular_color :
                fg_term(texelFetch(f0_tx, texel, 0).rgb, n_dot_v, texelFetch(roughness_tx, texel, 0).r);
  vec3 indirect = texelFetch(specular_indirect_tx, texel, 0).rgb;
  /* The engine filters each pass on its own, so where a pixel straddles an edge (the floor
   * row touching a wall) the product of the filtered colour and light can exceed what the
   * filtered image holds of it; no part of the image is more than all of it. */
  vec3 probe_reflection = min(specular_color * indirect, max(combined.rgb, vec3(0.0)));
  vec3 replaced = fg * reflection.rgb - reflection.a * probe_reflection;
  final_img = vec4(max(combined.rgb + replaced, vec3(0.0)), combined.a);
}
