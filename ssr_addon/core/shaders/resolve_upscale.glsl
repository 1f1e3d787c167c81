/* The half-resolution resolve scaled up to full resolution, bilinearly (the
 * "Sparse Ray Tracing" slide's cheaper variant, resolve_resolution=half): what
 * the deck's full-resolution resolve is compared with.
 *
 * Inputs:  resolved_tx, reflection_hit_tx (resolve.glsl's outputs at the traced size).
 * Outputs: resolved_img, reflection_hit_img (the same at full resolution). */

void main()
{
  /* The traced texels cover trace_scale * trace_size pixels (one more than an odd frame). */
  vec2 uv = gl_FragCoord.xy / (float(params.trace_scale) * params.trace_size);
  resolved_img = texture(resolved_tx, uv);
  reflection_hit_img = texture(reflection_hit_tx, uv);
}
