/* Copy part of a pyramid into its rectangle of the atlas, so a tracer can pick any
 * level from one sampler (Python-made textures have a single mip level): level 0, the
 * source, and each column of reduced levels as pyramid_downsample.glsl drew them.
 *
 * Input: level_tx. Output: atlas_img, drawn with the viewport on the rectangle at level_offset. */

void main()
{
  atlas_img = texelFetch(level_tx, ivec2(gl_FragCoord.xy) - level_offset, 0);
}
