/* The density with which trace.glsl draws a reflection ray ("Importance Sampling: BRDF,
 * Halton sequence" slides), shared with the resolve, which weighs each ray by it. */

/* The pdf, in solid angle, of a ray in direction L from a surface with view-space NORMAL, seen
 * along TO_EYE, of GGX ALPHA: as params.use_importance_sampling and params.ray_sampling draw it.
 * Directions below the surface are drawn too (trace.glsl gives them no light). */
float ray_pdf(vec3 normal, vec3 to_eye, float alpha, vec3 l)
{
  if (params.use_importance_sampling == 0) {
    return 1.0; /* mirror rays: a constant, so the resolve weights by the BRDF alone */
  }
  if (params.ray_sampling == RAY_SAMPLING_UNIFORM) {
    /* lobe_sample leaves out the grazing band cos(theta) < LOBE_TAIL */
    return 1.0 / (2.0 * M_PI * (1.0 - LOBE_TAIL));
  }
  float n_dot_h = max(dot(normal, normalize(to_eye + l)), 0.0);
  return visible_normal_pdf(max(dot(normal, to_eye), 1e-4), n_dot_h, alpha);
}
