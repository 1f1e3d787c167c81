/* Scene-linear colour to what the 3D View shows (not a slide: the deck composites into the
 * engine's own frame; the live overlay must match the viewport it covers). The scene's view
 * transform, look and gamma are baked into lut_tx (blender/colour_management.py) over a log2 shaper; hardware
 * trilinear filtering interpolates it. Exposure scales the scene-linear colour first, as in
 * Blender, so dragging it needs no new LUT. Debug views skip all this: they are data, shown
 * with the plain sRGB curve.
 * Inputs: image_tx (scene linear), lut_tx (LUT_SIZE^3, display encoded).
 * Constants: use_view_transform (0: plain sRGB), exposure_scale (2^exposure).
 * Output: display_img (display encoded). */

float lut_coordinate(float linear)
{
  float stops = log2(max(linear, exp2(LUT_LOG2_MIN)));
  float shaper = clamp((stops - LUT_LOG2_MIN) / (LUT_LOG2_MAX - LUT_LOG2_MIN), 0.0, 1.0);
  return (shaper * (LUT_SIZE - 1.0) + 0.5) / LUT_SIZE;  /* texel centres at the lattice points */
}

float srgb_encode(float linear)
{
  linear = clamp(linear, 0.0, 1.0);
  return linear <= 0.0031308 ? 12.92 * linear : 1.055 * pow(linear, 1.0 / 2.4) - 0.055;
}

void main()
{
  vec4 color = texelFetch(image_tx, ivec2(gl_FragCoord.xy), 0);
  if (use_view_transform != 0) {
    color.rgb *= exposure_scale;
    vec3 coordinate = vec3(lut_coordinate(color.r), lut_coordinate(color.g), lut_coordinate(color.b));
    display_img = vec4(texture(lut_tx, coordinate).rgb, 1.0);
  }
  else {
    display_img = vec4(srgb_encode(color.r), srgb_encode(color.g), srgb_encode(color.b), 1.0);
  }
}
