"""Camera frames in: image files and videos (PyAV), with one lost-frame policy.

Read by ``finray predict`` (:mod:`finray.predict`) and by ingest (:mod:`finray.recording`).
The policy: a frame that cannot be read is never dropped silently. It comes out of the
readers as a :class:`Frame` with ``image`` None and ``error`` saying why (a file that
does not decode, a stream that cannot be read on, a frame the container counts that
never came out of the decoder, e.g. its packet did not decode: after the video's other
frames, with its rank and time), so that the caller reports it and goes on. A source
that cannot be read at all raises :class:`MediaError`.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .errors import MediaError

IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
VIDEO_SUFFIXES = (".mp4", ".avi", ".mov", ".mkv", ".webm", ".ts")


def one_line(exc: BaseException) -> str:
    """``Type: first line`` of an exception from a reader (some span many lines)."""
    text = str(exc).strip().splitlines()
    return f"{type(exc).__name__}: {text[0] if text else ''}".rstrip(": ")


@dataclass
class Frame:
    """One frame of a source. ``index``: its place in the sequence the reader gives (0,
    1, ...; a lost frame gets one too); ``t_s``: its time (s) from the video's time
    stamps, or None; ``rank``: its rank in the stream from the time stamp and the frame
    rate, or None; ``image`` (H, W[, 3]) uint8, or None with ``error``; ``rest``: the
    error ends the video (the stream cannot be read on)."""

    index: int
    t_s: float | None
    rank: int | None
    image: np.ndarray | None
    error: str | None = None
    rest: bool = False


def read_image(path: str | Path, colour: bool = False) -> tuple[np.ndarray | None, str | None]:
    """``(image, None)`` of an image file, grey (H, W) or colour (H, W, 3) as stored
    (``colour``: always RGB), or ``(None, why)`` when it cannot be read as one."""
    from PIL import Image

    try:
        with Image.open(path) as im:
            if colour:
                im = im.convert("RGB")
            elif im.mode not in ("L", "LA", "RGB", "RGBA", "I", "I;16", "F"):
                im = im.convert("RGB")  # palette, bilevel, CMYK, ...
            img = np.asarray(im)
    except Exception as exc:  # any decoder's error on a bad file is this frame's, not the run's
        return None, f"not a readable image ({one_line(exc)})"
    if img.ndim == 3 and img.shape[-1] in (1, 2):  # grey (+ alpha)
        img = img[..., 0]
    elif img.ndim == 3 and img.shape[-1] == 4:  # RGBA
        img = img[..., :3]
    if img.ndim not in (2, 3) or img.size == 0 or (img.ndim == 3 and img.shape[-1] != 3):
        return None, f"not a single grey or colour image (array of shape {img.shape})"
    return img, None


@dataclass
class VideoInfo:
    """A video's first stream: ``rate_hz`` (nominal; 0 if the stream has none) and
    ``n_frames`` (as the container counts them, or from the duration; 0 if unknown)."""

    rate_hz: float
    n_frames: int


def video_info(path: str | Path) -> VideoInfo:
    """The frame rate and count of a video; :class:`MediaError` if it cannot be opened
    or has no video stream."""
    import av

    try:
        with av.open(str(path)) as c:
            if not c.streams.video:
                raise MediaError(f"{path} has no video stream")
            s = c.streams.video[0]
            rate = float(s.average_rate or s.guessed_rate or 0)
            n = _frame_count(c, s, rate)
    except (av.FFmpegError, OSError) as exc:
        raise MediaError(f"{path} is not a readable video ({one_line(exc)})") from None
    return VideoInfo(rate, n)


def _frame_count(container, stream, rate: float) -> int:
    """The frames a video's stream should hold: as the container counts them, else (a
    Matroska or WebM file counts none) its duration times the frame rate: the stream's
    duration, else the container's where the video is its only stream (an audio track
    may run longer); 0 where unknown."""
    import av

    n = int(stream.frames or 0)
    if n or not rate:
        return n
    if stream.duration and stream.time_base:
        return int(round(float(stream.duration * stream.time_base) * rate))
    if container.duration and len(container.streams) == 1:
        return int(round(container.duration / av.time_base * rate))
    return 0


def video_frames(path: str | Path, threads: bool = False):
    """Every :class:`Frame` of a video's first stream, lazily, RGB (H, W, 3) uint8.
    Opening it raises :class:`MediaError` here (not readable, no video stream). The
    frames come in the decoder's order; the frames the container counts (or its duration
    holds at the frame rate, where it counts none: Matroska, WebM) that never came
    out of it (a packet that does not decode, or a frame that depends on a lost one)
    come after them as error frames, each with its rank and time; without time stamps
    or a frame rate, a packet that does not decode gives an error frame where it fails.
    A stream that cannot be read on ends the sequence with an error frame (``rest``).
    ``threads``: let FFmpeg decode with several threads."""
    import av

    path = Path(path)
    try:
        container = av.open(str(path))
    except (av.FFmpegError, OSError) as exc:
        raise MediaError(f"{path} is not a readable video ({one_line(exc)})") from None
    if not container.streams.video:
        container.close()
        raise MediaError(f"{path} has no video stream")
    stream = container.streams.video[0]
    if threads:
        stream.thread_type = "AUTO"
    rate = float(stream.average_rate or stream.guessed_rate or 0)
    start = stream.start_time or 0
    expected = _frame_count(container, stream, rate)

    def stamp(pts, time_base):
        if pts is None or not time_base:
            return None, None
        t = float((pts - start) * time_base)
        return t, (round(t * rate) if rate else None)

    def frames():
        k, ranks, why = 0, set(), []
        with container:
            packets = container.demux(stream)
            while True:
                try:
                    packet = next(packets)
                except StopIteration:
                    break
                except av.FFmpegError as exc:
                    yield Frame(
                        k,
                        None,
                        None,
                        None,
                        f"the video cannot be read on ({one_line(exc)})",
                        rest=True,
                    )
                    return
                try:
                    decoded = packet.decode()
                except av.FFmpegError as exc:
                    # which frame it was shows at the end, as the rank that never came
                    # (a threaded decoder reports it on a later packet); without ranks, here
                    why.append(f"the frame does not decode ({one_line(exc)})")
                    if not rate:
                        yield Frame(k, None, None, None, why[-1])
                        k += 1
                    continue
                for fr in decoded:
                    t, r = stamp(fr.pts, fr.time_base)
                    ranks.add(r)
                    yield Frame(k, t, r, fr.to_ndarray(format="rgb24"))
                    k += 1
        if rate and None not in ranks:
            # the frames the container holds (a truncated Matroska file: its duration's)
            for r in range(expected):
                if r not in ranks:
                    yield Frame(
                        k,
                        r / rate,
                        r,
                        None,
                        why.pop(0)
                        if why
                        else "the frame was not decoded (a frame it depends on was lost)"
                        if ranks and r < max(ranks)
                        else "the frame is missing: the video ends before it (cut short?)",
                    )
                    k += 1

    return frames()


#: URL schemes of network streams that PyAV (FFmpeg) opens
STREAM_SCHEMES = ("rtsp", "rtsps", "rtmp", "udp", "tcp", "srt", "http", "https")


def is_live(source: str | Path) -> bool:
    """A live source: a network stream URL (:data:`STREAM_SCHEMES`), a V4L2 camera
    device (``/dev/video*``) or a camera's index (``0``, ``1``, ...: ``/dev/video<k>``)."""
    s = str(source)
    return (
        (s.split("://", 1)[0].lower() in STREAM_SCHEMES and "://" in s)
        or s.startswith("/dev/video")
        or s.isdigit()
    )


class LiveFrames:
    """The frames of a live source (:func:`is_live`), in order: a reader thread decodes
    as fast as the source sends and keeps the latest ``buffer`` frames, so that a
    consumer slower than the source drops the oldest instead of falling behind
    (``dropped`` counts them). Two absorb a network's jitter (two frames that arrive
    together, which a one-frame buffer dropped although the loop kept up on average) at
    the cost of at most one frame's extra latency. Iterating yields :class:`Frame` (RGB,
    ``t_s`` from the stream's time stamps, else the wall clock since it opened) until the
    stream ends or :meth:`close`. Opening raises :class:`MediaError` (unreachable, no
    video)."""

    def __init__(self, source: str | Path, open_timeout_s: float = 10.0, buffer: int = 2):
        import collections
        import threading
        import time

        import av

        if int(buffer) < 1:
            raise ValueError(f"buffer must hold at least one frame, got {buffer}")
        s = str(source)
        device = f"/dev/video{s}" if s.isdigit() else s
        fmt = "v4l2" if device.startswith("/dev/video") else None
        options = {"rtsp_transport": "tcp"} if s.lower().startswith("rtsp") else {}
        try:
            self._container = av.open(
                device, format=fmt, options=options, timeout=(open_timeout_s, open_timeout_s)
            )
        except (av.FFmpegError, OSError) as exc:
            raise MediaError(
                f"{source} cannot be opened as a live source ({one_line(exc)})"
            ) from None
        if not self._container.streams.video:
            self._container.close()
            raise MediaError(f"{source} has no video stream")
        self.source, self.dropped, self.received = s, 0, 0
        self.rate_hz = float(self._container.streams.video[0].average_rate or 0)
        self._t0 = time.perf_counter()
        self._frames = collections.deque(maxlen=int(buffer))
        self._done, self._error = False, None
        self._cond = threading.Condition()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._read, daemon=True)
        self._thread.start()

    def _read(self) -> None:
        import time

        import av

        try:
            for fr in self._container.decode(video=0):
                t = (
                    float(fr.pts * fr.time_base)
                    if fr.pts is not None and fr.time_base
                    else time.perf_counter() - self._t0
                )
                frame = Frame(self.received, t, None, fr.to_ndarray(format="rgb24"))
                with self._cond:
                    if len(self._frames) == self._frames.maxlen:
                        self.dropped += 1  # the consumer had not taken the oldest: it goes
                    self._frames.append(frame)
                    self.received += 1
                    self._cond.notify()
                if self._stop.is_set():
                    break
        except (av.FFmpegError, OSError) as exc:
            self._error = f"the stream cannot be read on ({one_line(exc)})"
        finally:
            with self._cond:
                self._done = True
                self._cond.notify()

    def __iter__(self):
        while True:
            with self._cond:
                while not self._frames and not self._done:
                    self._cond.wait()
                frame = self._frames.popleft() if self._frames else None
                done, error = self._done, self._error
            if frame is not None:
                yield frame
            elif done:
                if error:
                    yield Frame(self.received, None, None, None, error, rest=True)
                return

    def close(self) -> None:
        """Stop the reader, then close the stream. Closing while the reader is inside
        FFmpeg's decoder crashed the process (SIGSEGV on Ctrl-C), so the container is
        closed only once the reader has left it; a reader stuck on a silent network
        stream is left to the process's exit (it is a daemon)."""
        self._stop.set()
        self._thread.join(timeout=5.0)
        if self._thread.is_alive():
            return
        try:
            self._container.close()
        except Exception:  # closing a broken stream: nothing left to save
            pass


class VideoWriter:
    """Frames (H, W, 3) uint8 RGB into a video file through PyAV, the package's one
    video writer (the annotated video of ``finray predict``, the emulated rig's takes):
    H.264 (libx264) where the FFmpeg build has it, else MPEG-4 Part 2; at ``fps``
    (frames a second); one encoder thread (a live loop or a job has one core).

    ``size`` (W, H): the stream's; None: the first frame's, rounded down to even for a
    chroma-subsampled ``pix_fmt`` (frames are cut to it). ``crf``: x264's constant
    rate factor (None: its default); ``preset``, ``tune``: x264's (``ultrafast``: the
    encoder shares the live loop's core; ``zerolatency``: no frame held back).
    ``interpolation``: the RGB frame converted to ``pix_fmt`` here by swscale with this
    interpolation (``"POINT"``: each 2x2 block's chroma from one pixel, a third less
    time than the default bilinear, for the annotated frames' flat text and cells);
    None: converted by the encoder. A context manager (``close`` on exit)."""

    def __init__(
        self,
        path: str | Path,
        fps: float = 30.0,
        size: tuple[int, int] | None = None,
        crf: int | None = None,
        pix_fmt: str = "yuv420p",
        preset: str = "ultrafast",
        tune: str | None = None,
        interpolation: str | None = None,
    ):
        self.path, self.fps, self.size = Path(path), float(fps), size
        self.crf, self.pix_fmt, self.preset, self.tune = crf, pix_fmt, preset, tune
        self.interpolation = interpolation
        self._container = self._stream = None

    def _open(self, rgb: np.ndarray) -> None:
        from fractions import Fraction

        import av

        if self.size is not None:
            w, h = map(int, self.size)
        else:
            h, w = rgb.shape[:2]
            if self.pix_fmt.startswith(("yuv420", "yuvj420", "nv12")):
                h, w = (h // 2) * 2, (w // 2) * 2
        self._container = av.open(str(self.path), "w")
        h264 = "libx264" in av.codecs_available
        options = {"preset": self.preset, "threads": "1"} if h264 else {}
        if h264 and self.tune:
            options["tune"] = self.tune
        if h264 and self.crf is not None:
            options["crf"] = str(int(self.crf))
        self._stream = self._container.add_stream(
            "libx264" if h264 else "mpeg4",
            rate=Fraction(self.fps).limit_denominator(1001),
            options=options,
        )
        self._stream.width, self._stream.height = w, h
        self._stream.pix_fmt = self.pix_fmt

    def write(self, rgb: np.ndarray) -> None:
        import av

        if self._container is None:
            self._open(rgb)
        rgb = np.ascontiguousarray(rgb[: self._stream.height, : self._stream.width])
        # the array's buffer as the frame's, not a copy (from_ndarray copies row by row:
        # 3.5 ms of a 1280x816 frame)
        frame = av.VideoFrame.from_numpy_buffer(rgb, format="rgb24")
        if self.interpolation is not None:
            frame = frame.reformat(format=self.pix_fmt, interpolation=self.interpolation)
        for packet in self._stream.encode(frame):
            self._container.mux(packet)

    def close(self) -> None:
        if self._container is not None:
            for packet in self._stream.encode():
                self._container.mux(packet)
            self._container.close()
            self._container = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
