"""The deck's "Hierarchical ray trace" diagram: one ray's Hi-Z walk (hiz_walk.HiZWalk) seen
from the camera, from the side along the ray, and as its level at each iteration."""
import math

import numpy as np

from ..bench.charts import load_pyplot, save_figure

_OUTCOME_MARKERS = {"skip": ("^", "skip: in front, climb"),
                    "descend": ("v", "descend: may hit"),
                    "behind": ("o", "pass behind (level 0)"),
                    "hit": ("*", "hit")}


def _path_depth_profile(walk, depth, t_end, samples_per_pixel=8):
    """(screen distance, scene depth) along the ray's screen path from its origin up to T_END,
    read from DEPTH (image order) under each point."""
    width, height = walk.size
    length = float(walk.screen_distance(t_end))
    count = max(2, int(math.ceil(length * samples_per_pixel)) + 1)
    t = np.linspace(0.0, t_end, count)
    position = walk.position_px(t[:, None])
    x = np.clip(np.floor(position[:, 0]).astype(int), 0, width - 1)
    y = np.clip(np.floor(position[:, 1]).astype(int), 0, height - 1)
    return walk.screen_distance(t), depth[height - 1 - y, x]


def _ray_curve(samples, t_end, count=200):
    """(t, depth) of the ray up to T_END, drawn through its recorded SAMPLES {t: depth}. View depth
    along a projected ray is (a + b t) / (1 + d t) (1/depth is linear in t in perspective, depth
    itself in orthographic): fitted to the samples, else the samples joined by lines."""
    t = np.array(sorted(samples))
    depth = np.array([samples[key] for key in t])
    if len(t) >= 3:
        system = np.stack([np.ones_like(t), t, -depth * t], axis=1)
        (a, b, d), *_ = np.linalg.lstsq(system, depth, rcond=None)
        dense = np.linspace(0.0, t_end, count)  # from the ray's origin
        fitted = (a + b * dense) / (1 + d * dense)
        if np.allclose((a + b * t) / (1 + d * t), depth, rtol=1e-3, atol=1e-4 * depth.max()):
            return dense, fitted
    return t, depth


def _crop(walk, t_end, aspect=2.2):
    """(x0, x1, y0, y1) in image coordinates (y down) around the walk's cells and ray."""
    width, height = walk.size
    xs, ys = [], []
    for visit in walk.visits:
        x0, y0, x1, y1 = visit.pixel_bounds()
        xs += [x0, x1]
        ys += [height - y1, height - y0]
    for t in (0.0, t_end):
        x, y = walk.position_px(t)
        xs.append(x)
        ys.append(height - y)
    if not xs:
        return 0, width, 0, height
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    margin = max(4.0, 0.25 * max(x1 - x0, y1 - y0))
    x0, x1, y0, y1 = x0 - margin, x1 + margin, y0 - margin, y1 + margin
    if (x1 - x0) < aspect * (y1 - y0):  # widen to the panel's shape
        grow = 0.5 * (aspect * (y1 - y0) - (x1 - x0))
        x0, x1 = x0 - grow, x1 + grow
    for low, high, limit in ((0, 1, width), (2, 3, height)):
        box = [x0, x1, y0, y1]
        if box[high] - box[low] >= limit:
            box[low], box[high] = 0, limit
        elif box[low] < 0:
            box[low], box[high] = 0, box[high] - box[low]
        elif box[high] > limit:
            box[low], box[high] = box[low] - (box[high] - limit), limit
        x0, x1, y0, y1 = box
    return x0, x1, y0, y1


def _place_labels(axes, points, size=(12.0, 10.0)):
    """Offsets (dx, dy) in points for labels of data POINTS [(x, y)]: just below each where
    free, else the nearest free spot around it inside AXES (no earlier label within SIZE,
    display pixels); where none is free, the least crowded."""
    to_display = axes.transData.transform
    box = axes.get_window_extent()
    scale = axes.figure.dpi / 72.0
    candidates = sorted(((dx, dy) for dy in (-11, 11, -19, 19, -27, 27, -35, 35) for dx in (0, -9, 9, -18, 18)),
                        key=lambda offset: abs(offset[0]) + abs(offset[1]))
    placed, offsets = [], []
    for x, y in points:
        anchor = to_display((x, y))
        best = None
        for offset in candidates:
            centre = anchor + np.array(offset) * scale
            if not (box.x0 + 4 <= centre[0] <= box.x1 - 4 and box.y0 + 4 <= centre[1] <= box.y1 - 4):
                continue
            crowd = sum(abs(centre[0] - other[0]) < size[0] and abs(centre[1] - other[1]) < size[1]
                        for other in placed)
            if best is None or crowd < best[0]:
                best = (crowd, offset, centre)
            if crowd == 0:
                break
        if best is None:
            best = (0, (0, -11), anchor + np.array((0, -11)) * scale)
        placed.append(best[2])
        offsets.append(best[1])
    return offsets


def draw_hiz_walk(walk, depth, path, title=None, dpi=100):
    """Write the diagram of WALK (a HiZWalk) to PATH (PNG, 900 px wide); DEPTH is the frame's
    view depth (numpy, image order), drawn under the walk. Returns walk.summary().

    Three panels: the depth buffer seen from the camera around the ray, the visited cells
    outlined at their level's size; the side view along the ray's screen path (x: pixels
    from the ray's origin, y: view depth, the camera at the top) with the depth buffer under
    the path, each visited cell as a bar at its min depth over the stretch of ray inside it,
    numbered by iteration, and the ray; and the level at each iteration, which climbs,
    descends and stops at the hit.
    """
    pyplot = load_pyplot()
    from matplotlib.colors import ListedColormap, LogNorm
    from matplotlib.lines import Line2D
    from matplotlib.ticker import FormatStrFormatter, NullFormatter
    from matplotlib.patches import Patch, Rectangle

    depth = np.asarray(depth, np.float32)
    width, height = walk.size
    summary = walk.summary()
    levels = max([visit.level for visit in walk.visits], default=0) + 1
    palette = pyplot.get_cmap("plasma")
    level_colour = [palette(0.85 * level / max(levels - 1, 1)) for level in range(levels)]
    level_width = [1.5 + 1.5 * level for level in range(levels)]
    traced = walk.status != "no ray"

    figure = pyplot.figure(figsize=(9.0, 10.5), dpi=dpi)
    grid = figure.add_gridspec(3, 1, height_ratios=(3.0, 3.4, 1.8), hspace=0.42, left=0.08, right=0.70,
                               top=0.90, bottom=0.06)
    top, side, steps = (figure.add_subplot(grid[index]) for index in range(3))
    figure.suptitle(title or f"Hierarchical ray trace: the Hi-Z walk of pixel {walk.pixel}'s mirror ray\n"
                    f"{summary['caption']}", fontsize=13)

    t_end = walk.t_hit if walk.status == "hit" else max([v.t_next for v in walk.visits], default=0.0)
    foreground = depth < walk.clip_end
    near, far = (float(depth[foreground].min()), float(depth[foreground].max())) if foreground.any() else (1, 2)

    # Seen from the camera: image coordinates, x right, y down (a GL row y is image y = height - y).
    crop = _crop(walk, t_end)
    shown_depth = depth[int(crop[2]):int(math.ceil(crop[3])), int(crop[0]):int(math.ceil(crop[1]))]
    shown_depth = shown_depth[shown_depth < walk.clip_end]
    if shown_depth.size:  # the grey scale spans what the panel shows
        near, far = float(shown_depth.min()), float(shown_depth.max())
    near = max(near, 1e-6)
    far = max(far, near * 1.01)
    greys = ListedColormap(pyplot.get_cmap("Greys")(np.linspace(0.05, 0.7, 256)))
    shown = top.imshow(np.where(foreground, depth, np.nan), cmap=greys, norm=LogNorm(near, far),
                       extent=(0, width, height, 0), interpolation="nearest")
    top.set_facecolor("#d6e6f5")  # the world: no depth
    for visit in walk.visits:
        x0, y0, x1, y1 = visit.pixel_bounds()
        x1, y1 = min(x1, width), min(y1, height)
        top.add_patch(Rectangle((x0, height - y1), x1 - x0, y1 - y0, fill=visit.outcome == "hit",
                                facecolor="gold", edgecolor=level_colour[visit.level],
                                linewidth=level_width[visit.level] * 0.8, zorder=2 + visit.level))
    if traced:
        (sx, sy), (fx, fy) = walk.position_px(0.0), walk.position_px(t_end)
        top.plot([sx, fx], [height - sy, height - fy], color="deepskyblue", linewidth=1.3, zorder=20)
        top.plot(sx, height - sy, "o", color="deepskyblue", markeredgecolor="black", markersize=6, zorder=21)
        if walk.status == "hit":
            top.plot(fx, height - fy, "*", color="gold", markeredgecolor="black", markersize=15, zorder=21)
    top.set_xlim(crop[0], crop[1])
    top.set_ylim(crop[3], crop[2])
    top.set_title("Seen from the camera: the cells visited, at their level's size", fontsize=10)
    top.set_xlabel("pixel x")
    top.set_ylabel("pixel row")
    colourbar = figure.colorbar(shown, ax=top, fraction=0.04, pad=0.02)
    colourbar.set_label("view depth", fontsize=8)
    colourbar.ax.tick_params(labelsize=7)
    colourbar.set_ticks(sorted({float(f"{value:.2g}") for value in np.geomspace(near, far, 5)}))
    colourbar.ax.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    colourbar.ax.yaxis.set_minor_formatter(NullFormatter())

    # Side view along the ray.
    if traced:
        distance, profile = _path_depth_profile(walk, depth, max(t_end, 1e-6))
        surface = np.where(profile >= walk.clip_end, np.nan, profile.astype(np.float64))
    else:
        distance, surface = np.zeros(0), np.zeros(0)
    # Depths shown: the cells' and the ray's up to the deepest cell (a missing ray runs off the bottom).
    cells = [v.cell_depth for v in walk.visits if v.cell_depth < walk.clip_end]
    rays = [d for v in walk.visits for d in v.ray_depth] + ([walk.hit_depth] if walk.status == "hit" else [])
    deepest = max(cells + [walk.hit_depth]) + walk.thickness if cells else max(rays, default=far)
    low, high = min(cells + rays, default=near), max([d for d in rays if d <= deepest] + [deepest])
    margin = 0.08 * (high - low) + 1e-3
    side.set_ylim(high + margin, low - margin)  # the camera at the top
    sky_depth = high + 0.5 * margin  # where cells holding only the world are drawn
    side.fill_between(distance, surface, high + margin, color="0.85", step="mid", linewidth=0)
    side.fill_between(distance, surface, surface + walk.thickness, color="0.62", step="mid", linewidth=0)
    labels = []
    for visit in walk.visits:
        sky = visit.cell_depth >= walk.clip_end  # nothing but the world in the cell: drawn at the bottom
        bar_depth = sky_depth if sky else visit.cell_depth
        start, end = walk.screen_distance(visit.t), walk.screen_distance(visit.t_next)
        side.plot([start, end], [bar_depth] * 2, color=level_colour[visit.level], linestyle=":" if sky else "-",
                  linewidth=level_width[visit.level] + 1.0, solid_capstyle="butt", zorder=3)
        middle = 0.5 * (start + end)
        side.plot(middle, bar_depth, _OUTCOME_MARKERS[visit.outcome][0], color=level_colour[visit.level],
                  markeredgecolor="black", markersize=11 if visit.outcome == "hit" else 6, zorder=4)
        labels.append((visit.iteration, middle, bar_depth))
    x_span = max([float(walk.screen_distance(t_end))] + [x for _, x, _ in labels]) or 1.0
    side.set_xlim(0, x_span * 1.04)
    for (iteration, x, y), offset in zip(labels, _place_labels(side, [(x, y) for _, x, y in labels])):
        side.annotate(str(iteration), (x, y), xytext=offset, textcoords="offset points", ha="center",
                      va="center", fontsize=7, zorder=6)
    samples = {}
    for visit in walk.visits:
        samples[visit.t], samples[visit.t_next] = visit.ray_depth
    if walk.status == "hit":
        samples = {t: d for t, d in samples.items() if t <= walk.t_hit}
        samples[walk.t_hit] = walk.hit_depth
    if samples:
        ray_t, ray_depth = _ray_curve(samples, t_end)
        side.plot(walk.screen_distance(ray_t), ray_depth, color="deepskyblue", linewidth=1.8, zorder=5)
    if walk.status == "hit":
        side.plot(walk.screen_distance(walk.t_hit), walk.hit_depth, "*", color="gold", markeredgecolor="black",
                  markersize=16, zorder=7)
    side.set_title("Side view along the ray: each visited cell is a bar at its min depth", fontsize=10)
    side.set_xlabel("pixels along the ray's screen path")
    side.set_ylabel("view depth (camera at the top)")
    handles = [Line2D([], [], color="deepskyblue", linewidth=1.8, marker="o", markeredgecolor="black",
                      label="the ray (from its pixel)"),
               Line2D([], [], color="gold", marker="*", markeredgecolor="black", markersize=12, linestyle="",
                      label=f"hit: pixel {walk.hit_pixel}") if walk.status == "hit" else
               Line2D([], [], linestyle="", label=walk.ending()),
               Patch(color="0.62", label=f"surface + thickness ({walk.thickness:g})"),
               Patch(color="0.85", label="behind the surface")]
    handles += [Line2D([], [], color=level_colour[level], linewidth=level_width[level] + 1.0,
                       label=f"level {level}: {1 << level}x{1 << level} px cells") for level in range(levels)]
    if any(v.cell_depth >= walk.clip_end for v in walk.visits):
        handles.append(Line2D([], [], color="0.3", linestyle=":", linewidth=2.5, label="cell of world only"))
    side.legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.0), frameon=False)

    # Level at each iteration.
    steps.plot([v.iteration for v in walk.visits], [v.level for v in walk.visits], color="0.6", linewidth=1.0)
    for outcome, (marker, label) in _OUTCOME_MARKERS.items():
        chosen = [visit for visit in walk.visits if visit.outcome == outcome]
        colours = "gold" if outcome == "hit" else [level_colour[v.level] for v in chosen] or "white"
        steps.scatter([v.iteration for v in chosen], [v.level for v in chosen], marker=marker, c=colours,
                      edgecolors="black", s=110 if outcome == "hit" else 32, label=label, zorder=3)
    steps.set_yticks(range(levels))
    steps.set_ylim(-0.5, levels - 0.5)
    steps.set_xlim(0.3, max(walk.iterations, 1) + 0.7)
    steps.set_xlabel("iteration")
    steps.set_ylabel("level")
    steps.set_title(f"Level at each iteration: highest {walk.highest_level}; a pixel-by-pixel walk "
                    f"tests {walk.pixel_tests} pixels", fontsize=10)
    steps.legend(fontsize=8, loc="upper left", bbox_to_anchor=(1.02, 1.05), frameon=False)
    steps.grid(axis="y", color="0.9")

    save_figure(figure, path)
    return summary
