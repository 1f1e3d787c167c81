"""The charts: speed against accuracy, the contact sheet, the stability cases, stage costs and costs
against a count (matplotlib, Agg)."""
import numpy as np

from ssr_addon.batch.outputs import written_together
from .images import display
from .stability import FLICKER_LIMIT, SEAM_LIMIT


def load_pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as pyplot
    return pyplot


def save_figure(figure, path, palette=False):
    """Write FIGURE as a PNG, atomically; PALETTE: 256 colours (a contact sheet shrinks about threefold)."""
    with written_together([path]) as (partial,):
        if palette:
            from PIL import Image  # matplotlib's own image library
            figure.canvas.draw()
            pixels = np.asarray(figure.canvas.buffer_rgba())[..., :3]
            Image.fromarray(pixels).quantize(colors=256).save(partial, format="PNG", optimize=True)
        else:
            figure.savefig(partial, format="png")
    load_pyplot().close(figure)


def chart_speed_vs_accuracy(report, path):
    """Milliseconds per frame against FLIP on reflective pixels, one point per contender, Pareto front joined."""
    pyplot = load_pyplot()
    entries = [e for e in report["contenders"] if e["flip_reflective"] is not None]
    figure, axes = pyplot.subplots(figsize=(9, 4.5), dpi=100)
    # Points carry numbers, named beside the plot: the names would overlap where points crowd.
    for number, entry in enumerate(entries, 1):
        colour = "tab:red" if entry["pareto"] else "tab:blue"
        axes.scatter(entry["frame_ms"], entry["flip_reflective"], color=colour, zorder=3,
                     label=f"{number}  {entry['name']}")
        axes.annotate(str(number), (entry["frame_ms"], entry["flip_reflective"]), fontsize=7,
                      xytext=(4, 3), textcoords="offset points")
    front = sorted((e for e in entries if e["pareto"]), key=lambda e: e["frame_ms"])
    axes.step([e["frame_ms"] for e in front], [e["flip_reflective"] for e in front], where="post",
              color="tab:red", linewidth=1, label="Pareto front")
    reference_ms = [info["render_ms"] for info in report["reference"]["per_scene"].values()]
    axes.axvline(np.mean(reference_ms), color="grey", linestyle="--", linewidth=1,
                 label=f"Cycles reference ({report['reference']['samples']} spp, error 0 by definition)")
    axes.set_xscale("log")
    axes.set_xlabel("wall time per frame, whole method (ms, log scale)")
    axes.set_ylabel("mean FLIP on reflective pixels (lower is better)")
    width, height = report["resolution"]
    axes.set_title(f"Speed vs accuracy at {width}x{height}, mean over {', '.join(report['scenes'])}", fontsize=9)
    axes.grid(True, which="both", alpha=0.3)
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), frameon=False)
    figure.tight_layout()
    save_figure(figure, path)


def contact_sheet(sheet, path):
    """Every contender beside the reference, per scene: the image and its FLIP error map.

    The reference row shows the reflective-pixel mask in place of an error map.
    """
    pyplot = load_pyplot()
    from matplotlib import colormaps
    scenes = list(sheet)
    names = list(sheet[scenes[0]])
    height, width = sheet[scenes[0]]["reference"][0].shape[:2]
    dpi = 100
    label_inches, tile_inches = 2.0, (width / dpi, height / dpi)
    figure = pyplot.figure(figsize=(label_inches + 2 * len(scenes) * tile_inches[0],
                                    (len(names) + 0.3) * tile_inches[1]), dpi=dpi)
    for row, name in enumerate(names):
        for column, scene in enumerate(scenes):
            image, second = sheet[scene][name]
            tiles = (display(image), np.repeat(second[..., None], 3, -1).astype(np.float32) if name == "reference"
                     else colormaps["magma"](np.clip(second, 0, 1))[..., :3])
            for offset, tile in enumerate(tiles):
                left = (label_inches + (2 * column + offset) * tile_inches[0]) / figure.get_figwidth()
                bottom = 1 - (row + 1.3) * tile_inches[1] / figure.get_figheight()
                axes = figure.add_axes((left, bottom, tile_inches[0] / figure.get_figwidth(),
                                        tile_inches[1] / figure.get_figheight()))
                axes.imshow(tile, interpolation="nearest")
                axes.set_axis_off()
                if row == 0:
                    axes.set_title(f"{scene}: {('image', 'mask / FLIP')[offset]}", fontsize=6, pad=2)
        figure.text(0.01, 1 - (row + 0.8) * tile_inches[1] / figure.get_figheight(), name, fontsize=7,
                    va="center")
    save_figure(figure, path, palette=True)


def chart_stability(stability, path):
    """Per case: error against the fallback's, seam strength, flicker and ghosting, with the tested limits."""
    pyplot = load_pyplot()
    cases = stability["cases"]
    names = [case.removeprefix("stability_") for case in cases]
    positions = np.arange(len(cases))
    figure, axes = pyplot.subplots(2, 2, figsize=(10, 6), dpi=80)

    def values(key):
        return [np.nan if cases[c].get(key) is None else cases[c][key] for c in cases]

    def bars(panel, title, series, limit=None):
        """SERIES: (key, label) pairs, drawn side by side per case; LIMIT: the tested limit."""
        width = 0.8 / len(series)
        for index, (key, label) in enumerate(series):
            panel.bar(positions + (index - (len(series) - 1) / 2) * width, values(key), width, label=label)
        if limit is not None:
            panel.axhline(limit, color="tab:red", linestyle="--", linewidth=1, label="test limit")
        panel.set_title(title, fontsize=9)
        if any(label for _, label in series) or limit is not None:
            panel.legend(fontsize=7)
    bars(axes[0, 0], "mean FLIP on reflective pixels vs Cycles",
         (("flip_ssr_mean", "ssr"), ("flip_fallback_mean", "probe/world fallback")))
    bars(axes[0, 1], "seam strength (0 smooth fade, 1 one-pixel cut)", (("seam_max", None),), SEAM_LIMIT)
    bars(axes[1, 0], "flicker, static scenes (relative frame-to-frame change)",
         (("flicker", "default"), ("flicker_temporal_off", "temporal off")), FLICKER_LIMIT)
    bars(axes[1, 1], "ghosting: FLIP vs per-frame references, frames 2+",
         (("ghosting_flip_hit", "reproject hit point"), ("ghosting_flip_surface", "reproject surface point")))
    for panel in axes.ravel():
        panel.set_xticks(positions, names, fontsize=7, rotation=20)
        panel.tick_params(axis="y", labelsize=7)
    figure.tight_layout()
    save_figure(figure, path)


def chart_stage_costs(stages, deck, path, title):
    """Bars of each stage's cost in full-screen copy passes (STAGES: {stage: copies}), the total
    beside it, and DECK's ({label: copies}) for comparison."""
    pyplot = load_pyplot()
    labels = [*stages, "total", *deck]
    values = [*stages.values(), sum(stages.values()), *deck.values()]
    colours = ["tab:blue"] * len(stages) + ["tab:red"] + ["tab:grey"] * len(deck)
    figure, axes = pyplot.subplots(figsize=(9, 3.6), dpi=100)
    axes.bar(range(len(values)), values, color=colours)
    for position, value in enumerate(values):
        axes.annotate(f"{value:.1f}", (position, value), ha="center", va="bottom", fontsize=8)
    axes.set_xticks(range(len(labels)), labels, fontsize=8, rotation=20)
    axes.set_ylabel("full-screen copy passes")
    axes.set_title(title, fontsize=9)
    axes.grid(True, axis="y", alpha=0.3)
    figure.tight_layout()
    save_figure(figure, path)


def chart_cost_by_count(counts, curves, path, x_label, y_label, title):
    """Lines of each curve's cost (CURVES: {label: [cost per count]}) against COUNTS."""
    pyplot = load_pyplot()
    figure, axes = pyplot.subplots(figsize=(9, 3.6), dpi=100)
    for label, costs in curves.items():
        axes.plot(counts, costs, marker="o", label=label)
        axes.annotate(f"{costs[-1]:.0f}", (counts[-1], costs[-1]), textcoords="offset points", xytext=(4, 0),
                      fontsize=8, va="center")
    axes.set_xlabel(x_label)
    axes.set_ylabel(y_label)
    axes.set_ylim(bottom=0)
    axes.set_title(title, fontsize=9)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=8)
    figure.tight_layout()
    save_figure(figure, path)
