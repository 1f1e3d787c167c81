/* How many iterations the temporal history averages at a pixel, this one included
 * (temporal.glsl's count; 1 without history). The passes that trade blur for noise
 * (the resolve's cones, the spatial filter) stand for one iteration's few rays; a pixel
 * whose history averages n iterations needs 1/n of that, so a settled still is the lobe
 * integral of its rays, not a blur of it (progressive filtered importance sampling).
 * The count is read at the pixel itself: in a moving frame that is where the history
 * was a frame ago, near enough for a width. Needs history_record_tx. */
float accumulated_iterations(ivec2 pixel)
{
  if (params.history_mode == HISTORY_MODE_NONE) {
    return 1.0;
  }
  float history_count = texelFetch(history_record_tx, pixel, 0).x;
  return history_count >= 1.0 ? history_count + 1.0 : 1.0;
}
