/* GGX microfacet lobe: visible-normal importance sampling and the BRDF weight
 * of the resolve ("Importance Sampling: BRDF, Halton sequence" slides).
 * alpha = roughness^2, as in Blender's Principled BSDF. */

#ifndef M_PI
#  define M_PI 3.14159265358979
#endif
/* MIN_ALPHA, the alpha floor, is core.ggx.MIN_ALPHA, and LOBE_TAIL the share of the lobe's
 * visible normals rays never sample (trace.glsl); gpu_passes defines both with this file. */

float ggx_alpha(float roughness)
{
  return max(roughness * roughness, MIN_ALPHA);
}

float ggx_d(float n_dot_h, float alpha)
{
  float a2 = alpha * alpha;
  /* cos^2 (a2 - 1) + 1, written so that an a2 below float precision keeps the peak finite. */
  float cos2 = n_dot_h * n_dot_h;
  float denominator = max(1.0 - cos2, 0.0) + cos2 * a2;
  return a2 / (M_PI * denominator * denominator);
}

float smith_lambda_term(float n_dot_x, float alpha)
{
  float a2 = alpha * alpha;
  return sqrt(a2 + (1.0 - a2) * n_dot_x * n_dot_x);
}

float smith_g1(float n_dot_v, float alpha)
{
  return 2.0 * n_dot_v / (n_dot_v + smith_lambda_term(n_dot_v, alpha));
}

/* Height-correlated Smith masking-shadowing. */
float smith_g2(float n_dot_v, float n_dot_l, float alpha)
{
  return 2.0 * n_dot_v * n_dot_l /
         (n_dot_l * smith_lambda_term(n_dot_v, alpha) + n_dot_v * smith_lambda_term(n_dot_l, alpha));
}

/* Orthonormal basis around n (Duff et al. 2017). */
mat3 tangent_frame(vec3 n)
{
  float s = n.z >= 0.0 ? 1.0 : -1.0;
  float a = -1.0 / (s + n.z);
  float b = n.x * n.y * a;
  vec3 t = vec3(1.0 + s * n.x * n.x * a, s * b, -s * n.x);
  vec3 bt = vec3(b, s + n.y * n.y * a, -n.y);
  return mat3(t, bt, n);
}

/* Heitz 2018, "Sampling the GGX Distribution of Visible Normals". v in the tangent frame. */
vec3 sample_visible_normal(vec3 v, float alpha, vec2 u)
{
  vec3 vh = normalize(vec3(alpha * v.x, alpha * v.y, v.z));
  float length_sq = vh.x * vh.x + vh.y * vh.y;
  vec3 t1 = length_sq > 0.0 ? vec3(-vh.y, vh.x, 0.0) * inversesqrt(length_sq) : vec3(1.0, 0.0, 0.0);
  vec3 t2 = cross(vh, t1);
  float r = sqrt(u.x);
  float phi = 2.0 * M_PI * u.y;
  float p1 = r * cos(phi);
  float p2 = r * sin(phi);
  float s = 0.5 * (1.0 + vh.z);
  p2 = (1.0 - s) * sqrt(max(0.0, 1.0 - p1 * p1)) + s * p2;
  vec3 nh = p1 * t1 + p2 * t2 + sqrt(max(0.0, 1.0 - p1 * p1 - p2 * p2)) * vh;
  return normalize(vec3(alpha * nh.x, alpha * nh.y, max(0.0, nh.z)));
}

/* pdf of the reflected direction l for visible-normal sampling: G1(v) D(h) / (4 n.v). */
float visible_normal_pdf(float n_dot_v, float n_dot_h, float alpha)
{
  return smith_g1(n_dot_v, alpha) * ggx_d(n_dot_h, alpha) / (4.0 * n_dot_v);
}

/* f_s(l -> v) cos(theta_l) without Fresnel (Fresnel lives in the FG term). */
float ggx_brdf_cos(vec3 n, vec3 v, vec3 l, float alpha)
{
  float n_dot_l = dot(n, l);
  float n_dot_v = max(dot(n, v), 1e-4);
  if (n_dot_l <= 0.0) {
    return 0.0;
  }
  vec3 h = normalize(v + l);
  return ggx_d(max(dot(n, h), 0.0), alpha) * smith_g2(n_dot_v, n_dot_l, alpha) / (4.0 * n_dot_v);
}

/* The solid angle one of RAYS_AVERAGED rays drawn with PDF stands for, read as a cone
 * (filtered importance sampling: 1 / (N pdf)), but never more than the whole sampled lobe:
 * rays reach sqrt((1 - LOBE_TAIL) / LOBE_TAIL) alphas from its peak (7 at 2 %), about that
 * squared over the peak pdf in solid angle. Without the bound, a ray from a smooth lobe's
 * tail reads a blur of everything around its hit: a speck. */
float ray_solid_angle(float pdf, float rays_averaged, float n_dot_v, float alpha)
{
  float lobe_solid_angle = (1.0 - LOBE_TAIL) / LOBE_TAIL / visible_normal_pdf(max(n_dot_v, 1e-4), 1.0, alpha);
  return min(1.0 / (rays_averaged * pdf), lobe_solid_angle);
}
