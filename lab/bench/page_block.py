"""The bench's generated block of the measurements page: the chart, the contender, stage and
stability tables."""
import os
import shlex

from ..docs import page_link, rewrite_block
from .metrics import MIN_SPECULAR_COLOR
from .scenes import REPO
from .speed import COPY_PASS_LARGE, _size_label

PAGE_BLOCK = "bench"  # the page's generated block: <!-- bench:start --> ... <!-- bench:end -->

# The goals of the "Right before new" and "Cost" issues, on every scene: our balanced
# preset's error on reflective pixels at most this share of EEVEE's own screen-space ray
# tracing's, at most this multiple of its wall time per frame.
VERSUS_EEVEE_GOAL = 0.8
VERSUS_EEVEE_TIME_GOAL = 1.15


def versus_eevee(rows, ours="ssr balanced", theirs="eevee-rt"):
    """Per scene: (FLIP ours, FLIP theirs, rel. MAE ours, rel. MAE theirs) on reflective pixels,
    then (ms per frame ours, theirs)."""
    by_key = {(row["scene"], row["contender"]): row for row in rows}
    table = {}
    for scene in dict.fromkeys(row["scene"] for row in rows):
        mine, other = by_key.get((scene, ours)), by_key.get((scene, theirs))
        if mine and other and None not in (mine["flip_reflective"], other["flip_reflective"]):
            table[scene] = (mine["flip_reflective"], other["flip_reflective"],
                            mine["mae_reflective"], other["mae_reflective"], mine["frame_ms"], other["frame_ms"])
    return table


def _versus_eevee_lines(report):
    table = versus_eevee(report["results"])
    if not table:
        return []
    lines = ["", f"Per scene, `ssr balanced` against EEVEE's screen-space ray tracing (`eevee-rt`): error on the "
                 f"reflective pixels (the goal is a ratio of at most {VERSUS_EEVEE_GOAL}) and wall time per frame "
                 f"(at most {VERSUS_EEVEE_TIME_GOAL}x):", "",
             "| scene | FLIP ours | FLIP eevee-rt | ratio | rel. MAE ours | rel. MAE eevee-rt | ratio "
             "| ms ours | ms eevee-rt | ratio |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for scene, (flip_ours, flip_eevee, mae_ours, mae_eevee, ms_ours, ms_eevee) in table.items():
        lines.append(f"| {scene} | {flip_ours:.4f} | {flip_eevee:.4f} | {flip_ours / flip_eevee:.2f} | "
                     f"{mae_ours:.4f} | {mae_eevee:.4f} | {mae_ours / mae_eevee:.2f} | "
                     f"{ms_ours:.0f} | {ms_eevee:.0f} | {ms_ours / ms_eevee:.2f} |")
    return lines


def _contenders_argument(report):
    patterns = report.get("contender_patterns")
    return " --contenders " + " ".join(shlex.quote(p) for p in patterns) if patterns else ""


def bench_block(report, out_dir, page):
    """Markdown for PAGE: the chart, the contender table and the stability table."""
    folder = page_link(page, out_dir).replace(os.sep, "/")
    width, height = report["resolution"]
    copy_ms = report["copy_pass_ms"][f"{width}x{height}"]
    lines = [
        f"Latest run: `python -m lab bench --scenes {' '.join(report['scenes'])} "
        f"--resolution {width}x{height} --frames {report['frames_per_contender']} "
        f"--out {os.path.relpath(os.path.abspath(out_dir), REPO)} --page docs/measurements.md"
        f"{_contenders_argument(report)}` on "
        f"Blender {report['blender']}, "
        f"{report['gpu']['renderer']}{_gpu_note(report['gpu']['renderer'])}. Reference: Cycles, "
        f"{report['reference']['samples']} samples; EEVEE: {report['eevee_samples']} samples. Time: wall time "
        f"per frame of the whole method, engine render included; *add-on ms*: our own share of it, everything "
        f"but the engine's render (in scenes with lamps SSR splits their highlights off: `lamp_split`, "
        f"counted here); the contenders take turns over {report['frames_per_contender']} frames; after the "
        f"first, every other frame times each stage apart (a GPU wait after each: the stage table) and the "
        f"rest run as a render does (the times per frame); each counts its fastest; ×copy: as a multiple of a "
        f"full-screen copy pass ({copy_ms:.3f} ms here, "
        f"{report['copy_pass_ms'][_size_label(COPY_PASS_LARGE)]:.3f} ms at 1600x900). Errors: mean over the "
        f"scenes, on the last frame; *refl.* is the reflective pixels (roughness ≤ "
        f"{report['reflective_mask']['max_roughness']}, specular colour ≥ {MIN_SPECULAR_COLOR}).",
        "",
        f"![speed vs accuracy]({folder}/speed_vs_accuracy.png)",
        "",
        "| contender | ms/frame | add-on ms | ×copy | FLIP refl. | rel. MAE refl. | FLIP all | PSNR refl. | SSIM refl. "
        "| Pareto |",
        "|---|---:|---:|---:|---:|---:|---:|---:|---:|:-:|",
    ]
    for entry in report["contenders"]:
        lines.append(f"| {entry['name']} | {entry['frame_ms']:.0f} | {entry['addon_ms']:.0f} | "
                     f"{entry['frame_x_copy']:.0f} | "
                     f"{_cell(entry['flip_reflective'], 4)} | {_cell(entry['mae_reflective'], 4)} | "
                     f"{_cell(entry['flip_all'], 4)} | "
                     f"{_cell(entry['psnr_reflective'], 2)} | {_cell(entry['ssim_reflective'], 3)} | "
                     f"{'✓' if entry['pareto'] else ''} |")
    lines += _versus_eevee_lines(report)
    ours = [e for e in report["contenders"] if e["method"] == "ssr"]
    if ours:
        stages = [s for s in ours[0]["stages_ms"] if s != "render"]
        lines += ["", "Stages of ours (ms, ×copy):", "",
                  "| contender | " + " | ".join(stages) + " |", "|---|" + "---:|" * len(stages)]
        for entry in ours:
            lines.append(f"| {entry['name']} | " + " | ".join(
                f"{entry['stages_ms'].get(s, 0):.2f} ({entry['stages_x_copy'].get(s, 0):.1f})" for s in stages) + " |")
    if "stability" in report:
        limits = report["stability"]["limits"]
        lines += ["", f"Stability cases over frames {'-'.join(map(str, report['stability']['frames']))}, with the "
                      f"limits the tests assert: FLIP at most the fallback's + {limits['fallback_margin_flip']}, "
                      f"energy excess at most {limits['energy_tolerance']}, seam below {limits['seam']}, "
                      f"flicker below {limits['flicker']}, hit-point ghosting below surface-point ghosting.",
                  "", f"![stability]({folder}/stability.png)", "",
                  "| case | motion | finite | FLIP ssr | FLIP fallback | energy excess | seam | flicker (temporal off) "
                  "| ghosting FLIP hit / surface |",
                  "|---|---|:-:|---:|---:|---:|---:|---:|---:|"]
        for case, values in report["stability"]["cases"].items():
            flicker_cell = _cell(values.get("flicker"), 4)
            if values.get("flicker_temporal_off") is not None:
                flicker_cell += f" ({_cell(values['flicker_temporal_off'], 4)})"
            ghosting = (f"{_cell(values.get('ghosting_flip_hit'), 4)} / {_cell(values.get('ghosting_flip_surface'), 4)}"
                        if values.get("ghosting_flip_hit") is not None else "-")
            lines.append(f"| {case.removeprefix('stability_')} | {values['motion'] or 'static'} | "
                         f"{'yes' if values['finite'] else '**NO**'} | {_cell(values['flip_ssr_mean'], 4)} | "
                         f"{_cell(values['flip_fallback_mean'], 4)} | {_cell(values['energy_excess_max'], 4)} | "
                         f"{_cell(values['seam_max'], 3)} | {flicker_cell} | {ghosting} |")
    lines += ["", f"Contact sheet (every contender beside the reference, FLIP error maps): "
                  f"[{folder}/contact_sheet.png]({folder}/contact_sheet.png)"]
    return "\n".join(lines)


def _cell(value, digits):
    return "-" if value is None else f"{value:.{digits}f}"


def _gpu_note(renderer):
    return ": a software GPU, so every engine render is slow" if "llvmpipe" in renderer.lower() else ""


def update_page(page, report, out_dir):
    """Replace the bench block of PAGE (adding it under '## Benchmark' if absent)."""
    rewrite_block(page, PAGE_BLOCK, bench_block(report, out_dir, page), "Benchmark")
