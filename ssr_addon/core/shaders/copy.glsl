/* A plain full-screen copy: the yardstick the benchmarks divide every stage's cost by.
 * Input: source_tx. Output: copy_img. */

void main()
{
  copy_img = texelFetch(source_tx, ivec2(gl_FragCoord.xy), 0);
}
