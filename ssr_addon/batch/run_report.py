"""report.json: what a run rendered into an output folder, and whether a new run may carry on there.

A run is identified by its fingerprint: the scene (path and content hash), the
method, engine, comparison mode, chain settings, resolution, samples, file
prefix and add-on version. A new run resumes a folder (keeps its complete
frames) only when its fingerprint is the old one; otherwise it refuses, naming
what differs, unless told to overwrite, which first removes the earlier run's
frames. The report keeps every frame's entry across resumes and is strict JSON.
"""
import hashlib
import json
import os
import tomllib
from dataclasses import asdict

from ..core.errors import SSRError

REPORT_NAME = "report.json"
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


def read_report(out_dir):
    """The earlier run's report, {} when there is none; a damaged one is an error."""
    path = os.path.join(out_dir, REPORT_NAME)
    if not os.path.exists(path):
        return {}
    try:
        with open(path, encoding="utf-8") as stream:
            return json.load(stream)
    except (OSError, ValueError) as error:
        raise SSRError(f"cannot read {path} ({error}): {OVERWRITE_HINT}") from None


def claim_folder(out_dir, new_fingerprint, frames, overwrite):
    """Make OUT_DIR this run's: the earlier report's entries to keep (frame -> entry).

    Same fingerprint: keep every complete frame's entry. Different, or frames
    without a report: refuse, unless OVERWRITE, which removes the earlier run's frames.
    """
    old = read_report(out_dir)
    prefix = new_fingerprint["file_prefix"]
    if not old:
        strangers = [frame for frame in frames if any(os.path.exists(path)
                                                      for path in frame_paths(out_dir, prefix, frame))]
        if strangers and not overwrite:
            raise SSRError(f"{out_dir} already holds frames ({', '.join(map(str, strangers[:5]))}) but no "
                           f"{REPORT_NAME} says how they were made: {OVERWRITE_HINT}")
        return {}
    if overwrite:
        for entry in old.get("frames", []):
            for path in frame_paths(out_dir, old.get("fingerprint", {}).get("file_prefix", prefix), entry["frame"]):
                if os.path.exists(path):
                    os.remove(path)
        return {}
    differences = list(_differences(old.get("fingerprint", {}), new_fingerprint))
    if differences:
        raise SSRError(f"{out_dir} holds another run (differs in: {'; '.join(differences)}): {OVERWRITE_HINT}")
    return {entry["frame"]: entry for entry in old.get("frames", []) if is_complete(out_dir, prefix, entry["frame"])}
