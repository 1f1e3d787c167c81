/* The pre-integrated FG table ("FG is precomputed BRDF factor"): for the GGX
 * BRDF of ggx_lib.glsl, the directional albedo split as F0 * A + B
 * (Karis 2013), over n.v (x) and roughness (y) at the centres of a
 * DFG_SIZE x DFG_SIZE table.
 *
 * Output: dfg_img = (A, B, 0, 0). Integrated with DFG_SAMPLES Hammersley
 * points drawn from D(h) cos(theta_h); tests/oracles.py integrates the same
 * points in numpy. */

vec2 hammersley(uint index, uint count)
{
  uint bits = index;
  bits = (bits << 16u) | (bits >> 16u);
  bits = ((bits & 0x55555555u) << 1u) | ((bits & 0xAAAAAAAAu) >> 1u);
  bits = ((bits & 0x33333333u) << 2u) | ((bits & 0xCCCCCCCCu) >> 2u);
  bits = ((bits & 0x0F0F0F0Fu) << 4u) | ((bits & 0xF0F0F0F0u) >> 4u);
  bits = ((bits & 0x00FF00FFu) << 8u) | ((bits & 0xFF00FF00u) >> 8u);
  return vec2((float(index) + 0.5) / float(count), float(bits) * 2.3283064365386963e-10);
}

void main()
{
  vec2 coordinate = gl_FragCoord.xy / float(DFG_SIZE); /* texel centres: (i + 0.5) / N */
  float n_dot_v = coordinate.x;
  float alpha = ggx_alpha(coordinate.y);
  vec3 v = vec3(sqrt(1.0 - n_dot_v * n_dot_v), 0.0, n_dot_v);
  float a = 0.0, b = 0.0;
  for (uint i = 0u; i < uint(DFG_SAMPLES); i++) {
    vec2 u = hammersley(i, uint(DFG_SAMPLES));
    float cos_theta = sqrt((1.0 - u.x) / (1.0 + (alpha * alpha - 1.0) * u.x));
    float sin_theta = sqrt(1.0 - cos_theta * cos_theta);
    float phi = 2.0 * M_PI * u.y;
    vec3 h = vec3(sin_theta * cos(phi), sin_theta * sin(phi), cos_theta);
    float v_dot_h = dot(v, h);
    vec3 l = 2.0 * v_dot_h * h - v;
    if (l.z <= 0.0 || v_dot_h <= 0.0) {
      continue;
    }
    /* Weight of a D(h) cos(theta_h) sample: G2 (v.h) / ((n.h) (n.v)). */
    float visibility = smith_g2(n_dot_v, l.z, alpha) * v_dot_h / (h.z * n_dot_v);
    float fresnel = pow(1.0 - v_dot_h, 5.0);
    a += (1.0 - fresnel) * visibility;
    b += fresnel * visibility;
  }
  dfg_img = vec4(a, b, 0.0, 0.0) / float(DFG_SAMPLES);
}
