"""Progress of a frame loop: a one-line bar on a terminal, plain lines otherwise."""
import sys
import time


class FrameProgress:
    """Frames done, seconds per frame and time left, for a known number of frames."""

    def __init__(self, total, stream=None):
        self.total = total
        self.done = 0
        self.stream = stream or sys.stderr
        self.interactive = hasattr(self.stream, "isatty") and self.stream.isatty()
        self._start = time.perf_counter()

    def frame_done(self, frame, note=""):
        self.done += 1
        elapsed = time.perf_counter() - self._start
        per_frame = elapsed / self.done
        remaining = per_frame * (self.total - self.done)
        status = (f"{self.done}/{self.total} frames, {per_frame:.1f} s/frame, "
                  f"ETA {_duration(remaining)} (frame {frame}{': ' + note if note else ''})")
        if self.interactive:
            width = 24
            filled = width * self.done // max(self.total, 1)
            self.stream.write(f"\r[{'#' * filled}{'.' * (width - filled)}] {status}\033[K")
            if self.done == self.total:
                self.stream.write("\n")
        else:
            self.stream.write(status + "\n")
        self.stream.flush()


def _duration(seconds):
    minutes, seconds = divmod(int(round(seconds)), 60)
    hours, minutes = divmod(minutes, 60)
    return f"{hours}h{minutes:02d}m" if hours else f"{minutes}m{seconds:02d}s"
