/* Copy a pyramid's level 0, its source, into its rectangle of the atlas, so a tracer can
 * pick any level from one sampler (Python-made textures have a single mip level); the
 * reduced levels draw themselves there (pyramid_downsample.glsl).
 *
 * Input: level_tx. Output: atlas_img, drawn with the viewport on the level's rectangle. */

void main()
{
  atlas_img = texelFetch(level_tx, ivec2(gl_FragCoord.xy) - level_offset, 0);
}
