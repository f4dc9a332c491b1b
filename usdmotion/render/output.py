"""Frame writers (image sequences through OpenImageIO, H.264 video through PyAV), all
atomic, and a writer thread fed through a bounded queue.

* ``frames/####.png`` (or ``%04d``): one file per frame, numbered from 0, written into
  a hidden temporary folder beside the target folder and moved into place at the end.
  ``.png``/``.jpg``/``.tif`` hold 8-bit sRGB (what was displayed); ``.exr`` holds
  *linear* half floats: the renderer's output decoded with its own transfer
  function (pyrender writes ``linear^(1/2.2)``), so ``exr = (png / 255)^2.2``.
* ``.mp4``: H.264 (libx264, yuv420p, CRF ``quality``) into a temporary file, renamed at
  the end.

On any error or interrupt nothing is left at the target.
"""

from __future__ import annotations

import contextlib
import os
import queue
import re
import shutil
import tempfile
import threading
import time
from fractions import Fraction
from pathlib import Path

import numpy as np

from usdmotion.errors import OutputError

VIDEO_EXTENSIONS = (".mp4",)
IMAGE_EXTENSIONS = (".png", ".jpg", ".jpeg", ".exr", ".tif", ".tiff")
DISPLAY_GAMMA = 2.2  # pyrender's fragment shader ends with pow(color, 1/2.2)
_PATTERN = re.compile(r"#+|%0?(\d*)d")


def _umask_mode(path: Path, mode: int) -> None:
    """Give a temporary output the permissions a normally created one would have."""
    umask = os.umask(0)
    os.umask(umask)
    os.chmod(path, mode & ~umask)


def is_video(path: Path) -> bool:
    return Path(path).suffix.lower() in VIDEO_EXTENSIONS


def frame_name(pattern: str, index: int) -> str:
    """``"####.png", 7 → "0007.png"``; ``"f_%03d.exr", 7 → "f_007.exr"``."""
    match = _PATTERN.search(pattern)
    width = len(match[0]) if match[0].startswith("#") else int(match[1] or 0)
    return pattern[:match.start()] + f"{index:0{width}d}" + pattern[match.end():]


def check_output(path: Path, width: int, height: int) -> None:
    """Fail early (before any rendering) on an output that cannot be written."""
    ext = path.suffix.lower()
    if ext in VIDEO_EXTENSIONS:
        if width % 2 or height % 2:
            raise OutputError(f"{path}: H.264 needs an even width and height, got {width}x{height}")
        folder = path.parent
    elif ext in IMAGE_EXTENSIONS:
        if not _PATTERN.search(path.name):
            raise OutputError(f"{path}: an image sequence needs a frame-number pattern in the file name, "
                              "e.g. frames/####.png or frames/f_%04d.png")
        folder = path.parent if path.parent.is_dir() else path.parent.parent
    else:
        raise OutputError(f"{path}: unknown output format {ext!r} (use .mp4 or an image sequence "
                          f"{', '.join(IMAGE_EXTENSIONS)} with #### in the name)")
    if not folder.is_dir():
        raise OutputError(f"{path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"{path}: cannot write in {folder} (permission denied)")


class VideoWriter:
    """H.264 MP4 through PyAV, written to a temporary file and renamed on :meth:`commit`."""

    def __init__(self, path: Path, width: int, height: int, fps: float, quality: int = 20):
        import av

        self.path = path
        fd, name = tempfile.mkstemp(prefix=f".{path.stem}.", suffix=".tmp.mp4", dir=path.parent or ".")
        os.close(fd)
        self.tmp = Path(name)
        self.container = av.open(str(self.tmp), mode="w", format="mp4")
        self.stream = self.container.add_stream("libx264", rate=Fraction(fps).limit_denominator(1001))
        self.stream.width, self.stream.height, self.stream.pix_fmt = width, height, "yuv420p"
        self.stream.options = {"crf": str(int(quality)), "preset": "veryfast"}
        self.av = av

    def write(self, image: np.ndarray, index: int) -> None:
        """Encode ``image``: ``(H, W, 3)`` RGB or ``(H, W, 4)`` RGBA (alpha ignored) uint8."""
        frame = self.av.VideoFrame.from_ndarray(image, format="rgba" if image.shape[2] == 4 else "rgb24")
        self.container.mux(self.stream.encode(frame))

    def commit(self) -> None:
        self.container.mux(self.stream.encode())
        self.container.close()
        _umask_mode(self.tmp, 0o666)
        os.replace(self.tmp, self.path)

    def abort(self) -> None:
        with contextlib.suppress(Exception):
            self.container.close()
        with contextlib.suppress(FileNotFoundError):
            self.tmp.unlink()


class ImageSequenceWriter:
    """Numbered images through OpenImageIO into a temporary folder, moved on :meth:`commit`."""

    def __init__(self, pattern: Path):
        self.target = pattern.parent
        self.name = pattern.name
        self.ext = pattern.suffix.lower()
        base = self.target if self.target.is_dir() else self.target.parent
        self.tmp = Path(tempfile.mkdtemp(prefix=f".{self.target.name or 'frames'}.", suffix=".tmp", dir=base))
        self.written: list[str] = []

    def write(self, image: np.ndarray, index: int) -> None:
        import OpenImageIO as oiio

        name = frame_name(self.name, index)
        image = np.ascontiguousarray(image[..., :3])  # RGBA frames: without their alpha
        if self.ext == ".exr":
            pixels = (image.astype(np.float32) / 255.0) ** DISPLAY_GAMMA
            spec = oiio.ImageSpec(image.shape[1], image.shape[0], 3, "half")
            spec.attribute("compression", "zip")
            spec.attribute("oiio:ColorSpace", "lin_rec709")
        else:
            pixels = image
            spec = oiio.ImageSpec(image.shape[1], image.shape[0], 3, "uint8")
            spec.attribute("oiio:ColorSpace", "srgb_rec709_scene")
            if self.ext in (".jpg", ".jpeg"):
                spec.attribute("Compression", "jpeg:92")
        out = oiio.ImageOutput.create(str(self.tmp / name))
        if out is None or not out.open(str(self.tmp / name), spec):
            raise OutputError(f"{self.target / name}: cannot write: {oiio.geterror()}")
        ok = out.write_image(pixels)
        out.close()
        if not ok:
            raise OutputError(f"{self.target / name}: cannot write: {out.geterror()}")
        self.written.append(name)

    def commit(self) -> None:
        if not self.target.exists():
            _umask_mode(self.tmp, 0o777)
            os.replace(self.tmp, self.target)
            return
        for name in self.written:
            os.replace(self.tmp / name, self.target / name)
        shutil.rmtree(self.tmp, ignore_errors=True)

    def abort(self) -> None:
        shutil.rmtree(self.tmp, ignore_errors=True)


def open_writer(path: Path, width: int, height: int, fps: float, quality: int = 20):
    check_output(path, width, height)
    try:
        if is_video(path):
            return VideoWriter(path, width, height, fps, quality)
        return ImageSequenceWriter(path)
    except OSError as exc:
        raise OutputError(f"{path}: cannot write: {exc.strerror or exc}") from None


class WriterThread:
    """Finish, encode and write frames on a background thread while the caller renders the next ones.

    ``writer`` is a frame writer, or a function that opens one: it is then opened on the thread,
    so importing and starting the encoder overlap the caller's work (building the body) instead of
    delaying the first frame. ``put(payload, index, finish)`` queues a frame; ``finish(payload,
    index)`` (optional), run on the thread before the write, returns the ``(H, W, 3)`` uint8 image
    (the overlays and the composition of the views: the rendering thread goes on to the next frame
    meanwhile). ``put`` blocks when ``depth`` frames are waiting (memory stays flat); an error in
    the thread (opening, finishing or writing) is re-raised in the caller at the next ``put`` or at
    ``close``.
    """

    def __init__(self, writer, depth: int = 8):
        self.writer = writer if hasattr(writer, "write") else None
        self._open = None if self.writer is not None else writer
        self.queue: queue.Queue = queue.Queue(maxsize=depth)
        self.error: BaseException | None = None
        self.busy = 0.0  # seconds spent writing/encoding
        self.finishing = 0.0  # seconds spent in ``finish``
        self.thread = threading.Thread(target=self._run, name="usdmotion-writer", daemon=True)
        self.thread.start()

    def _run(self) -> None:
        if self._open is not None:
            try:
                self.writer = self._open()
            except BaseException as exc:  # re-raised in the rendering thread
                self.error = exc
        while True:
            item = self.queue.get()
            if item is None:
                return
            if self.error is None:
                try:
                    payload, index, finish = item
                    started = time.perf_counter()
                    image = payload if finish is None else finish(payload, index)
                    done = time.perf_counter()
                    self.writer.write(image, index)
                    self.finishing += done - started
                    self.busy += time.perf_counter() - done
                except BaseException as exc:  # re-raised in the rendering thread
                    self.error = exc

    def put(self, payload, index: int, finish=None) -> None:
        if self.error is not None:
            raise self.error
        self.queue.put((payload, index, finish))

    def close(self, commit: bool) -> None:
        self.queue.put(None)
        self.thread.join()
        if self.writer is None:  # it could not be opened
            if commit and self.error is not None:
                raise self.error
            return
        if commit and self.error is None:
            try:
                started = time.perf_counter()
                self.writer.commit()
                self.busy += time.perf_counter() - started
                return
            except OSError as exc:
                self.writer.abort()
                target = getattr(self.writer, "path", None) or getattr(self.writer, "target", "output")
                raise OutputError(f"{target}: cannot write: {exc.strerror or exc}") from None
        self.writer.abort()
        if commit and self.error is not None:
            raise self.error
