"""Progress lines of long jobs (FEA scenes, rendering) reach the job's log."""

import re

from finray.fea.material import NeoHookean
from finray.fea.simulate import SimulationOptions, simulate
from finray.geometry.finger import FingerParams, mesh_finger
from finray.logs import JOB_CPU, Progress, log_to
from finray.render import RenderParams, render_scene

from helpers import front_contact_circle, write_synthetic_fea_result


def test_fea_scene_logs_frame_travel_and_time(tmp_path):
    finger = mesh_finger(FingerParams(), size_mm=2.0)
    obj = front_contact_circle(FingerParams(), 30.0, 20.0, gap_mm=0.1)
    with log_to(tmp_path / "fea.log"):  # as the workflow's fea_scene job runs it
        simulate(
            finger,
            obj,
            NeoHookean.from_E_nu(12.0, 0.45, "ninjaflex"),
            SimulationOptions(push_mm=1.0, frame_step_mm=0.5, log_every_s=0),
        )
    lines = (tmp_path / "fea.log").read_text().splitlines()
    assert lines.pop().startswith(JOB_CPU)  # log_to's last line: the job's CPU time
    assert lines[0].startswith("FEA circle_d20: push 1 mm in 2 frames")
    pat = r"FEA circle_d20: frame (\d)/2, travel ([\d.]+)/1 mm, \d+ load steps, [\d.]+ s"
    got = [re.fullmatch(pat, line) for line in lines[1:]]
    assert all(got), lines
    assert [(m[1], m[2]) for m in got] == [("1", "0.50"), ("2", "1.00")]


def test_progress_lines_are_periodic_and_end_at_the_last_frame(monkeypatch, caplog):
    import logging

    import finray.logs

    clock = iter([0.0, 10.0, 25.0, 31.0, 40.0, 45.0])  # start, then frames 1-5 done
    monkeypatch.setattr(finray.logs.time, "perf_counter", lambda: next(clock))
    progress = Progress(logging.getLogger("finray.test"), "job", 5, every_s=30.0)
    with caplog.at_level(logging.INFO, logger="finray.test"):
        for k in range(1, 6):
            progress(k, f"travel {k}.00 mm")
    assert caplog.messages == [
        "job: frame 3/5, travel 3.00 mm, 31.0 s",
        "job: frame 5/5, travel 5.00 mm, 45.0 s",
    ]


def test_render_logs_frame_travel_and_time(tmp_path):
    res = write_synthetic_fea_result(tmp_path / "result.npz", n_frames=4)
    with log_to(tmp_path / "render.log"):  # as the workflow's render job runs it
        index = render_scene(
            res,
            tmp_path / "p0",
            0.0,
            params=RenderParams(frames_per_scene=3),
            scene={"object": "c10", "material": "steel", "height_mm": 30},
            log_every_s=0,
        )
    lines = (tmp_path / "render.log").read_text().splitlines()
    assert lines.pop().startswith(JOB_CPU)  # log_to's last line: the job's CPU time
    assert lines[0] == "render c10_steel_h30: 3 frames at pitch 0 deg (raster)"
    travel = [f"{f['displacement_mm']:.2f}" for f in index["frames"]]
    pat = r"render c10_steel_h30: frame (\d)/3, travel ([\d.]+) mm, [\d.]+ s"
    got = [re.fullmatch(pat, line) for line in lines[1:]]
    assert all(got), lines
    assert [(m[1], m[2]) for m in got] == [("1", travel[0]), ("2", travel[1]), ("3", travel[2])]
