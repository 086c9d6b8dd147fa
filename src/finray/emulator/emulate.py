"""One emulated take, in the recording format, from an FEA result of the as-built finger.

``emulate_take(result_npz, take_dir, lab, ...)`` writes into ``take_dir``:

- ``take.mp4`` (H.264, the camera's frames), ``forces.csv`` (the sensor's log on its
  own clock) and ``take.json`` (object, contact height, push axis, the camera's
  intrinsics as a RealSense reports them; the finger's colour when ``lab.look`` names
  one) -- what a real rig writes, and all that ``finray ingest`` reads;
- ``truth/`` for QA only: ``masks.npz`` (the true finger mask of every frame, bit-
  packed), ``frames.csv`` (per frame: camera time, push, true push force averaged over
  the frame's interval) and ``truth.json`` (the clock offset, its drift over the take,
  the sensor's gain and offsets, the camera).

Per frame k at camera time t_k = k / fps (mid-exposure): the push d(t) of
:class:`~finray.emulator.motion.GripperMotion` picks the FEA state (node displacements
interpolated linearly in the push between solver frames); the camera integrates
``exposure_ms`` (sub-frames averaged while the gripper moves: motion blur), then lens
distortion, the optics' blur (Gaussian PSF), shot and read noise, 8 bits, H.264.

The sensor's force: the FEA's elastic force at the push, or, for a viscoelastic print
(``print_law``, :mod:`finray.viscoelastic`), that force over the push's history,
softened and relaxed (:class:`_PrintForces`; ``truth/frames.csv`` then also holds the
elastic force). The image follows the push alone: the shape's own creep under a held
position (which a position-controlled axis keeps at the contact) is left out.
"""

from __future__ import annotations

import json
import time
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np

from ..media import VideoWriter
from ..render.result import load_fea_result
from .camera import LensDistortion, PinholeCamera, SensorNoise
from .motion import GripperMotion
from .studio import Studio
from .sensor import ForceSensor, write_forces_csv


def camera_from_config(cam: dict, target_mm) -> PinholeCamera:
    return PinholeCamera.looking_at(
        target_mm,
        width=cam["size_px"][0],
        height=cam["size_px"][1],
        hfov_deg=cam["hfov_deg"],
        distance_mm=cam["distance_mm"],
        yaw_deg=cam["yaw_deg"],
        pitch_deg=cam["pitch_deg"],
        roll_deg=cam["roll_deg"],
        principal_offset_px=cam["principal_offset_px"],
        distortion=cam["distortion"],
    )


class _Interpolator:
    """FEA state at any push d (mm): node positions (N, 2), object-frame forces (N)."""

    def __init__(self, res):
        self.res = res
        self.d = np.asarray(res.displacement_mm, dtype=np.float64)
        if np.any(np.diff(self.d) <= 0):
            raise ValueError("FEA frames are not increasing in push")

    def points(self, d: float) -> np.ndarray:
        i = int(np.clip(np.searchsorted(self.d, d) - 1, 0, len(self.d) - 2))
        w = float(np.clip((d - self.d[i]) / (self.d[i + 1] - self.d[i]), 0.0, 1.0))
        u = (1 - w) * self.res.u_mm[i].astype(np.float64) + w * self.res.u_mm[i + 1]
        return self.res.points + u

    def forces(self, d: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(push force on the finger along the push, force along the finger's length)."""
        d = np.clip(d, self.d[0], self.d[-1])
        return np.interp(d, self.d, self.res.fx_N), np.interp(d, self.d, self.res.fy_N)


#: the grid (s) on which a viscoelastic print's force history is computed, then read
#: anywhere by linear interpolation (a 1 kHz sensor samples every second point)
PRINT_GRID_S = 5e-4


class _PrintForces:
    """The force of a viscoelastic print (:mod:`finray.viscoelastic`) at any camera time
    of the take: the FEA's elastic forces over the push history, softened by the push
    force's Mullins factor and relaxed, on a grid of :data:`PRINT_GRID_S` from ``t0_s``
    to ``t1_s``."""

    def __init__(self, fea: _Interpolator, motion: GripperMotion, law, t0_s: float, t1_s: float):
        from ..viscoelastic import relax, softening_factor

        n = int(np.ceil((t1_s - t0_s) / PRINT_GRID_S)) + 1
        self.t = t0_s + PRINT_GRID_S * np.arange(n)
        push, along = fea.forces(motion.push(self.t))
        eta = softening_factor(push, law.softening)
        g, tau, _ = law.as_rows()
        self.push = relax(self.t, push * eta, g, tau, 0.0)[0]
        self.along = relax(self.t, along * eta, g, tau, 0.0)[0]

    def __call__(self, t_cam) -> tuple[np.ndarray, np.ndarray]:
        return np.interp(t_cam, self.t, self.push), np.interp(t_cam, self.t, self.along)


def emulate_take(
    result_npz,
    take_dir,
    lab: dict,
    *,
    object_name: str,
    height_mm: float,
    extrusion_mm: float,
    seed: int = 0,
    print_law=None,
    log=print,
) -> dict:
    """Write one take (see the module's text); returns ``truth.json``'s content.
    ``lab``: the config's ``lab`` section; ``print_law``: the print's time dependence
    (:class:`finray.viscoelastic.PrintLaw`; None or elastic: the FEA's force as it is)."""
    t_wall = time.perf_counter()
    take_dir = Path(take_dir)
    (take_dir / "truth").mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    res = load_fea_result(result_npz)
    fea = _Interpolator(res)
    motion = GripperMotion.from_config(lab["motion"])
    reach = float(fea.d[-1])
    force_limited = motion.push_mm > reach + 1e-3
    if force_limited:
        # the FEA stopped at its physical limit (fea.force_cap_N; a scene that failed
        # writes no result): a force-limited gripper stops there too, at the same speed
        motion = replace(motion, push_mm=reach)
        log(
            f"the FEA stopped at {reach:.3f} mm of lab.motion.push_mm's "
            f"{lab['motion']['push_mm']:g} mm: the take pushes {reach:.3f} mm"
        )
    cam_cfg, look = lab["camera"], lab["look"]
    target = (float(look["target_mm"][0]), float(look["target_mm"][1]), 0.0)
    camera = camera_from_config(cam_cfg, target)
    fps = float(cam_cfg["fps"])
    n = int(round(motion.duration_s * fps))
    t = np.arange(n) / fps
    exposure = 1e-3 * float(cam_cfg["exposure_ms"])
    n_sub = max(1, int(cam_cfg["blur_subframes"]))
    lens = LensDistortion(camera)
    outline = res.object_points_mm[0].astype(np.float64)[_loop(res.object_edges)]

    psf = float(cam_cfg["psf_sigma_px"])
    r = int(np.ceil(4 * psf)) if psf > 0 else 0  # gaussian_filter's reach (truncate 4)
    H, W = camera.height, camera.width
    push_mid = motion.push(t)
    bits, mask_px = np.zeros((n, H, (W + 7) // 8), np.uint8), np.zeros(n, np.int64)
    with (
        Studio(res.mesh, outline, camera, look, extrusion_mm, seed=seed) as studio,
        VideoWriter(
            take_dir / "take.mp4",
            fps,
            (W, H),
            crf=cam_cfg["video_crf"],
            pix_fmt=cam_cfg["video_pix_fmt"],
        ) as video,
    ):
        # Only the finger and the clamp move: the full frame is rendered and processed
        # once, and each frame re-renders and re-processes only the box they can reach.
        pin = studio.render_colour().astype(np.float32)  # the pinhole image, full frame
        still = _optics(lens.image(pin), psf)
        noise = SensorNoise(still.shape, cam_cfg["read_noise_dn"], cam_cfg["shot_gain_dn"], rng)
        sigma = noise.sigma(still)
        pin_mask = np.zeros((H, W), bool)
        # moving clutter: every pixel may change, so the box is the whole frame
        v0, v1, u0, u1 = (0, H, 0, W) if studio.moving else _moving_box(studio, fea, camera)
        studio.set_window(u0, v0, u1 - u0, v1 - v0)
        b1 = lens.box_reading(v0, v1, u0, u1)  # output pixels that sample the box
        b2 = _grow(b1, r, H, W)  # ... and those the optics' blur reaches from them
        b3 = _grow(b2, r, H, W)  # what the blur of b2 reads
        inner = (slice(b2[0] - b3[0], b2[1] - b3[0]), slice(b2[2] - b3[2], b2[3] - b3[2]))
        log(f"  moving box {u1 - u0}x{v1 - v0} px of {W}x{H}")
        next_report = 0.1
        box = (slice(b2[0], b2[1]), slice(b2[2], b2[3]))
        # a still frame at a push seen before (the rest and the hold: most of a take) is
        # that frame again up to its noise: its box, mask and noise level are kept
        seen: dict[tuple[float, float], tuple[np.ndarray, np.ndarray, np.ndarray]] = {}
        # outside the box every frame is the still one: the box is written into these
        frame, sig = still.copy(), sigma.copy()
        for k in range(n):
            subs = t[k] + exposure * (np.linspace(-0.5, 0.5, n_sub) if n_sub > 1 else np.zeros(1))
            pushes = motion.push(subs)
            key = None
            if np.ptp(pushes) < 1e-3 and not studio.moving:  # still: one render
                pushes = pushes[len(pushes) // 2 : len(pushes) // 2 + 1]
                subs = subs[len(subs) // 2 : len(subs) // 2 + 1]
                key = (float(pushes[0]), float(push_mid[k]))
            if key in seen:
                box_img, box_mask, box_sig = seen[key]
            else:
                acc = np.zeros((v1 - v0, u1 - u0, 3), np.float32)
                for d, t_sub in zip(pushes, subs):
                    studio.pose(fea.points(d), -d)
                    studio.at_time(t_sub)
                    acc += studio.render_colour()
                pin[v0:v1, u0:u1] = acc / len(pushes)
                studio.pose(fea.points(push_mid[k]), -push_mid[k])
                studio.at_time(t[k])
                pin_mask[v0:v1, u0:u1] = studio.render_mask()
                box_mask = lens.labels(pin_mask, b1)
                box_img = _optics(lens.image(pin, b3), psf)[inner]
                box_sig = noise.sigma(box_img)
                if key is not None:
                    seen[key] = (box_img, box_mask, box_sig)
            mask = np.zeros((H, W), bool)
            mask[b1[0] : b1[1], b1[2] : b1[3]] = box_mask
            bits[k], mask_px[k] = np.packbits(mask, axis=-1), mask.sum()
            frame[box], sig[box] = box_img, box_sig
            video.write(noise.apply(frame, sig))
            if (k + 1) / n >= next_report:
                log(f"  frame {k + 1}/{n} ({time.perf_counter() - t_wall:.1f} s)")
                next_report += 0.1

    # the sensor under the object: the force on the object is minus the finger's
    sensor = ForceSensor.from_config(lab["sensor"])
    offset = sensor.draw_offset(rng)

    if print_law is None or print_law.elastic:

        def print_forces(t_cam):
            return fea.forces(motion.push(t_cam))
    else:  # over the whole log, margins included, so that every sample has its history
        m = sensor.margin_s + 1.0
        print_forces = _PrintForces(fea, motion, print_law, -m, motion.duration_s + m)

    def force_at(t_cam):
        push, along = print_forces(t_cam)
        return push, -along  # on the object: minus the finger's

    flog = sensor.log(force_at, motion.duration_s, offset, rng)
    write_forces_csv(take_dir / "forces.csv", flog)
    drift = 1e-6 * sensor.drift_ppm
    # camera = sensor + offset(t): offset(t) = offset (1 + drift) - drift t (see sensor)
    offset_mid = offset * (1 + drift) - drift * 0.5 * motion.duration_s

    meta = {
        "object": object_name,
        "contact_height_mm": float(height_mm),
        "push_axis": "-fz",
        "camera": {"intrinsics": camera.intrinsics(), "model": cam_cfg["model"]},
        "video": "take.mp4",
        "emulated": "finray.emulator: an emulated rig, not a recording (see truth/truth.json)",
    }
    if look.get("finger_colour"):
        meta["finger_colour"] = look["finger_colour"]
    (take_dir / "take.json").write_text(json.dumps(meta, indent=1))
    np.savez_compressed(take_dir / "truth" / "masks.npz", bits=bits, shape=np.array([n, H, W]))
    half = 0.5 / fps  # the force over each frame's interval, as ingest labels it
    fine = np.linspace(-half, half, 21)
    f_frame = force_at((t[:, None] + fine[None, :]).ravel())[0].reshape(n, -1).mean(axis=1)
    import pandas as pd

    viscous = not (print_law is None or print_law.elastic)
    columns = {"frame": np.arange(n), "t_s": t, "push_mm": push_mid, "force_N": f_frame}
    if viscous:  # the FEA's force at the frame's push, before the print's history acts
        columns["elastic_force_N"] = fea.forces(push_mid)[0]
    pd.DataFrame({**columns, "mask_px": mask_px}).to_csv(
        take_dir / "truth" / "frames.csv", index=False, float_format="%.6g"
    )
    truth = {
        "offset_s": offset_mid,
        "offset_start_s": offset * (1 + drift),
        "offset_end_s": offset * (1 + drift) - drift * motion.duration_s,
        "frame_interval_s": 1.0 / fps,
        "n_frames": n,
        "sensor": {
            "gain": 1.0 + sensor.gain_error,
            "bias_N": list(sensor.bias_N),
            "noise_N": list(sensor.noise_N),
            "rate_hz": sensor.rate_hz,
        },
        "camera": {
            "intrinsics": camera.intrinsics(),
            "position_mm": list(camera.position),
            "target_mm": list(camera.target),
            "up": list(camera.up),
        },
        "force_max_N": float(f_frame.max()),
        "fea_result": str(result_npz),
        "push_mm": motion.push_mm,
        "force_limited": force_limited,
        "seed": seed,
        "wall_s": time.perf_counter() - t_wall,
    }
    if viscous:
        truth["print_law"] = asdict(print_law)
    (take_dir / "truth" / "truth.json").write_text(json.dumps(truth, indent=1))
    log(
        f"{take_dir.name}: {n} frames {camera.width}x{camera.height} at {fps:g} FPS, "
        f"{len(flog['t_s'])} sensor samples, offset {offset_mid:+.4f} s, "
        f"largest force {truth['force_max_N']:.2f} N ({truth['wall_s']:.1f} s)"
    )
    return truth


def _optics(img: np.ndarray, sigma_px: float) -> np.ndarray:
    """The lens and demosaicing blur: a Gaussian of ``sigma_px`` over rows and columns."""
    from scipy import ndimage as ndi

    return ndi.gaussian_filter(img, (sigma_px, sigma_px, 0)) if sigma_px > 0 else img


def _grow(box, r: int, H: int, W: int):
    return (max(box[0] - r, 0), min(box[1] + r, H), max(box[2] - r, 0), min(box[3] + r, W))


def _moving_box(studio: Studio, fea: _Interpolator, camera: PinholeCamera, margin: int = 3):
    """The pinhole image's box (rows, cols; end exclusive) that holds the finger and the
    clamp in every FEA state, each at its shift (-push along x), plus ``margin`` px."""
    pts = [
        studio.surface.deformed(fea.res.points + fea.res.u_mm[i]) - [d, 0.0, 0.0]
        for i, d in enumerate(fea.d)
    ]
    pts += [studio.clamp_ref.points - [d, 0.0, 0.0] for d in (fea.d[0], fea.d[-1])]
    uv = camera.project(np.vstack(pts))
    c0, r0 = np.floor(uv.min(axis=0)).astype(int) - margin
    c1, r1 = np.ceil(uv.max(axis=0)).astype(int) + 1 + margin
    return (max(r0, 0), min(r1, camera.height), max(c0, 0), min(c1, camera.width))


def _loop(edges: np.ndarray) -> np.ndarray:
    """The vertex order (K,) of the closed loop of segments ``edges`` (E, 2)
    (the first loop: a rigid object's outer boundary)."""
    nxt = {int(a): int(b) for a, b in edges[:, :2]}
    start = int(edges[0, 0])
    order, v = [start], nxt[start]
    while v != start and len(order) <= len(edges):
        order.append(v)
        v = nxt[v]
    return np.asarray(order)
