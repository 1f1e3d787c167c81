"""report.json: what the runs rendered into an output folder, and whether a new run may carry on there.

A run is identified by its fingerprint: the scene (path and content hash), the
method, engine, comparison mode, chain settings, resolution, samples, file
prefix and add-on version. A new run resumes a folder (keeps its complete
frames) only when its fingerprint is the old one; otherwise it refuses, naming
what differs, unless told to overwrite, which first removes the earlier run's
frames. The report keeps every frame's entry across resumes and is strict JSON.

Several runs may render disjoint frame ranges of one shot into one folder at once
(a render farm's chunks, `farm`): each keeps its own record of its range
(RECORDS_FOLDER/frames_A-B.json, replaced whole after every frame), and report.json
is their merge, rewritten under the folder's lock, so no writer loses another's frames.
"""
import fcntl
import hashlib
import json
import os
import platform
import tomllib
from contextlib import contextmanager
from dataclasses import asdict

from ..core.errors import SSRError
from .outputs import write_json

REPORT_NAME = "report.json"
RECORDS_FOLDER = ".ssr_records"  # one record per run's frame range, and the folder's lock
LOCK_NAME = "lock"
MERGED_LISTS = ("frames", "failed_frames", "warnings", "runs")  # merged entry by entry, not replaced
OUTPUT_SUFFIXES = (".exr", ".png", ".passes.exr")
# The extension root, two packages up: ssr_addon/batch/ -> the folder holding blender_manifest.toml.
MANIFEST = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                        "blender_manifest.toml")
OVERWRITE_HINT = "render with --overwrite (in Blender: Output properties > Overwrite) or into another folder"


def addon_version():
    with open(MANIFEST, "rb") as stream:
        return tomllib.load(stream)["version"]


def scene_identity(scene_path, unsaved_changes=False):
    """{"path", "sha256"} of the scene file; sha256 is None when the file on disk is not what renders."""
    if not scene_path or unsaved_changes or not os.path.isfile(scene_path):
        return {"path": scene_path or None, "sha256": None}
    digest = hashlib.sha256()
    with open(scene_path, "rb") as stream:
        for block in iter(lambda: stream.read(1 << 20), b""):
            digest.update(block)
    return {"path": os.path.abspath(scene_path), "sha256": digest.hexdigest()}


def fingerprint(scene, request, resolution, samples):
    """Everything that decides a run's frames. SCENE is scene_identity's."""
    return {"scene": scene, "method": request.method, "engine": request.engine, "mode": request.mode,
            "settings": asdict(request.settings), "resolution": list(resolution), "samples": samples,
            "file_prefix": request.file_prefix, "addon_version": addon_version()}


def frame_paths(out_dir, prefix, frame):
    stem = os.path.join(out_dir, f"{prefix}{frame:04d}")
    return [stem + suffix for suffix in OUTPUT_SUFFIXES]


def is_complete(out_dir, prefix, frame):
    return all(os.path.isfile(path) for path in frame_paths(out_dir, prefix, frame))


def _differences(old, new):
    if old.get("scene", {}).get("sha256") is None or new["scene"]["sha256"] is None:
        yield "the scene is unsaved or was never saved, so its frames cannot be matched"
    for key, value in new.items():
        if old.get(key) != value:
            if isinstance(value, dict) and isinstance(old.get(key), dict):
                inner = sorted(name for name in set(value) | set(old[key]) if old[key].get(name) != value.get(name))
                yield f"{key} ({', '.join(inner)})"
            else:
                yield f"{key} ({old.get(key)} -> {value})"


def _read_json(path):
    try:
        with open(path, encoding="utf-8") as stream:
            return json.load(stream)
    except (OSError, ValueError) as error:
        raise SSRError(f"cannot read {path} ({error}): {OVERWRITE_HINT}") from None


def _record_paths(out_dir):
    folder = os.path.join(out_dir, RECORDS_FOLDER)
    names = sorted(name for name in os.listdir(folder) if name.endswith(".json")) if os.path.isdir(folder) else []
    return [os.path.join(folder, name) for name in names]


def read_report(out_dir):
    """What the runs in OUT_DIR rendered: report.json merged with every run's record, {} when
    there is none; a damaged one is an error."""
    path = os.path.join(out_dir, REPORT_NAME)
    reports = [_read_json(path)] if os.path.exists(path) else []
    reports += [_read_json(record) for record in _record_paths(out_dir)]
    return merge_reports(reports)


def merge_reports(reports):
    """One report of REPORTS (report.json's and the runs' records): each run-level entry as the
    last report holding it has it, every frame's newest entry, the failures no run has since
    rendered, and each run's range, machine and GPU under "runs"."""
    if not reports:
        return {}
    merged, frames, failed, warnings, runs = {}, {}, {}, [], {}
    for report in reports:
        merged.update((key, value) for key, value in report.items() if key not in MERGED_LISTS)
        frames.update((entry["frame"], entry) for entry in report.get("frames", []))
        failed.update((entry["frame"], entry) for entry in report.get("failed_frames", []))
        warnings += [warning for warning in report.get("warnings", []) if warning not in warnings]
        runs.update(((run["host"], run["frames"]), run) for run in report.get("runs", []))
    merged["frames"] = [entry for _, entry in sorted(frames.items())]
    merged["failed_frames"] = [entry for frame, entry in sorted(failed.items()) if frame not in frames]
    merged["runs"] = list(runs.values())
    if warnings:
        merged["warnings"] = warnings
    summary = cost_summary(merged["frames"])
    if summary:
        merged["mean_ms_per_frame"] = summary
    return merged


def cost_summary(frames):
    """The add-on's mean cost per frame beside the render's, over the FRAMES entries timed; None if none is."""
    timed = [entry for entry in frames if "addon_ms" in entry]
    if not timed:
        return None
    render_ms = sum(entry["render_ms"] for entry in timed) / len(timed)
    addon_ms = sum(entry["addon_ms"] for entry in timed) / len(timed)
    return {"render": round(render_ms, 1), "addon": round(addon_ms, 1),
            "addon_over_render": round(addon_ms / render_ms, 4)}


def remove_run(out_dir, report=None):
    """Remove what the runs of OUT_DIR's REPORT (default: read_report's) wrote: frames, records, report."""
    report = read_report(out_dir) if report is None else report
    prefix = report.get("fingerprint", {}).get("file_prefix", "frame_")
    written = [path for entry in report.get("frames", []) for path in frame_paths(out_dir, prefix, entry["frame"])]
    for path in written + _record_paths(out_dir) + [os.path.join(out_dir, REPORT_NAME)]:
        if os.path.exists(path):
            os.remove(path)


class FolderRecords:
    """An output folder shared by the runs that render disjoint frame ranges of one shot into it.

    FRAMES: this run's frames. Every change is made under the folder's lock (an advisory
    fcntl lock on a file in RECORDS_FOLDER): claiming the folder, and writing this run's
    record and the merged report.json.
    """

    def __init__(self, out_dir, frames):
        self.out_dir = out_dir
        self.folder = os.path.join(out_dir, RECORDS_FOLDER)
        self.frames = set(frames)
        self.record_path = os.path.join(self.folder, f"frames_{min(frames):04d}-{max(frames):04d}.json")
        self.machine = {"host": platform.node(), "frames": f"{min(frames)}-{max(frames)}"}

    @contextmanager
    def locked(self):
        """Hold the folder's lock: a POSIX record lock (lockf), which network file systems carry
        between machines, where flock may lock only this machine's processes out."""
        os.makedirs(self.folder, exist_ok=True)
        with open(os.path.join(self.folder, LOCK_NAME), "a+") as lock:
            fcntl.lockf(lock, fcntl.LOCK_EX)
            try:
                yield
            finally:
                fcntl.lockf(lock, fcntl.LOCK_UN)

    def claim(self, new_fingerprint, overwrite):
        """Make the folder this run's: the entries of its complete frames to keep (frame -> entry).

        Same fingerprint: keep every complete frame's entry. Different, or frames without a
        report: refuse, unless OVERWRITE, which removes the earlier runs' frames and records.
        The fingerprint is recorded before the lock is let go, so a run starting beside this one
        is checked against it.
        """
        try:
            with self.locked():
                kept = self._claim(new_fingerprint, overwrite)
                self._write_record({"fingerprint": new_fingerprint,
                                    "frames": [entry for frame, entry in kept.items() if frame in self.frames]})
        except SSRError:
            if os.listdir(self.folder) == [LOCK_NAME]:  # a refused folder keeps nothing of this run
                os.remove(os.path.join(self.folder, LOCK_NAME))
                os.rmdir(self.folder)
            raise
        return kept

    def _claim(self, new_fingerprint, overwrite):
        old = read_report(self.out_dir)
        out_dir, prefix = self.out_dir, new_fingerprint["file_prefix"]
        if not old:
            strangers = [frame for frame in sorted(self.frames)
                         if any(os.path.exists(path) for path in frame_paths(out_dir, prefix, frame))]
            if strangers and not overwrite:
                raise SSRError(f"{out_dir} already holds frames ({', '.join(map(str, strangers[:5]))}) but no "
                               f"{REPORT_NAME} says how they were made: {OVERWRITE_HINT}")
            return {}
        if overwrite:
            remove_run(out_dir, old)
            return {}
        differences = list(_differences(old.get("fingerprint", {}), new_fingerprint))
        if differences:
            raise SSRError(f"{out_dir} holds another run (differs in: {'; '.join(differences)}): {OVERWRITE_HINT}")
        return {entry["frame"]: entry for entry in old.get("frames", [])
                if is_complete(out_dir, prefix, entry["frame"])}

    def write(self, report):
        """Record REPORT's entries for this run's frames, then rewrite report.json as the merge of
        every run's record."""
        with self.locked():
            self._write_record(report)
            write_json(os.path.join(self.out_dir, REPORT_NAME), read_report(self.out_dir))

    def _write_record(self, report):
        record = {**report, "runs": [{**self.machine, "blender": report.get("blender"), "gpu": report.get("gpu")}],
                  "frames": [entry for entry in report.get("frames", []) if entry["frame"] in self.frames],
                  "failed_frames": [entry for entry in report.get("failed_frames", [])
                                    if entry["frame"] in self.frames]}
        write_json(self.record_path, record)
