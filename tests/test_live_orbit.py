"""The live view orbiting the wet street (issue "Live while you navigate"): each moving view,
one iteration over the last view's reprojected history, is no further from a converged still
of that view than one iteration of its own passes without history, and a slow orbit does not
flicker. `make bench-live` measures the same orbits; this holds their goals."""
import pytest

from ssr_addon.blender.scene_io import load_scene
from ssr_addon.core.settings import ChainSettings

pytestmark = [pytest.mark.blender, pytest.mark.slow]


def test_history_helps_every_view_of_an_orbit_over_the_wet_street(gpu_backend, tmp_path):
    """24 views, 1 degree each, of a 320x180 view captured at 160x90 (the default Live
    Resolution), as the bench's orbit. The street's last views keep only a strip of wet ground
    along the frame's edge, where a history clipped to one iteration's noisy neighbourhood came
    out darker than no history at all (0.245 against 0.213). Each still stops once a doubling of
    its iterations moves it by less than noise_threshold of its level, so it lies about that far
    from what it converges to, and it cannot tell apart two errors measured against it that
    differ by less than that: a view counts as worse with history only by more than that.
    Over the orbit, history must also take a fifth off the error without it."""
    from lab.bench.scenes import resolve_scene
    from lab.live_latency import orbit_quality
    settings = ChainSettings()
    _, rows, _ = orbit_quality(load_scene(resolve_scene("wet_street")), tmp_path, settings, (160, 90), 24)
    assert len(rows) == 24
    worse = [(row["view"], round(row["moving"], 4), round(row["without_history"], 4))
             for row in rows if row["moving"] > row["without_history"] + settings.noise_threshold]
    assert not worse, f"views worse with history (view, moving, without history): {worse}"
    moving, without_history = (sum(row[name] for row in rows) / len(rows) for name in ("moving", "without_history"))
    assert moving <= 0.8 * without_history, f"mean error {moving:.3f} with history, {without_history:.3f} without"


@pytest.mark.xfail(strict=True, reason="over the one-sample views an artist's orbit draws, the moving view flickers "
                                       "0.057 (without history about 0.07; EEVEE's own one-sample image 0.034)")
def test_a_slow_orbit_over_the_wet_street_flickers_within_the_still_cameras_limit(gpu_backend, tmp_path):
    """The issue's flicker goal, as `make bench-live` measures it: over an orbit so slow that an
    error moving with the view moves less than a pixel a view, each view's error changes from one
    view to the next by less than the stability suite's limit for a still camera. EEVEE's image
    without SSR, which does not flicker, shows the measure's own floor there."""
    from lab.bench.scenes import resolve_scene
    from lab.bench.stability import FLICKER_LIMIT
    from lab.live_latency import FLICKER_ORBIT, orbit_quality
    _, _, flicker = orbit_quality(load_scene(resolve_scene("wet_street")), tmp_path, ChainSettings(), (160, 90),
                                  *FLICKER_ORBIT)
    assert flicker["without_ssr"] < FLICKER_LIMIT / 2, flicker  # the measure sees a steady image as steady
    assert flicker["moving"] < FLICKER_LIMIT, flicker
