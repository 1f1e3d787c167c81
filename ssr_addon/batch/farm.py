"""`farm`: a shot split into chunks of frames, rendered by local processes, WORKERS at a time, into one
folder, as a render farm's workers would render it (docs/cli.md).

Each chunk is one `render --frames A-B --warmup K` process: it renders the K frames before its
first one without writing them, so its first frame carries an uninterrupted run's history, and
it records its frames in the folder's shared records (run_report), so the chunks never lose each
other's frames. A chunk's output goes to a log file beside its record; one line a chunk is printed.
"""
import os
import signal
import subprocess
import sys
import time

import bpy

from ..core.errors import SSRError
from .outputs import prepare_output_folder
from .run_report import RECORDS_FOLDER, read_report, remove_run

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def chunk_ranges(first, last, size):
    """(first, last) of each run of SIZE consecutive frames from FIRST to LAST, the last one shorter
    (Flamenco's frameChunker on a plain range)."""
    if size < 1:
        raise SSRError(f"--chunk must be at least 1 frame, got {size}")
    return [(start, min(start + size - 1, last)) for start in range(first, last + 1, size)]


def render_command(scene_path, chunk, out_dir, warmup, render_words):
    """The command line that renders CHUNK of SCENE_PATH into OUT_DIR: this Python with the add-on's
    package, or, inside the Blender binary, that binary in the background on the .blend file."""
    first, last = chunk
    words = ["render", "--frames", f"{first}-{last}", "--warmup", str(warmup), "--out", out_dir, *render_words]
    if not bpy.app.binary_path:  # the bpy module: this Python renders
        return [sys.executable, "-m", "ssr_addon", *words[:1], scene_path, *words[1:]]
    expression = f"import sys; sys.path.insert(0, {REPO!r}); import ssr_addon.batch.cli as cli; cli.main()"
    return [bpy.app.binary_path, "-b", scene_path, "--python-expr", expression, "--", *words]


def run_farm(scene_path, frames, chunk_size, workers, out_dir, warmup, render_words, overwrite=False, log=print):
    """Render FRAMES (first, last) of SCENE_PATH as chunks of CHUNK_SIZE frames, WORKERS processes at
    a time; RENDER_WORDS: the render options every chunk gets (--method, --set ...). Raises SSRError
    naming the chunks that failed once every chunk has ended; SIGTERM or Ctrl-C stops them all."""
    if workers < 1:
        raise SSRError(f"--workers must be at least 1, got {workers}")
    chunks = chunk_ranges(*frames, chunk_size)
    prepare_output_folder(out_dir)
    if overwrite:
        remove_run(out_dir)
    logs = os.path.join(out_dir, RECORDS_FOLDER, "logs")
    os.makedirs(logs, exist_ok=True)
    waiting, running, failed = list(chunks), {}, []
    started = time.monotonic()
    log(f"{len(chunks)} chunks of up to {chunk_size} frames, {workers} at a time, warm-up {warmup} frames each")
    try:
        while waiting or running:
            while waiting and len(running) < workers:
                chunk = waiting.pop(0)
                log_path = os.path.join(logs, f"frames_{chunk[0]:04d}-{chunk[1]:04d}.log")
                with open(log_path, "w", encoding="utf-8") as stream:
                    process = subprocess.Popen(render_command(scene_path, chunk, out_dir, warmup, render_words),
                                               stdout=stream, stderr=subprocess.STDOUT, cwd=REPO)
                running[process] = (chunk, log_path, time.monotonic())
            time.sleep(0.2)
            for process in [process for process in running if process.poll() is not None]:
                chunk, log_path, start = running.pop(process)
                if process.returncode == 0:
                    log(f"chunk {chunk[0]}-{chunk[1]}: done in {time.monotonic() - start:.0f} s")
                else:
                    failed.append(chunk)
                    log(f"chunk {chunk[0]}-{chunk[1]}: failed (status {process.returncode}): "
                        f"{_last_line(log_path)} (log: {log_path})")
    finally:
        for process in running:  # stopped early: each chunk ends cleanly, its written frames complete
            process.send_signal(signal.SIGTERM)
        for process in running:
            process.wait()
    report = read_report(out_dir)
    log(f"{len(report.get('frames', []))} frames in {out_dir} after {time.monotonic() - started:.0f} s")
    if failed:
        raise SSRError(f"{len(failed)} chunk(s) failed: {', '.join(f'{a}-{b}' for a, b in failed)}; rerun the "
                       "same command to render what they left")
    return report


def _last_line(path):
    with open(path, encoding="utf-8", errors="replace") as stream:
        lines = [line.strip() for line in stream if line.strip() and "EGL" not in line]
    return lines[-1] if lines else "no output"
