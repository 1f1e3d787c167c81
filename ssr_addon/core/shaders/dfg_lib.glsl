/* The pre-integrated FG table (dfg_table.glsl) read at n.v and roughness: (A, B) of the
 * split-sum FG = F0 * A + B, and with F0 = 1 the GGX lobe's reflectance A + B, which
 * normalises it. Needs dfg_tx. */
vec2 dfg_lookup(float n_dot_v, float roughness)
{
  /* Texel i holds (i + 0.5) / N: map [0.5/N, 1 - 0.5/N] onto the texel centres. */
  vec2 table_size = vec2(textureSize(dfg_tx, 0));
  vec2 coordinate = clamp(vec2(n_dot_v, roughness), 0.5 / table_size, 1.0 - 0.5 / table_size);
  return textureLod(dfg_tx, coordinate, 0.0).xy;
}
