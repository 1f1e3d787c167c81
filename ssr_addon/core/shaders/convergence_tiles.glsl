/* The stopping rule's measurement (not a slide: the deck renders one frame at a time; a still
 * or a paused live view accumulates until its running mean holds). Each output texel sums one
 * CONVERGENCE_TILE x CONVERGENCE_TILE tile of the reflection at two checks, so only a few
 * thousand texels go back to the CPU instead of the whole image.
 * Inputs: before_tx, after_tx (premultiplied reflected radiance, confidence).
 * Output: tiles_img = (sum |after - before| over RGB, sum |after| over RGB, reflecting pixels,
 * pixels), each over the tile's pixels that reflect at either check. */

void main()
{
  ivec2 size = textureSize(after_tx, 0);
  ivec2 origin = ivec2(gl_FragCoord.xy) * CONVERGENCE_TILE;
  ivec2 end = min(origin + CONVERGENCE_TILE, size);
  vec4 sums = vec4(0.0, 0.0, 0.0, float((end.x - origin.x) * (end.y - origin.y)));
  for (int y = origin.y; y < end.y; y++) {
    for (int x = origin.x; x < end.x; x++) {
      vec4 before = texelFetch(before_tx, ivec2(x, y), 0);
      vec4 after = texelFetch(after_tx, ivec2(x, y), 0);
      if (before.a > 0.0 || after.a > 0.0) {
        vec3 change = abs(after.rgb - before.rgb);
        vec3 level = abs(after.rgb);
        sums.xyz += vec3(change.r + change.g + change.b, level.r + level.g + level.b, 1.0);
      }
    }
  }
  tiles_img = sums;
}
