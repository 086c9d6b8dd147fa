"""What prediction costs per frame: the network and its preprocessing at batch 1
(:func:`latency`, :func:`latency_report`), and the whole live loop of ``finray predict``
on a 30 FPS stream (:func:`stream_benchmark`, :func:`realtime_report`).

The live loop is measured as a user runs it: a video is served over TCP (MPEG-TS,
paced at its frame rate, by PyAV in a process pinned to one core) and ``finray
predict`` reads it as a live source in another process pinned to the other core
(decode, segment, crop, network; with ``--annotate`` also the stress overlay and the
annotated video's encoding). Its stdout lines (one per predicted frame, flushed) are
time-stamped as they arrive: the latency of a frame is that time less the moment the
server sent it. Frames that came while the loop was busy, beyond the reader's two, are
dropped by it (:class:`finray.media.LiveFrames`) and counted. Timings, not correctness:
run on a quiet machine (the Snakemake rule takes both cores).
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..predictor import Predictor

#: The paper's inference time (GPU), for comparison with :func:`latency`.
PAPER_LATENCY_MS = 8.0


def latency(
    predictor: Predictor, frames: list[np.ndarray], n_frames: int = 200, repeats: int = 3
) -> dict:
    """Per-frame latency (ms) at batch 1 of ``predictor`` from raw images: medians over
    ``repeats`` x ``n_frames`` calls (frames cycled), end to end (``force``: force only;
    ``full``: force and stress map) and per stage (segmentation, crop + resample,
    network full / force only). Wall time (``*_ms``) and the calling thread's CPU time
    (``*_cpu_ms``: on a machine shared with other jobs, the wall time also counts the
    time the thread waited for a core; one-thread runtimes compute in the calling
    thread). Timings, not correctness: run on a quiet machine."""
    if not frames:
        raise ValueError("no frames to time")
    names = ("segment", "resample", "network_full", "network_force", "force", "full")
    wall = {k: [] for k in names}
    cpu = {k: [] for k in names}
    for f in frames[:10]:  # warm-up (allocators, ONNX Runtime's first runs)
        predictor(f)
        predictor.force(f)
    for _ in range(repeats):
        for k in range(n_frames):
            f = frames[k % len(frames)]
            t, c = [time.perf_counter()], [time.thread_time()]

            def tick():
                t.append(time.perf_counter())
                c.append(time.thread_time())

            mask = predictor.segment(f)
            tick()
            x = predictor.network_input(mask)
            tick()
            predictor.run(x)
            tick()
            predictor.run_force(x)
            tick()
            predictor.force(f)
            tick()
            predictor(f)
            tick()
            for j, key in enumerate(names):
                wall[key].append((t[j + 1] - t[j]) * 1e3)
                cpu[key].append((c[j + 1] - c[j]) * 1e3)
    out = {
        "backend": predictor.backend,
        "device": str(predictor.device),
        "input_size": list(predictor.size),
        "base_channels": predictor.meta.get("base_channels"),
        "roi_stride": predictor.roi_stride,
        "frame_shape": list(np.asarray(frames[0]).shape),
        "n_calls": repeats * n_frames,
        "n_distinct_frames": min(len(frames), n_frames),
    }
    for key in names:
        out[f"{key}_ms"] = float(np.median(wall[key]))
        out[f"{key}_p90_ms"] = float(np.percentile(wall[key], 90))
        out[f"{key}_cpu_ms"] = float(np.median(cpu[key]))
    out["median_of_repeats_force_ms"] = [
        float(np.median(wall["force"][r * n_frames : (r + 1) * n_frames])) for r in range(repeats)
    ]
    out["paper_ms"] = PAPER_LATENCY_MS
    out["paper_note"] = "the paper's inference time per image, on a GPU"
    return out


def latency_report(
    model_path: str | Path,
    images,
    n_frames: int = 200,
    repeats: int = 3,
    backends=("onnx", "torchscript"),
    device: str = "cpu",
) -> dict:
    """Latency (ms) per frame at batch 1 on one thread of the exported model on raw
    camera images (paths; up to ``n_frames`` distinct ones, evenly picked), per
    backend (:func:`latency`); the first backend's figures at the top level, the
    machine's load average before and after (timings on a shared machine are high).
    On the CPU by default, whatever the machine has (``finray.benchmarks.device``
    times a GPU)."""
    import imageio.v3 as iio

    images = list(images)
    if not images:
        raise ValueError("no images to time")
    pick = np.unique(
        np.linspace(0, len(images) - 1, min(n_frames, len(images))).round().astype(int)
    )
    frames = [iio.imread(images[k]) for k in pick]
    load_before = os.getloadavg()
    runs = {
        b: latency(
            Predictor(model_path, threads=1, backend=b, device=device), frames, n_frames, repeats
        )
        for b in backends
    }
    out = dict(runs[backends[0]])
    out.update(
        {
            "model": str(model_path),
            "cpu_count": os.cpu_count(),
            "load_average_before": list(load_before),
            "load_average_after": list(os.getloadavg()),
            "target_ms": 2.0,
            "by_backend": runs,
        }
    )
    return out


def fit_frame(rgb: np.ndarray, size_hw: tuple[int, int]) -> np.ndarray:
    """``rgb`` centre-cropped to the aspect of ``size_hw`` (H, W) and area-resized to it."""
    from PIL import Image

    H, W = rgb.shape[:2]
    h, w = size_hw
    if H * w > W * h:  # too tall: crop rows
        ch, cw = round(W * h / w), W
    else:
        ch, cw = H, round(H * w / h)
    r0, c0 = (H - ch) // 2, (W - cw) // 2
    crop = Image.fromarray(np.ascontiguousarray(rgb[r0 : r0 + ch, c0 : c0 + cw, :3]))
    return np.asarray(crop.resize((w, h), Image.Resampling.BOX))


def write_stream_video(
    frames: list[np.ndarray],
    path: str | Path,
    size_hw: tuple[int, int],
    n_frames: int,
    fps: float = 30.0,
) -> Path:
    """``n_frames`` frames (``frames`` cycled forth and back, each fitted to ``size_hw``
    by :func:`fit_frame`) as an MPEG-TS file at ``fps``: H.264 without B-frames (a
    camera's live stream) where the FFmpeg build has it, else MPEG-2."""
    import av
    from fractions import Fraction

    if not frames:
        raise ValueError("no frames for the stream")
    fitted = [fit_frame(f, size_hw) for f in frames]
    order = fitted + fitted[-2:0:-1] if len(fitted) > 2 else fitted
    path = Path(path)
    with av.open(str(path), "w", format="mpegts") as c:
        h264 = "libx264" in av.codecs_available
        s = c.add_stream(
            "libx264" if h264 else "mpeg2video",
            rate=Fraction(fps).limit_denominator(1001),
            options={"bf": "0", "tune": "zerolatency", "preset": "veryfast"} if h264 else {},
        )
        s.height, s.width = size_hw
        s.pix_fmt = "yuv420p"
        for k in range(n_frames):
            c.mux(s.encode(av.VideoFrame.from_ndarray(order[k % len(order)], format="rgb24")))
        c.mux(s.encode())
    return path


#: The server: copies a video's packets to a TCP client at their own pace, then prints
#: the moment (time.perf_counter, CLOCK_MONOTONIC: shared with the reading process) it
#: sent the first one and that packet's time stamp (s).
SERVE = """
import json, sys, time, av
src, port = sys.argv[1], int(sys.argv[2])
inp = av.open(src)
ist = inp.streams.video[0]
with av.open(f"tcp://127.0.0.1:{port}?listen=1", "w", format="mpegts",
              options={"flush_packets": "1", "max_delay": "0"}) as out:
    ost = out.add_stream_from_template(ist)
    t0 = pts0 = None
    for pkt in inp.demux(ist):
        if pkt.dts is None:
            continue
        ts = float(pkt.pts * pkt.time_base)
        if t0 is not None:
            wait = t0 + (ts - pts0) - time.perf_counter()
            if wait > 0:
                time.sleep(wait)
        pkt.stream = ost
        out.mux(pkt)  # the first waits for the client to connect
        if t0 is None:
            t0, pts0 = time.perf_counter(), ts
print(json.dumps({"t0": t0, "pts0": pts0}))
"""


#: The reader alone (the baseline of the stream's own delay: MPEG-TS completes a frame's
#: packet only when the next one starts, and the decoder holds a frame): the frames of a
#: live source as ``finray predict`` reads them (:class:`finray.media.LiveFrames`), each
#: printed as predict prints a row, the same summary line on stderr.
READ_ONLY = """
import sys
from finray.media import LiveFrames
frames = LiveFrames(sys.argv[1])
n = 0
for f in frames:
    if f.error is None:
        n += 1
        print(f"live_{f.index:06d}\tt {f.t_s:.4f} s", flush=True)
print(f"finray read: {n} frames predicted of {frames.received} received ({frames.dropped} dropped)",
      file=sys.stderr)
"""

#: what the predicting process runs per mode
MODES = ("read", "force", "annotate")


def _free_port() -> int:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return sock.getsockname()[1]


def _cpu_s(pid: int) -> float:
    """User + system CPU time (s) of a running process so far (/proc; 10 ms ticks)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def _pin(core: int | None):
    if core is None or not hasattr(os, "sched_setaffinity"):
        return None
    return lambda: os.sched_setaffinity(0, {core})


def stream_benchmark(
    model_path: str | Path,
    video: str | Path,
    out_dir: str | Path,
    mode: str = "force",
    cores: tuple[int, int] | None = (0, 1),
    timeout_s: float = 300.0,
) -> dict:
    """``finray predict`` on ``video`` served as a live TCP stream (see the module
    docstring), ``mode``: ``"force"`` (``--force-only``), ``"annotate"`` (``--annotate
    --no-maps``: the stress overlay drawn and the annotated video encoded) or ``"read"``
    (the reader alone, :data:`READ_ONLY`: the stream's own delay). ``cores``: (the
    predicting process's core, the server's); None: unpinned. Returns frames sent,
    received, predicted and dropped (all, and ``dropped_steady``: in the steady state,
    from gaps in the time stamps), the predicted frame rate, latency p50/p99 (ms, from
    the moment the server sent the frame to its row on stdout) and CPU time per
    predicted frame (ms, the predicting process's threads together: over the steady
    state's frames, ``cpu_ms_per_frame``, read from /proc as each row arrives, in 10 ms
    ticks; and from the first frame to the process's end, ``cpu_ms_per_frame_run``).
    The steady state is the predicted frames from :data:`WARMUP_S` after the first one
    to :data:`END_S` before the last (the stream's end delivers its last frames at
    once: the decoder's pending frames, flushed together)."""
    from ..media import video_info

    if mode not in MODES:
        raise ValueError(f"mode must be one of {MODES}, not {mode!r}")
    info = video_info(video)
    port = _free_port()
    server = subprocess.Popen(
        [sys.executable, "-c", SERVE, str(video), str(port)],
        stdout=subprocess.PIPE,
        text=True,
        preexec_fn=_pin(cores and cores[1]),
    )
    url = f"tcp://127.0.0.1:{port}"
    args = (
        [sys.executable, "-c", READ_ONLY, url]
        if mode == "read"
        else [
            sys.executable,
            "-m",
            "finray.cli",
            "predict",
            "--model",
            str(model_path),
            url,
            "--out",
            str(out_dir),
            "--overwrite",
            "--backend",
            "onnx",
            *(["--annotate", "--no-maps"] if mode == "annotate" else ["--force-only"]),
        ]
    )
    arrivals, t_s, cpu_at, cpu_total, err, rc = [], [], [], None, "", None
    try:
        for _ in range(200):  # until the server listens
            proc = subprocess.Popen(
                args,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                preexec_fn=_pin(cores and cores[0]),
            )
            for line in proc.stdout:
                now = time.perf_counter()
                parts = line.split("\t")
                if len(parts) > 1 and parts[1].startswith("t "):
                    cpu_at.append(_cpu_s(proc.pid))  # read as its row arrives
                    arrivals.append(now)
                    t_s.append(float(parts[1].split()[1]))
            err = proc.stderr.read()
            _, status, usage = os.wait4(proc.pid, 0)  # the CPU time of all its threads
            rc = proc.returncode = os.waitstatus_to_exitcode(status)
            cpu_total = usage.ru_utime + usage.ru_stime
            if arrivals or "cannot be opened" not in err:
                break
            time.sleep(0.1)
        sent = json.loads(server.communicate(timeout=timeout_s)[0].strip().splitlines()[-1])
    finally:
        if server.poll() is None:
            server.kill()
    t = np.asarray(t_s)
    steady = np.flatnonzero((t >= t[0] + WARMUP_S) & (t <= t[-1] - END_S)) if len(t) else t
    if rc != 0 or len(steady) < 3:
        raise RuntimeError(
            f"finray predict on the stream failed (exit code {rc}, "
            f"{len(arrivals)} frames): {err.strip()[-500:]}"
        )
    summary = err.strip().splitlines()[-1]
    received = int(summary.split(" received (")[0].rsplit(" ", 1)[1])
    dropped = int(summary.split(" received (")[1].split()[0])
    lat = (np.asarray(arrivals) - (sent["t0"] + t - sent["pts0"])) * 1e3
    s0, s1 = steady[0], steady[-1]
    gaps = np.rint(np.diff(t[s0 : s1 + 1]) * info.rate_hz).astype(int) - 1
    span = arrivals[s1] - arrivals[s0]
    n = s1 - s0
    out = {
        "video": str(video),
        "frames_sent": info.n_frames,
        "rate_hz": info.rate_hz,
        "mode": mode,
        "received": received,
        "predicted": len(arrivals),
        "dropped": dropped,
        "dropped_steady": int(gaps.clip(0).sum()),
        "fps": n / span if span > 0 else float("nan"),
        "latency_p50_ms": float(np.percentile(lat[steady], 50)),
        "latency_p99_ms": float(np.percentile(lat[steady], 99)),
        "latency_max_ms": float(lat[steady].max()),
        "first_frame_latency_ms": float(lat[0]),
        # the steady state's frames, as the other figures; and from the first frame to
        # the end of the process, which adds the run's closing work (the annotated
        # video's last packets, the force-against-time figure) spread over the frames
        "cpu_ms_per_frame": (cpu_at[s1] - cpu_at[s0]) / n * 1e3,
        "cpu_ms_per_frame_run": (cpu_total - cpu_at[0]) / (len(arrivals) - 1) * 1e3,
        "pinned_cores": list(cores) if cores else None,
    }
    out["keeps_up"] = bool(out["dropped_steady"] == 0 and out["fps"] >= 0.97 * info.rate_hz)
    return out


#: seconds of stream after the first predicted frame left out of the steady-state figures
#: (ONNX Runtime's first runs, and the frames that queued while the model loaded)
WARMUP_S = 1.0
#: seconds before the last predicted frame left out (the end's burst: with the reader's
#: two-frame buffer, a burst of three lost one at 9.9 s of a 10 s stream, reader alone)
END_S = 0.2


@functools.lru_cache(maxsize=4)
def _frame_stamps(video: str) -> tuple[float, ...]:
    """Every frame's time stamp (s) of a stream file, decoded once for all the runs on it."""
    from ..media import video_frames

    return tuple(f.t_s for f in video_frames(video))


def stream_force_error(forces_csv: str | Path, video: str | Path, truth_N) -> dict:
    """How well a run on a stream of :func:`write_stream_video` predicted: each row of
    its ``forces.csv`` (``t_s``, ``fx_N``) matched by time stamp to the stream's frame
    ``k``, whose source image is ``k`` of the forth-and-back cycle and whose force is
    ``truth_N`` of that image (the FEA's ``fx_N``, N). RMSE (N) and NRMSE (% of the
    largest |force|) over the rows: a fast loop that misreads frames shows here."""
    import pandas as pd

    truth = np.asarray(truth_N, float)
    n = len(truth)
    order = np.r_[np.arange(n), np.arange(n - 2, 0, -1)] if n > 2 else np.arange(n)
    stamps = np.array(_frame_stamps(str(video)))
    rows = pd.read_csv(forces_csv)
    k = np.abs(rows["t_s"].to_numpy()[:, None] - stamps[None, :]).argmin(axis=1)
    err = rows["fx_N"].to_numpy() - truth[order[k % len(order)]]
    rmse = float(np.sqrt(np.mean(err**2)))
    return {"force_rmse_N": rmse, "force_nrmse_pct": 100 * rmse / float(np.abs(truth).max())}


def realtime_report(
    model_path: str | Path,
    images,
    work_dir: str | Path,
    sizes=((480, 640), (720, 1280)),
    seconds: float = 20.0,
    fps: float = 30.0,
    modes=MODES,
    cores: tuple[int, int] | None = (0, 1),
    forces_N=None,
) -> dict:
    """:func:`stream_benchmark` at each frame size (H, W) and mode, on a stream of
    ``seconds`` at ``fps`` made of ``images`` (paths, cycled forth and back): the figures
    per run, the machine (CPU, cores) and whether each run kept up; with ``forces_N``
    (each image's true force, N) also each predicting run's force error
    (:func:`stream_force_error`). ``work_dir`` holds the streams and the runs' outputs."""
    import imageio.v3 as iio

    from ..precision import cpu_name

    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    frames = [iio.imread(f)[..., :3] for f in images]
    if not frames:
        raise ValueError("no images for the stream")
    runs = []
    for h, w in sizes:
        video = write_stream_video(
            frames, work / f"stream_{w}x{h}.ts", (h, w), int(seconds * fps), fps
        )
        for mode in modes:
            r = stream_benchmark(model_path, video, work / f"out_{w}x{h}_{mode}", mode, cores)
            r["size"] = f"{w}x{h}"
            if forces_N is not None and mode != "read":
                r.update(
                    stream_force_error(work / f"out_{w}x{h}_{mode}" / "forces.csv", video, forces_N)
                )
            print(
                f"{w}x{h} {mode}: {r['fps']:.1f} fps, latency p50 {r['latency_p50_ms']:.1f} ms, "
                f"p99 {r['latency_p99_ms']:.1f} ms, {r['dropped_steady']} dropped, "
                f"{r['cpu_ms_per_frame']:.1f} ms CPU per frame",
                flush=True,
            )
            runs.append(r)
    return {
        "model": str(model_path),
        "cpu": cpu_name(),
        "cpu_count": os.cpu_count(),
        "load_average": list(os.getloadavg()),
        "rate_hz": fps,
        "seconds": seconds,
        "warmup_s": WARMUP_S,
        "end_s": END_S,
        "runs": runs,
    }


def realtime_table(report: dict) -> str:
    """The report as a Markdown table, with what it measured."""
    import pandas as pd

    cols = {
        "size": "stream",
        "mode": "mode",
        "fps": "fps",
        "latency_p50_ms": "latency p50 (ms)",
        "latency_p99_ms": "p99 (ms)",
        "dropped_steady": "dropped",
        "dropped": "dropped (all)",
        "received": "received",
        "cpu_ms_per_frame": "CPU per frame (ms)",
        "cpu_ms_per_frame_run": "CPU per frame, to the end (ms)",
        "keeps_up": "keeps up",
        "force_nrmse_pct": "force NRMSE (%)",
    }
    df = pd.DataFrame(report["runs"])
    df = df[[c for c in cols if c in df]].rename(columns=cols)
    head = (
        f"# `finray predict` on a live {report['rate_hz']:g} FPS stream\n\n"
        f"{report['cpu']}, the predicting process pinned to one core, the server to the "
        f"other. Each stream {report['seconds']:g} s of pyvista renders of a held-out "
        f"shape (H.264 over TCP, MPEG-TS); figures from {report['warmup_s']:g} s after "
        f"the first predicted frame to {report['end_s']:g} s before the last (the "
        "stream's end delivers its last frames at once); `dropped` counts those in that "
        "window, `dropped (all)` every frame dropped. Latency: from the moment the "
        "server sent a frame to its row on stdout; mode `read` is the reader alone "
        "(the stream's own delay: MPEG-TS completes a frame only when the next one "
        "starts), `force` is `--force-only`, `annotate` is `--annotate --no-maps` (the "
        "overlay drawn and the annotated video encoded). Dropped: frames that came "
        "while the loop was busy. CPU per frame: the predicting process's threads over the "
        "steady state's frames; `to the end`: from the first predicted frame to the "
        "process's end, which adds the run's closing work (the annotated video's last "
        "packets, the force-against-time figure) spread over the frames. Force NRMSE: the predicted force of each row "
        "against the FEA's for the frame it read, in % of the largest force.\n\n"
    )
    return head + df.to_markdown(index=False, floatfmt=".1f") + "\n"
