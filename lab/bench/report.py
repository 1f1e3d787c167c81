"""bench.json and bench.csv: the per-contender summary over the scenes, and writing every output."""
import csv
import os

import numpy as np

from ssr_addon.batch.outputs import write_json, written_together
from .charts import chart_speed_vs_accuracy, chart_stability, contact_sheet
from .metrics import ACCURACY_METRICS, _mean, pareto_front


def summarise_contenders(contenders, rows, copy_ms):
    """One entry per contender: its means over the scenes and whether it is on the Pareto front."""
    summary = []
    for contender in contenders:
        mine = [row for row in rows if row["contender"] == contender.name]
        stages = {stage: float(np.mean([row["stages_ms"].get(stage, 0.0) for row in mine]))
                  for stage in mine[0]["stages_ms"]}
        entry = {"name": contender.name, "method": contender.method, "settings": contender.overrides(),
                 "frame_ms": float(np.mean([row["frame_ms"] for row in mine])),
                 "addon_ms": float(np.mean([row["addon_ms"] for row in mine])),
                 "stages_ms": stages, "stages_x_copy": {s: ms / copy_ms for s, ms in stages.items()}}
        entry["frame_x_copy"] = entry["frame_ms"] / copy_ms
        for metric in ACCURACY_METRICS:
            entry[metric] = _mean([row[metric] for row in mine])
        summary.append(entry)
    scored = {e["name"]: (e["frame_ms"], e["flip_reflective"]) for e in summary if e["flip_reflective"] is not None}
    front = pareto_front(scored)
    for entry in summary:
        entry["pareto"] = entry["name"] in front
    return summary


CSV_METRICS = ("frame_ms", "addon_ms", "frame_x_copy", *ACCURACY_METRICS)


def write_outputs(report, sheet, out_dir):
    write_json(os.path.join(out_dir, "bench.json"), report)
    write_csv(os.path.join(out_dir, "bench.csv"), report)
    chart_speed_vs_accuracy(report, os.path.join(out_dir, "speed_vs_accuracy.png"))
    contact_sheet(sheet, os.path.join(out_dir, "contact_sheet.png"))
    if "stability" in report:
        chart_stability(report["stability"], os.path.join(out_dir, "stability.png"))


def write_csv(path, report):
    """One row per scene and contender, then one per contender over all scenes (scene "mean")."""
    stages = list(dict.fromkeys(stage for row in report["results"] for stage in row["stages_ms"]))
    header = ["scene", "contender", "method", *CSV_METRICS, "pareto",
              *(f"{stage}_ms" for stage in stages), *(f"{stage}_x_copy" for stage in stages)]
    pareto = {entry["name"]: entry["pareto"] for entry in report["contenders"]}
    lines = [dict(row, pareto=pareto[row["contender"]]) for row in report["results"]]
    lines += [dict(entry, scene="mean", contender=entry["name"]) for entry in report["contenders"]]
    with written_together([path]) as (partial,), open(partial, "w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(header)
        for line in lines:
            writer.writerow([line["scene"], line["contender"], line["method"],
                             *(_csv_value(line[m]) for m in CSV_METRICS), line["pareto"],
                             *(_csv_value(line["stages_ms"].get(s)) for s in stages),
                             *(_csv_value(line["stages_x_copy"].get(s)) for s in stages)])


def _csv_value(value):
    return "" if value is None else f"{value:.6g}"
