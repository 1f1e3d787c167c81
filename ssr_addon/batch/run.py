"""The frame loop: every requested frame of a scene rendered in order with temporal history,
written whole, resumable, with progress and a report (report.json)."""
import ctypes
import ctypes.util
import functools

import bpy

from ..blender.lamp_renders import lamp_world_for_run
from ..blender.render_setup import render_samples, render_size
from ..blender.scene_io import require_camera, require_square_pixels
from ..core.chain import ChainState
from ..core.errors import SSRError
from ..core.gpu_backend import describe_gpu
from .frame import FrameFallbacks, render_frame, write_frame
from .outputs import prepare_output_folder, remove_partials, signals_held
from .progress_bar import FrameProgress
from .request import DEFAULT_WARMUP_FRAMES, frame_numbers
from .run_report import FolderRecords, cost_summary, fingerprint, frame_paths, scene_identity


def return_large_buffers_to_the_system():
    """Serve every allocation over 1 MiB with its own mapping (glibc), freed back at once.

    Each frame allocates and frees tens of full-resolution buffers; glibc's
    adaptive threshold otherwise moves them onto the heap after the first free,
    where fragmentation grows resident memory ~10 MiB a frame at 1600x900
    (python -m lab memory).
    """
    libc_name = ctypes.util.find_library("c")
    if libc_name and hasattr(ctypes.CDLL(libc_name), "mallopt"):
        m_mmap_threshold = -3
        ctypes.CDLL(libc_name).mallopt(m_mmap_threshold, 1 << 20)


class RenderRun:
    """One run of REQUEST over SCENE's frames into request.out_dir, carrying temporal history.

    Made before anything renders: it checks the scene and claims the output
    folder (run_report: resume a matching run, refuse a different one; other runs
    may write other frames of the shot there at the same time). `frames()` renders
    and writes the frames one at a time, yielding each (frame, images) once written,
    so a modal operator can step it; the run's report is in `report` (the folder's
    report.json, every run's frames, is rewritten after every frame).
    Before the first frame it renders, the run renders the request's warm-up frames
    without writing them, so that frame carries the history an uninterrupted run would.
    RENDER(scene, request, state, fallbacks) renders one frame (default render_frame; an
    operator's applies a comparison baseline first) with the run's FrameFallbacks: the levels
    decided on the first frame, captures reused from frame to frame while nothing they show moves. UNSAVED_CHANGES: the scene file on
    disk is not what renders, so the run can never be resumed.
    """

    def __init__(self, scene, scene_path, request, log=print, progress_stream=None, render=None,
                 unsaved_changes=False):
        require_camera(scene)
        require_square_pixels(scene)
        self.scene, self.request, self.log, self.render = scene, request, log, render
        self.progress_stream = progress_stream
        self.frame_list = frame_numbers(scene, request.frames)
        prepare_output_folder(request.out_dir, remove_leftovers=False)  # other runs may be writing there
        return_large_buffers_to_the_system()
        samples = render_samples(scene, request.engine, request.samples)
        identity = fingerprint(scene_identity(scene_path, unsaved_changes), request,
                               render_size(scene, request.resolution), samples)
        self.records = FolderRecords(request.out_dir, self.frame_list)
        kept = self.records.claim(identity, request.overwrite)
        self.todo = [f for f in self.frame_list if f not in kept]
        for frame in self.todo:  # what an interrupted run left of this run's frames
            remove_partials(frame_paths(request.out_dir, request.file_prefix, frame))
        self.report = {
            "fingerprint": identity,
            "scene": scene_path, "method": request.method, "engine": request.engine, "samples": samples,
            "blender": bpy.app.version_string, "gpu": None,
            "frames": [entry for _, entry in sorted(kept.items())],
            "failed_frames": [],
        }

    def frames(self):
        request = self.request
        if not self.todo:
            self.log(f"all {len(self.frame_list)} frames are already complete in {request.out_dir}")
            return
        first_missing = self.todo[0]
        warmup = self._warmup_frames(first_missing)
        if len(self.todo) < len(self.frame_list):
            self.log(f"resuming at frame {first_missing}: {len(self.frame_list) - len(self.todo)} complete frames "
                     f"kept, history re-warmed over {len(warmup)} frames")
        elif warmup:
            self.log(f"history warmed over frames {warmup[0]}-{warmup[-1]} (rendered, not written)")
        # One frame is a still (accumulated until converged); a range, or a frame after warm-up
        # frames, is an animation whose history carries from frame to frame, reset on a jump in
        # the range or a camera cut.
        state = ChainState.still() if len(self.frame_list) == 1 and not warmup else ChainState()
        fallbacks = FrameFallbacks() if request.method == "ssr" else None
        render = functools.partial(self.render or render_frame, fallbacks=fallbacks)
        try:
            with lamp_world_for_run():
                yield from self._render_frames(warmup, first_missing, state, render)
        finally:
            if fallbacks is not None:
                fallbacks.release()
        _summarise(self.report, self.log)
        self.records.write(self.report)
        failed = self.report["failed_frames"]
        if failed:
            raise SSRError(f"{len(failed)} frame(s) failed: {', '.join(str(entry['frame']) for entry in failed)}")

    def _render_frames(self, warmup, first_missing, state, render):
        request, scene = self.request, self.scene
        warned = set()
        progress = None  # started at the first written frame, so warm-up does not skew the ETA
        for frame in warmup + self.todo:
            scene.frame_set(frame)
            state.begin_frame(frame, scene.camera.name if scene.camera else None)
            if frame == first_missing:
                progress = FrameProgress(len(self.todo), self.progress_stream)
            try:
                images, timer = render(scene, request, state)
                self._warn_once(images.passes, warned)
                if frame in warmup:
                    continue
                with signals_held():  # a frame on disk is a frame in the report
                    written = write_frame(request.out_dir, frame, images, scene, request.file_prefix)
                    timer.lap("write")
                    self.log(f"Saved: '{written}'")  # Blender's own line, which a farm's worker reads
                    self._record(frame, images, timer, progress)
            except SSRError as error:
                if request.on_error == "stop" or frame in warmup:
                    raise
                self.log(f"frame {frame} failed: {error}; going on (--on-error skip)")
                self.report["failed_frames"].append({"frame": frame, "error": str(error)})
                state.reset_history()
                progress.frame_done(frame, "failed")
                self.records.write(self.report)
                continue
            yield frame, images

    def _warmup_frames(self, first):
        """The frames before FIRST, within the scene, that give it an uninterrupted run's history."""
        request = self.request
        if request.method != "ssr" or not request.settings.use_temporal:
            return []
        count = request.warmup
        if count is None:
            count = DEFAULT_WARMUP_FRAMES if len(self.frame_list) > 1 else 0  # one frame alone is a still
        return list(range(max(first - count, self.scene.frame_start), first))

    def _warn_once(self, passes, warned):
        """The material warnings of the passes, each logged once per run and kept in the report."""
        for warning in passes.material_warnings:
            if warning not in warned:
                warned.add(warning)
                self.log(f"warning: {warning}")
                self.report.setdefault("warnings", []).append(warning)

    def _record(self, frame, images, timer, progress):
        report = self.report
        if report["gpu"] is None and self.request.method == "ssr":
            report["gpu"] = describe_gpu()
        height, width = images.final.shape[:2]
        report["resolution"] = [width, height]
        stages = {stage: round(ms, 3) for stage, ms in timer.milliseconds.items()}
        own_ms = sum(ms for stage, ms in stages.items() if stage != "render")
        report["frames"].append({"frame": frame, "stages_ms": stages, "total_ms": round(sum(stages.values()), 3),
                                 "render_ms": stages["render"], "addon_ms": round(own_ms, 3),
                                 **images.stats})
        report["frames"].sort(key=lambda entry: entry["frame"])
        self.records.write(report)
        progress.frame_done(frame, f"render {stages['render'] / 1000:.1f} s + add-on {own_ms / 1000:.2f} s")


def run_render(scene, scene_path, request, log=print, progress_stream=None):
    """Render every requested frame into request.out_dir (RenderRun); returns the run's report."""
    run = RenderRun(scene, scene_path, request, log, progress_stream)
    for _ in run.frames():
        pass
    return run.report


def _summarise(report, log):
    """The add-on's own cost per frame beside the render's, as a ratio (into the report and the log)."""
    summary = cost_summary(report["frames"])
    if summary:
        report["mean_ms_per_frame"] = summary
        log(f"per frame: render {summary['render']:.0f} ms, add-on (lamp split, read-back, chain, composite, "
            f"writing) {summary['addon']:.0f} ms = {summary['addon_over_render']:.3f} x the render")
