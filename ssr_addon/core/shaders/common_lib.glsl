/* Helpers shared by the passes: the frame's camera (view_lib.glsl through params),
 * hashing, and pyramid atlas access. */

#define M_PI 3.14159265358979

/* The texel under a screen position in full-resolution pixels, kept on screen. */
ivec2 texel_at(vec2 position_px)
{
  return clamp(ivec2(floor(position_px)), ivec2(0), ivec2(params.viewport_size) - 1);
}

/* The pixel whose ray traced texel TEXEL holds this iteration: with half-resolution
 * tracing, pixel params.quad_phase of its 2x2 quad (the trace, and a resolve at
 * the traced size, shade there). */
ivec2 ray_origin_pixel(ivec2 texel)
{
  int scale = params.trace_scale;
  int phase = params.quad_phase;
  ivec2 offset = scale > 1 ? ivec2(phase & 1, (phase >> 1) ^ (phase & 1)) : ivec2(0);
  return min(texel * scale + offset, ivec2(params.viewport_size) - 1);
}

bool is_background(float depth)
{
  return depth >= params.clip_end;
}

/* Camera ray through a screen position (uv in [0,1]^2): near-plane point and direction. */
void camera_ray(vec2 uv, out vec3 ray_origin, out vec3 ray_direction)
{
  camera_ray_of(params.clip_to_view, uv, ray_origin, ray_direction);
}

vec3 view_position(vec2 uv, float depth)
{
  vec3 origin, direction;
  camera_ray(uv, origin, direction);
  return ray_point_at_depth(origin, direction, depth);
}

vec3 view_incident(vec2 uv)
{
  vec3 origin, direction;
  camera_ray(uv, origin, direction);
  return normalize(direction);
}

vec3 view_normal(vec3 world_normal)
{
  return normalize(mat3(params.world_to_view) * world_normal);
}

/* Size of one pixel, in view units, at this depth of a camera with projection VIEW_TO_CLIP
 * and HEIGHT_PX rows of pixels. */
float pixel_footprint_of(mat4 view_to_clip, float height_px, float depth)
{
  bool orthographic = view_to_clip[3][3] == 1.0;
  return 2.0 / (view_to_clip[1][1] * height_px) * (orthographic ? 1.0 : depth);
}

/* Size of one pixel of the frame, in view units, on a surface at this depth. */
float pixel_footprint(float depth)
{
  return pixel_footprint_of(params.view_to_clip, params.viewport_size.y, depth);
}

/* The level of a colour pyramid whose texel matches the patch a ray's cone of SOLID_ANGLE
 * steradians covers at HIT_DISTANCE, where a level-0 texel there is TEXEL_SIZE across
 * (fractional; clamped to the LEVELS there are). */
float cone_level(float hit_distance, float solid_angle, float texel_size, int levels)
{
  float patch_area = hit_distance * hit_distance * solid_angle;
  return clamp(0.5 * log2(patch_area / (texel_size * texel_size)), 0.0, float(levels) - 1.0);
}


/* No NaN or Inf in any component. Read from the exponent bits: comparisons and isnan()
 * may be folded away by a compiler that assumes finite maths (Mesa's does). */
bool is_finite(vec4 value)
{
  uvec4 exponent = floatBitsToUint(value) & 0x7f800000u;
  return all(notEqual(exponent, uvec4(0x7f800000u)));
}

/* PCG hash: decorrelates pixels (Cranley-Patterson rotation of the Halton points). */
uint pcg_hash(uint value)
{
  uint state = value * 747796405u + 2891336453u;
  uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
  return (word >> 22u) ^ word;
}

/* Two uniform numbers per pixel and SEED (0: the pixel's fixed rotation). Pixels count from
 * the requested frame's corner, so a frame draws the same numbers with or without a guard band. */
vec2 pixel_noise(ivec2 pixel, uint seed_offset)
{
  ivec2 frame_pixel = pixel - ivec2(params.frame_rect.xy);
  uint seed = pcg_hash(uint(frame_pixel.x) + pcg_hash(uint(frame_pixel.y) + pcg_hash(seed_offset)));
  return vec2(seed & 0xffffu, seed >> 16u) / 65536.0;
}

/* One texel of a pyramid level packed in an atlas (level rectangles from params). */
vec4 atlas_fetch(sampler2D atlas, vec4 level_rect, ivec2 texel)
{
  ivec2 clamped = clamp(texel, ivec2(0), ivec2(level_rect.zw) - 1);
  return texelFetch(atlas, ivec2(level_rect.xy) + clamped, 0);
}

/* Bilinear sample of one level of an atlas, never bleeding into its neighbours. */
vec4 atlas_sample(sampler2D atlas, vec4 level_rect, vec2 uv)
{
  vec2 position = clamp(uv * level_rect.zw, vec2(0.5), level_rect.zw - 0.5);
  return textureLod(atlas, (level_rect.xy + position) / vec2(textureSize(atlas, 0)), 0.0);
}

/* Trilinear sample of a colour pyramid atlas at LEVEL between its level rectangles. */
vec3 pyramid_sample(sampler2D atlas, vec4 lower_rect, vec4 upper_rect, float level, vec2 uv)
{
  vec3 a = atlas_sample(atlas, lower_rect, uv).rgb;
  vec3 b = atlas_sample(atlas, upper_rect, uv).rgb;
  return mix(a, b, level - floor(level));
}

/* The colour of the texel of level-0 rectangle LEVEL0 that a sharp hit at UV lies in. The frame
 * is already filtered over each pixel, and a plane or convex mirror never magnifies what it
 * reflects (its virtual image lies at least as far away as the object), so a blend of the texels
 * around the hit would only blur the reflection again; and where a wall meets the floor, the
 * wall's anti-aliased last row holds the floor's colour, which a blend read into the floor's
 * reflection of the wall as a bright line. */
vec3 texel_colour(sampler2D atlas, vec4 level0, vec2 uv)
{
  return atlas_fetch(atlas, level0, ivec2(floor(uv * level0.zw))).rgb;
}
