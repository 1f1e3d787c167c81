/* One level of a 2x2 reduction pyramid ("Generate Depth Mip-Map: use min values
 * instead of average"): REDUCE_MIN for the Hi-Z depth pyramid, else the
 * average, for the colour pyramid of the cone-filtered resolve.
 *
 * Input:  source_tx, the previous level at source_offset, source_size texels.
 * Output: level_img, drawn with the viewport on the level's rectangle at level_offset
 *         in the column texture of its parity (chain.build_pyramid: odd and even levels
 *         take turns, as a texture may not be read while drawn into).
 * Levels are ceil(previous / 2) in size, so texel c always covers source
 * texels 2c and 2c+1 (the last one alone on an odd edge) and a cell of level
 * L is exactly the 2^L x 2^L block of full-resolution pixels the tracer assumes. */

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy) - level_offset;
  ivec2 first = texel * 2;
  ivec2 last = min(first + 1, source_size - 1);
#ifdef REDUCE_MIN
  float nearest = 1e30;
  for (int y = first.y; y <= last.y; y++) {
    for (int x = first.x; x <= last.x; x++) {
      nearest = min(nearest, texelFetch(source_tx, source_offset + ivec2(x, y), 0).r);
    }
  }
  level_img = vec4(nearest);
#else
  vec4 total = vec4(0.0);
  for (int y = first.y; y <= last.y; y++) {
    for (int x = first.x; x <= last.x; x++) {
      total += texelFetch(source_tx, source_offset + ivec2(x, y), 0);
    }
  }
  level_img = total / float((last.x - first.x + 1) * (last.y - first.y + 1));
#endif
}
