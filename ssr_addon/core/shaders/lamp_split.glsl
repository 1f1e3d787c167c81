/* Lamp split (lamp_split = analytic, the Cost issue): EEVEE's "Specular Light" holds lamp
 * highlights and probe/world reflections together; SSR replaces only the latter. This pass
 * computes what the light holds of each lamp and splits it off, inside the chain, from
 * textures it has uploaded anyway: no second, lamps-only render, and nothing read back.
 *
 * Inputs:  depth_tx (view depth), normal_tx (world normal), roughness_tx, dfg_tx
 *          (the FG table, whose A + B is the GGX lobe's reflectance: dfg_lib.glsl), specular_light_tx
 *          (EEVEE's Specular Light), shadow_tx (EEVEE's Shadow pass), and the lamps in
 *          lamp_block (blender/lights.py reads them as EEVEE sets its lights up).
 * Outputs: specular_direct_img = (the lamps' specular light, shadowed, 1),
 *          specular_indirect_img = (the rest of the Specular Light, which SSR replaces, 1).
 *
 * EEVEE integrates each light's shape against the normalised lobe (LTC). Here the same
 * integral is estimated with two strategies, points on the shape and the lobe's visible
 * normals, on one fixed stratified pattern, combined by multiple importance sampling
 * (power heuristic): a mirror is exact through the lobe samples, a rough surface under a
 * small lamp through the shape samples. Spheres, Soft Falloff disks and suns are disks
 * facing the point, as in EEVEE. Shadows come from EEVEE's Shadow pass, each sample's
 * shadowed share of all lamp light: exact for one lamp, a lamp-weighted mean for more. */

struct Emitter {
  vec3 centre; /* relative to the shading point */
  vec3 x_axis, y_axis, normal;
  vec2 half_size;
  bool ellipse;
};

vec3 world_position(vec2 uv, float depth, out vec3 towards_camera)
{
  vec3 origin, direction;
  camera_ray_of(lamp_block.clip_to_view, uv, origin, direction);
  vec3 view_point = ray_point_at_depth(origin, direction, depth);
  towards_camera = normalize(-mat3(lamp_block.view_to_world) * direction);
  return (lamp_block.view_to_world * vec4(view_point, 1.0)).xyz;
}

vec2 stratum(int index, int side)
{
  return (vec2(index % side, index / side) + 0.5) / float(side);
}

/* EEVEE's attenuation of LAMP at a point (without shadows): distance fade, spot cone,
 * the back of an area light, and the fade below the surface's horizon. */
float lamp_attenuation(LampData lamp, vec3 to_lamp, vec3 normal)
{
  float distance_to_lamp = lamp.shape == LAMP_SHAPE_SUN ? 1.0 : length(to_lamp);
  vec3 direction = to_lamp / distance_to_lamp;
  float attenuation = 1.0;
  if (lamp.shape != LAMP_SHAPE_SUN) {
    float fade = clamp(1.0 - pow(distance_to_lamp / lamp.influence_radius, 4.0), 0.0, 1.0);
    attenuation = fade * fade;
  }
  if (lamp.is_spot != 0) {
    vec3 local = transpose(mat3(lamp.x_axis, lamp.y_axis, lamp.z_axis)) * direction;
    vec2 stretched = local.xy * lamp.spot_size_inv / (abs(local.z) > 1e-12 ? local.z : 1e-12);
    float ellipse = inversesqrt(1.0 + dot(stretched, stretched));
    float mask = smoothstep(0.0, 1.0, ellipse * lamp.spot_mul + lamp.spot_bias);
    attenuation *= local.z > 0.0 ? mask : 0.0;
  }
  bool is_area = lamp.shape == LAMP_SHAPE_RECT || lamp.shape == LAMP_SHAPE_ELLIPSE;
  if (is_area && dot(direction, lamp.z_axis) <= 0.0) {
    return 0.0;
  }
  float shape_radius = is_area ? length(vec2(lamp.half_width, lamp.half_height)) : lamp.half_width;
  return attenuation * clamp((shape_radius / distance_to_lamp + dot(direction, normal) + 0.1) * 10.0, 0.0, 1.0);
}

Emitter lamp_emitter(LampData lamp, vec3 to_lamp)
{
  Emitter emitter;
  emitter.centre = to_lamp;
  if (lamp.shape == LAMP_SHAPE_RECT || lamp.shape == LAMP_SHAPE_ELLIPSE) {
    emitter.x_axis = lamp.x_axis;
    emitter.y_axis = lamp.y_axis;
    emitter.half_size = vec2(lamp.half_width, lamp.half_height);
    emitter.ellipse = lamp.shape == LAMP_SHAPE_ELLIPSE;
  }
  else {
    float distance_to_lamp = length(to_lamp);
    float radius = lamp.half_width;
    if (lamp.shape == LAMP_SHAPE_SPHERE) {
      /* The disk at the centre spanning the sphere's solid angle. */
      radius *= inversesqrt(max(1e-8, 1.0 - (radius / distance_to_lamp) * (radius / distance_to_lamp)));
    }
    mat3 frame = tangent_frame(to_lamp / distance_to_lamp);
    emitter.x_axis = frame[0];
    emitter.y_axis = frame[1];
    emitter.half_size = vec2(radius);
    emitter.ellipse = true;
  }
  emitter.normal = cross(emitter.x_axis, emitter.y_axis);
  return emitter;
}

float emitter_area(Emitter emitter)
{
  return 4.0 * emitter.half_size.x * emitter.half_size.y * (emitter.ellipse ? M_PI / 4.0 : 1.0);
}

/* Solid-angle pdf of sampling direction L uniformly over the emitter, 0 where L misses it. */
float emitter_pdf(Emitter emitter, vec3 l)
{
  float cos_emitter = dot(l, emitter.normal);
  if (abs(cos_emitter) < 1e-12) {
    return 0.0;
  }
  float t = dot(emitter.centre, emitter.normal) / cos_emitter;
  vec3 offset = l * t - emitter.centre;
  vec2 unit = vec2(dot(offset, emitter.x_axis), dot(offset, emitter.y_axis)) / emitter.half_size;
  bool inside = emitter.ellipse ? dot(unit, unit) <= 1.0 : all(lessThanEqual(abs(unit), vec2(1.0)));
  return (t > 0.0 && inside) ? t * t / (emitter_area(emitter) * abs(cos_emitter)) : 0.0;
}

vec3 emitter_point(Emitter emitter, vec2 u)
{
  vec2 unit = emitter.ellipse ? sqrt(u.x) * vec2(cos(2.0 * M_PI * u.y), sin(2.0 * M_PI * u.y)) : u * 2.0 - 1.0;
  return emitter.centre + unit.x * emitter.half_size.x * emitter.x_axis +
         unit.y * emitter.half_size.y * emitter.y_axis;
}

/* The normalised lobe at L (BRDF cos over the lobe's reflectance) and its visible-normal pdf. */
void lobe_at(mat3 frame, vec3 v, vec3 l, float alpha, float albedo, out float value, out float lobe_pdf)
{
  vec3 n = frame[2];
  float n_dot_v = max(dot(n, v), 1e-4);
  float n_dot_h = max(dot(n, normalize(v + l)), 0.0);
  value = ggx_brdf_cos(n, v, l, alpha) / albedo;
  lobe_pdf = visible_normal_pdf(n_dot_v, n_dot_h, alpha);
}

float lamp_integral(Emitter emitter, mat3 frame, vec3 v, float alpha, float albedo)
{
  int side = lamp_block.strata_per_side;
  int count = side * side;
  vec3 v_local = transpose(frame) * v;
  v_local.z = max(v_local.z, 1e-4);
  v_local = normalize(v_local);
  float sum = 0.0;
  for (int i = 0; i < count; i++) {
    vec2 u = stratum(i, side);
    /* A point on the shape. */
    vec3 to_point = emitter_point(emitter, u);
    vec3 l = normalize(to_point);
    float shape_pdf = dot(to_point, to_point) /
                      max(emitter_area(emitter) * abs(dot(l, emitter.normal)), 1e-20);
    float value, lobe_pdf;
    lobe_at(frame, v, l, alpha, albedo, value, lobe_pdf);
    sum += value * shape_pdf / max(shape_pdf * shape_pdf + lobe_pdf * lobe_pdf, 1e-30);
    /* A direction from the lobe, where it meets the shape. */
    vec3 h = frame * sample_visible_normal(v_local, alpha, u);
    l = reflect(-v, h);
    shape_pdf = emitter_pdf(emitter, l);
    if (shape_pdf > 0.0) {
      lobe_at(frame, v, l, alpha, albedo, value, lobe_pdf);
      sum += value * lobe_pdf / max(shape_pdf * shape_pdf + lobe_pdf * lobe_pdf, 1e-30);
    }
  }
  return sum / float(count);
}

/* The unshadowed specular light of every lamp at a surface pixel. */
vec3 lamp_light(ivec2 texel, float depth)
{
  vec2 uv = (vec2(texel) + 0.5) / lamp_block.viewport_size;
  vec3 v;
  vec3 position = world_position(uv, depth, v);
  vec3 n = normalize(texelFetch(normal_tx, texel, 0).xyz);
  float roughness = clamp(texelFetch(roughness_tx, texel, 0).r, 0.0, 1.0);
  /* The lobe's own width down to LAMP_MIN_ALPHA (core.ggx): at the rays' floor a mirror's tail
   * would light it where no engine does. */
  float alpha = max(roughness * roughness, LAMP_MIN_ALPHA);
  mat3 frame = tangent_frame(n);
  float n_dot_v = clamp(dot(n, v), 1e-4, 1.0);
  vec2 scale_bias = dfg_lookup(n_dot_v, roughness);
  float albedo = max(scale_bias.x + scale_bias.y, 1e-4);
  vec3 light = vec3(0.0);
  for (int index = 0; index < lamp_block.lamp_count; index++) {
    LampData lamp = lamp_block.lamps[index];
    vec3 to_lamp = lamp.shape == LAMP_SHAPE_SUN ? lamp.position : lamp.position - position;
    float attenuation = lamp_attenuation(lamp, to_lamp, n);
    if (attenuation > 1e-6) {
      light += lamp.radiance * attenuation * lamp_integral(lamp_emitter(lamp, to_lamp), frame, v, alpha, albedo);
    }
  }
  return light;
}

void main()
{
  ivec2 texel = ivec2(gl_FragCoord.xy);
  float depth = texelFetch(depth_tx, texel, 0).r;
  vec3 specular_light = texelFetch(specular_light_tx, texel, 0).rgb;
  vec3 direct = vec3(0.0);
  if (depth < lamp_block.background_depth) {
    direct = lamp_light(texel, depth) * texelFetch(shadow_tx, texel, 0).r;
  }
  specular_direct_img = vec4(direct, 1.0);
  specular_indirect_img = vec4(max(specular_light - direct, vec3(0.0)), 1.0);
}
