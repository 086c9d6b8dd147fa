"""Finding the finger in camera footage (finray.recording.finder) and flagging the frames
that cannot be trusted (finray.validity): one test per failure mode, each asserting the
flag and the message; the stress reference saved with the model labels the colour bar."""

import csv
import json

from finray.train.export import seal

import numpy as np
import pytest
import torch

from finray.cli import main
from finray.model import FinRayNet, NetConfig
from finray.predict import Predictor
from finray.recording.finder import FingerFinder, finder_from_spec, learn_finder
from finray.train import export_torchscript
from finray.validity import check_frame, near_base, training_ranges
from helpers import CAMERA_PREPROCESS as PREPROCESS
from recording_synth import APEX, FINGER_RGB, background, render_frame, write_video

SIZE = (360, 480)  # a camera frame (H, W)
PPM = SIZE[0] / 120.0
ORIGIN = (0.45 * SIZE[1], 0.88 * SIZE[0])


def frame(defl_mm=0.0, clutter=False, seed=0):
    """An orange finger over a lit grey background (the finger darker than it: the
    renders' grey threshold takes the background), bent by ``defl_mm``; ``clutter``: an
    orange disc of the finger's colour standing apart, left of it."""
    img, truth = render_frame(background(SIZE, seed), PPM, ORIGIN, defl_mm, 0.0)
    if clutter:
        rr, cc = np.ogrid[: SIZE[0], : SIZE[1]]
        disc = (rr - 0.45 * SIZE[0]) ** 2 + (cc - 0.15 * SIZE[1]) ** 2 < (0.1 * SIZE[0]) ** 2
        img[disc] = FINGER_RGB.astype(np.uint8)
    return img, truth


def finger_inputs(p: Predictor, n=5):
    """Network inputs (n, 1, H, W) of the finger bent from 0 to 4 mm (its true masks)."""
    return np.concatenate([p.network_input(frame(d)[1]) for d in np.linspace(0, 4, n)])


@pytest.fixture(scope="module")
def model(tmp_path_factory):
    """An untrained network with the contact head, exported with the training ranges of
    the synthetic finger's silhouettes (forces and heights wide open), and the same
    without them (an export before they were saved)."""
    torch.manual_seed(3)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32, contact=True))
    net.set_force_normalisation([3.0], [2.0])
    net.set_contact_normalisation(40.0, 15.0)
    net.eval()
    d = tmp_path_factory.mktemp("model")
    export_torchscript(net, d / "old.ts", PREPROCESS, contact_min_force_N=0.0)
    x = finger_inputs(Predictor(d / "old.ts", backend="torchscript"))
    trained = training_ranges(
        x, np.array([[-1e3], [1e3], [0], [0], [0]]), ["fx_N"], np.array([-1e4, 1e4, 0, 0, 0]), -1.0
    )
    export_torchscript(
        net,
        d / "model.ts",
        PREPROCESS,
        contact_min_force_N=0.0,
        stress_ref_MPa=1e-3,
        trained=trained,
    )
    return d


def test_the_finger_is_found_by_its_colour_where_the_grey_threshold_takes_the_background(model):
    img, truth = frame(2.0)
    p = Predictor(model / "model.ts", backend="torchscript")
    grey, conf_grey = p.finder.find(img)
    assert grey.mean() > 0.5  # the bright background
    x = p.network_input(grey)
    assert "fills_frame" in p.check(grey, conf_grey, x, p.forces(img))
    found = learn_finder([frame(0.0)[0]] * 3, p.finder)
    assert found.mode == "colour" and "learned" in found.describe()
    mask, conf = found.find(img)
    iou = (mask & truth).sum() / (mask | truth).sum()
    assert iou > 0.9 and conf > 0.95
    p.finder = found
    x = p.network_input(mask)
    assert p.check(mask, conf, x, p.forces(img)) == []
    # a render (a bright finger on black): the grey threshold finds the same finger and is kept
    render = np.where(truth[..., None], FINGER_RGB, 12).astype(np.uint8)
    kept = learn_finder([render], FingerFinder.grey(PREPROCESS["segment"], 4))
    assert kept.mode == "grey" and "same finger" in kept.describe()


def test_a_take_where_the_finger_is_never_found_stops_with_one_line(model, tmp_path, capsys):
    """Finger not found: every frame lacks it -> exit 2, one line naming the count."""
    video = tmp_path / "empty.mp4"
    write_video(
        video, [np.clip(background(SIZE, k), 0, 255).astype(np.uint8) for k in range(4)], 10
    )
    assert (
        main(
            [
                "predict",
                "--model",
                str(model / "model.ts"),
                str(video),
                "--out",
                str(tmp_path / "out"),
                "--finger-colour",
                "orange",
            ]
        )
        == 2
    )
    err = [line for line in capsys.readouterr().err.strip().splitlines() if "note:" not in line]
    assert len(err) == 1 and err[0].startswith(
        "finray predict: the finger was found in none of the 4 frames of"
    ), err
    assert "--finger-colour" in err[0] and "--check" in err[0]
    assert (
        main(
            [
                "predict",
                "--model",
                str(model / "model.ts"),
                str(video),
                "--out",
                str(tmp_path / "out"),
                "--segmentation",
                "colour",
            ]
        )
        == 2
    )
    assert "no finger colour could be learned" in capsys.readouterr().err


def test_a_mask_filling_the_frame_is_flagged(model, tmp_path, capsys):
    """The renders' grey threshold on a camera's bright background: every frame flagged,
    a column of forces.csv and a warning with the count; the learned colour: none."""
    video = tmp_path / "take.mp4"
    write_video(video, [frame(d)[0] for d in (0.0, 1.0, 2.0)], 10)
    assert (
        main(
            [
                "predict",
                "--model",
                str(model / "model.ts"),
                str(video),
                "--out",
                str(tmp_path / "grey"),
                "--segmentation",
                "grey",
                "--force-only",
            ]
        )
        == 0
    )
    rows = list(csv.DictReader(open(tmp_path / "grey" / "forces.csv")))
    assert len(rows) == 3 and all("fills_frame" in r["valid"] for r in rows)
    io = capsys.readouterr()
    assert "finray predict: warning: 3 of 3 frames flagged" in io.err and "fills_frame 3" in io.err
    assert io.out.count("\tNOT VALID: fills_frame") == 3  # each frame's line says so too
    assert (
        main(
            [
                "predict",
                "--model",
                str(model / "model.ts"),
                str(video),
                "--out",
                str(tmp_path / "auto"),
                "--force-only",
            ]
        )
        == 0
    )
    rows = list(csv.DictReader(open(tmp_path / "auto" / "forces.csv")))
    assert [r["valid"] for r in rows] == ["ok"] * 3
    io = capsys.readouterr()
    assert "warning" not in io.err and "note: finger found by colour" in io.err
    saved = json.loads((tmp_path / "auto" / "segmentation.json").read_text())
    assert saved["mode"] == "colour"
    again = finder_from_spec(str(tmp_path / "auto" / "segmentation.json"))  # reused as given
    assert again.colour == finder_from_spec(saved).colour and again.mode == "colour"


def test_clutter_of_the_fingers_colour_is_flagged(model, tmp_path, capsys):
    """A second object of the finger's colour in view: the finger is still the one kept,
    but the frame is flagged low_confidence; the annotated frame gets a red border."""
    p = Predictor(model / "model.ts", backend="torchscript", finder=finder_from_spec("orange"))
    clean, truth = frame(1.0)
    mask, conf = p.find(clean)
    assert p.check(mask, conf, p.network_input(mask), p.forces(clean)) == []
    cluttered, _ = frame(1.0, clutter=True)
    mask, conf = p.find(cluttered)
    assert (mask & truth).sum() / (mask | truth).sum() > 0.9 and conf < 0.8
    assert p.check(mask, conf, p.network_input(mask), p.forces(cluttered)) == ["low_confidence"]
    from PIL import Image

    Image.fromarray(cluttered).save(tmp_path / "cluttered.png")
    assert (
        main(
            [
                "predict",
                "--model",
                str(model / "model.ts"),
                str(tmp_path / "cluttered.png"),
                "--out",
                str(tmp_path / "out"),
                "--finger-colour",
                "orange",
                "--annotate",
            ]
        )
        == 0
    )
    assert "low_confidence 1 (much of the finger's colour lies outside" in capsys.readouterr().err
    ann = np.asarray(Image.open(tmp_path / "out" / "cluttered_annotated.png"))
    assert (ann[SIZE[0] // 2, 0] == (255, 40, 40)).all()  # the red border


def test_a_contact_outside_the_trained_heights_is_flagged(model, tmp_path):
    d = tmp_path / "m"
    d.mkdir()
    meta = json.loads((model / "model.ts.json").read_text())
    for name in ("model.ts", "model.ts.json"):
        (d / name).write_bytes((model / name).read_bytes())
    img = frame(1.0)[0]
    p = Predictor(d / "model.ts", backend="torchscript", finder=finder_from_spec("orange"))
    mask, conf = p.find(img)
    out = p.forces(img)
    assert p.check(mask, conf, p.network_input(mask), out) == []
    # heights trained far above the predicted one
    meta["trained"]["contact_mm"] = [out["contact_mm"] + 10.0, out["contact_mm"] + 30.0]
    (d / "model.ts.json").write_text(json.dumps(meta))
    seal(d / "model.ts")  # an export of these ranges (an edited file is refused)
    p = Predictor(d / "model.ts", backend="torchscript", finder=finder_from_spec("orange"))
    assert p.check(mask, conf, p.network_input(mask), out) == ["contact_range"]
    # below the smallest force the height was trained on, the height is a guess: not flagged
    p.contact_min_force_N = abs(out["fx_N"]) + 1.0
    assert p.check(mask, conf, p.network_input(mask), out) == []


def test_something_of_the_fingers_colour_touching_it_is_flagged_grown(model, tmp_path):
    """A video whose first frames show the finger alone, then a patch of its colour
    touching its side (one blob with it: the colour finder's confidence stays high):
    those frames are flagged ``grown`` against the first frames' mask, the others not;
    separate images have no first frames to compare with, and are not checked."""
    from scipy import ndimage as ndi

    from finray.predict import predict_files

    frames, touched = [], []
    for k in range(12):
        img, truth = frame(0.1 * k, seed=k)
        if k >= 8:
            band = ndi.binary_dilation(truth, iterations=12) & ~truth
            rows = np.flatnonzero(truth.any(axis=1))
            band[: rows[0] + (rows[-1] - rows[0]) // 3] = False  # its upper two thirds
            band[rows[0] + 2 * (rows[-1] - rows[0]) // 3 :] = False
            img[band] = FINGER_RGB.astype(np.uint8)
        frames.append(img)
        touched.append(k >= 8)
    write_video(tmp_path / "take.mp4", frames, 30.0, pix_fmt="yuv444p")
    res = predict_files(
        model / "model.ts",
        tmp_path / "take.mp4",
        tmp_path / "out",
        force_only=True,
        segmentation="colour",
    )
    valid = [r["valid"] for r in res["rows"]]
    assert ["grown" in v for v in valid] == touched, valid
    assert set(valid[:8]) == {"ok"}
    assert check_frame(0.1, 0.0, 1.0, np.zeros((1, 1, 8, 4)), {}, None, growth=0.04) == []
    assert check_frame(0.1, 0.0, 1.0, np.zeros((1, 1, 8, 4)), {}, None, growth=0.06) == ["grown"]
    for k, img in enumerate(frames):
        from PIL import Image

        Image.fromarray(img).save(tmp_path / f"f{k:02d}.png")
    res = predict_files(
        model / "model.ts", tmp_path, tmp_path / "images", force_only=True, segmentation="colour"
    )
    assert not any("grown" in r["valid"] for r in res["rows"])


def test_force_shape_and_window_checks():
    x = np.zeros((1, 1, 64, 32), np.float32)
    x[..., 10:, 4:20] = 1.0
    trained = training_ranges(np.repeat(x, 3, axis=0), np.array([[0.0], [5.0], [10.0]]), ["fx_N"])
    assert check_frame(0.1, 0.0, 1.0, x, {"fx_N": 5.0}, trained) == []
    assert check_frame(0.1, 0.0, 1.0, x, {"fx_N": 12.0}, trained) == ["force_range"]
    assert check_frame(0.1, 0.0, 1.0, x, {"fx_N": 10.5}, trained) == []  # within 10 % of the span
    other = np.zeros_like(x)
    other[..., :30, 10:32] = 1.0  # another silhouette
    assert check_frame(0.1, 0.0, 1.0, other, {"fx_N": 5.0}, trained) == ["shape"]
    assert check_frame(0.1, 0.3, 1.0, x, {"fx_N": 5.0}, None) == ["off_frame"]


def test_a_contact_where_the_training_was_stiff_is_flagged_near_base():
    x = np.zeros((4, 1, 64, 32), np.float32)
    x[..., 10:, 4:20] = 1.0
    force = np.array([[1.0], [8.0], [30.0], [6.0]])
    contact = np.array([15.0, 9.0, 6.0, 40.0])
    stiff = np.array([0.5, 5.0, 20.0, np.nan])  # N/mm: the frames at 9 and 6 mm are stiff
    trained = training_ranges(x, force, ["fx_N"], contact, 0.2, stiffness_N_per_mm=stiff)
    assert trained["stiff_below_mm"] == 9.0
    one = x[:1]
    assert check_frame(0.1, 0.0, 1.0, one, {"fx_N": 5.0, "contact_mm": 8.0}, trained, 0.2) == [
        "near_base"
    ]
    assert check_frame(0.1, 0.0, 1.0, one, {"fx_N": 5.0, "contact_mm": 12.0}, trained, 0.2) == []
    # unloaded, the contact head's height is a guess: not flagged
    assert check_frame(0.1, 0.0, 1.0, one, {"fx_N": 0.1, "contact_mm": 8.0}, trained, 0.2) == []
    # no frame above the limit: nothing to flag
    soft = training_ranges(x, force, ["fx_N"], contact, 0.2, stiffness_N_per_mm=stiff / 10)
    assert "stiff_below_mm" not in soft
    # the array form (sim-to-real's) flags the same frames as check_frame
    cs, fs = np.array([8.0, 12.0, 8.0, np.nan, 3.0]), np.array([5.0, 5.0, 0.1, 9.0, -7.0])
    one_by_one = [
        "near_base" in check_frame(0.1, 0.0, 1.0, one, {"fx_N": f, "contact_mm": c}, trained, 0.2)
        for c, f in zip(cs, fs)
    ]
    assert (
        near_base(cs, fs, trained, 0.2).tolist() == one_by_one == [True, False, False, False, True]
    )
    assert not near_base(cs, fs, soft, 0.2).any() and not near_base(cs, fs, None).any()


def test_the_stress_reference_saved_with_the_model_labels_the_colour_bar(model, tmp_path):
    """A model exported with another stress_ref: the bar's ticks (MPa) sit where the ramp
    has the colour the overlay gives a map value of that stress at the model's reference;
    an export without it falls back to 1 kPa with a note."""
    from finray.annotate import _bar_panel, _lut, bar_tick_rows, stress_log, stress_log_max

    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32)).eval()
    export_torchscript(net, tmp_path / "m.ts", PREPROCESS, stress_ref_MPa=1e-2)
    p = Predictor(tmp_path / "m.ts", backend="torchscript")
    assert p.stress_ref_MPa == 1e-2 and not any("stress_ref" in n for n in p.notes)
    H = 400
    panel = _bar_panel(H, p.stress_ref_MPa)
    lut = _lut().astype(int)
    for t, row in bar_tick_rows(H, p.stress_ref_MPa).items():
        r = min(max(int(round(row)), int(0.12 * H)), int(0.88 * H) - 1)  # on the ramp
        bar = panel[r, 18].astype(int)
        shown = int(np.argmin(((lut - bar) ** 2).sum(axis=1)))
        want = round(
            float(stress_log(t, p.stress_ref_MPa)) / stress_log_max(p.stress_ref_MPa) * 255
        )
        assert abs(shown - want) <= 3, (t, shown, want)
    # the 1 kPa labels would sit elsewhere: 0.1 MPa at 67 % of the bar, not 52 %
    assert abs(float(stress_log(0.1)) / stress_log_max() - 0.667) < 0.01
    assert abs(float(stress_log(0.1, 1e-2)) / stress_log_max(1e-2) - 0.519) < 0.01
    old = Predictor(model / "old.ts", backend="torchscript")
    assert old.stress_ref_MPa == 1e-3 and any("no stress_ref_MPa" in n for n in old.notes)
    assert old.trained is None and any("no training ranges" in n for n in old.notes)


def test_one_video_writer():
    """Video is written in one place (finray.media.VideoWriter)."""
    from pathlib import Path

    import finray

    src = Path(finray.__file__).parent
    homes = [f for f in src.rglob("*.py") if "class VideoWriter" in f.read_text()]
    assert [f.relative_to(src).as_posix() for f in homes] == ["media.py"]


def test_apex_is_in_view():
    """The synthetic frames hold the whole finger (the checks' premise)."""
    _, truth = frame(0.0)
    rows = np.flatnonzero(truth.any(axis=1))
    assert rows[0] > 0 and rows[-1] < SIZE[0] - 1 and APEX[1] * PPM < SIZE[0]


def _emulated_rig(tmp_path):
    """A synthetic FEA result, the smoke config's look of the emulated rig and a
    320 x 240 camera on it: what a Studio needs."""
    from finray.config import load_config
    from finray.emulator.camera import PinholeCamera
    from finray.render.result import load_fea_result
    from helpers import write_synthetic_fea_result

    res = load_fea_result(
        write_synthetic_fea_result(
            tmp_path / "result.npz", n_frames=3, max_displacement_mm=2.0, size_mm=1.0
        )
    )
    look = dict(load_config("config/smoke.yaml")["lab"]["look"])
    cam = PinholeCamera.looking_at(
        (5.0, 38.0, 0.0), width=320, height=240, hfov_deg=69.4, distance_mm=200
    )
    return res, look, cam


def test_the_emulated_rig_draws_clutter_that_the_finder_flags(tmp_path):
    """The emulated rig's scene with a second object of the finger's colour and a hand:
    the label view (the true mask) leaves them out; the colour finder keeps the finger
    and flags the frame low_confidence."""
    from finray.emulator.studio import Studio

    res, look, cam = _emulated_rig(tmp_path)
    outline = res.object_points_mm[0].astype(float)
    views = {}
    for name, clutter in (
        ("plain", []),
        (
            "clutter",
            [
                {"kind": "object", "centre_mm": [65.0, 40.0], "size_mm": [14.0, 20.0]},
                {"kind": "hand", "centre_mm": [-45.0, 75.0], "size_mm": [40.0, 25.0]},
            ],
        ),
    ):
        with Studio(res.mesh, outline, cam, look | {"clutter": clutter}, 20.0) as scene:
            scene.pose(res.deformed_points(0), 0.0)
            views[name] = (scene.render_colour().copy(), scene.render_mask().copy())
    (plain, truth), (cluttered, truth_c) = views["plain"], views["clutter"]
    assert np.array_equal(truth, truth_c)  # the clutter stands apart: the finger is whole
    box = cam.project(np.array([[58.0, 30.0, 10.0], [72.0, 50.0, 10.0]]))
    c0, c1 = sorted(box[:, 0].astype(int))
    r0, r1 = sorted(box[:, 1].astype(int))
    patch = cluttered[r0 + 2 : r1 - 2, c0 + 2 : c1 - 2].reshape(-1, 3).astype(int)
    assert (patch[:, 0] > patch[:, 2] + 60).mean() > 0.9  # the finger's orange
    finder = finder_from_spec("orange", stride=2)
    mask, conf = finder.find(plain)
    assert conf > 0.9 and (mask & truth).sum() / (mask | truth).sum() > 0.8
    mask, conf = finder.find(cluttered)
    assert (mask & truth).sum() / (mask | truth).sum() > 0.8 and conf < 0.8


def test_the_emulated_rig_moves_clutter_behind_the_finger(tmp_path):
    """A hand passing behind the rig (``velocity_mm_s``): Studio.at_time moves it, the
    colour view shows it where v * t puts it, and the true finger mask never changes."""
    from finray.emulator.studio import Studio

    res, look, cam = _emulated_rig(tmp_path)
    hand = {"kind": "hand", "centre_mm": [-60.0, 20.0], "size_mm": [30.0, 20.0]}
    hand |= {"velocity_mm_s": [40.0, 0.0], "z_mm": -30.0}
    skin = np.array([0.80, 0.52, 0.40])
    centres, masks = [], []
    outline = res.object_points_mm[0].astype(float)
    with Studio(res.mesh, outline, cam, look | {"clutter": [hand]}, 20.0) as studio:
        studio.pose(res.deformed_points(0), 0.0)
        for t in (0.0, 1.0):
            studio.at_time(t)
            img = studio.render_colour().astype(float) / 255
            masks.append(studio.render_mask().copy())
            ratio = img / np.maximum(img.max(axis=-1, keepdims=True), 1e-6)
            near = np.linalg.norm(ratio - skin / skin.max(), axis=-1) < 0.08
            near &= img.max(axis=-1) > 0.2
            cols = np.flatnonzero(near.any(axis=0))
            centres.append(0.5 * (cols[0] + cols[-1]))
    assert np.array_equal(masks[0], masks[1])
    at = cam.project(np.array([[-60.0, 20.0, -30.0], [-20.0, 20.0, -30.0]]))  # 40 mm in 1 s
    assert centres[1] - centres[0] == pytest.approx(at[1, 0] - at[0, 0], abs=6)


def test_the_stress_reference_comes_from_the_training_shards(tmp_path):
    """The stress reference saved with a model is the one its shards' renders used
    (render.stress_ref_MPa); shards on two scales cannot train one network."""
    from finray.train.data import shard_stress_ref

    def shard(name, ref):
        meta = {"render": {} if ref is None else {"stress_ref_MPa": ref}}
        np.savez(tmp_path / name, meta=np.array(json.dumps(meta)))
        return tmp_path / name

    a, b, c = shard("a.npz", 0.01), shard("b.npz", 0.01), shard("c.npz", 0.001)
    assert shard_stress_ref([a, b]) == 0.01
    assert shard_stress_ref([shard("old.npz", None)]) is None
    with pytest.raises(ValueError, match="different references"):
        shard_stress_ref([a, c])


def test_a_trained_model_saves_its_stress_reference_and_ranges(tmp_path, monkeypatch):
    """train_from_shards writes into model.ts.json the shards' stress reference, the force
    normalisation and the training's ranges, which the predictor reads back."""
    import finray.train.stage as stage
    from finray.train import TrainConfig

    rng = np.random.default_rng(0)
    n = 48
    images = np.zeros((n, 1, 32, 16), "f4")
    images[:, :, 4:, 3:11] = 1.0
    force = rng.uniform(0.5, 6.0, (n, 1)).astype("f4")
    fake = {
        "images": images,
        "stress": np.zeros_like(images),
        "force_N": force,
        "contact_mm": np.full(n, np.nan, "f4"),
        "scene_id": np.repeat([f"s{k}" for k in range(8)], n // 8),
    }
    monkeypatch.setattr(stage, "load_split", lambda *a, **k: fake)
    np.savez(
        tmp_path / "shard.npz", meta=np.array(json.dumps({"render": {"stress_ref_MPa": 0.004}}))
    )
    stage.train_from_shards(
        [tmp_path / "shard.npz"],
        tmp_path / "out",
        NetConfig(in_channels=1, height=32, width=16, base_channels=4),
        TrainConfig(epochs=1, batch_size=16, contact_weight=0.0, threads=1, progress=False),
        None,
        0.25,
        log=lambda m: None,
    )
    meta = json.loads((tmp_path / "out" / "model.ts.json").read_text())
    assert meta["stress_ref_MPa"] == 0.004
    train_ids = ~np.isin(fake["scene_id"], list(stage.validation_scenes(fake["scene_id"], 0.25, 0)))
    lo, hi = meta["trained"]["force_N"]["fx_N"]
    assert lo == pytest.approx(force[train_ids].min()) and hi == pytest.approx(
        force[train_ids].max()
    )
    assert (
        meta["trained"]["fill"] == pytest.approx([28 / 32 * 8 / 16] * 2)
        and meta["trained"]["shape_iou_min"] == 1.0
    )
    assert len(meta["force_normalisation"]["mean_N"]) == 1
    p = Predictor(tmp_path / "out" / "model.ts", backend="torchscript")
    assert p.stress_ref_MPa == 0.004 and p.trained == meta["trained"] and p.notes == []


def test_check_reports_the_mask_and_validity_of_a_few_frames(model, tmp_path, capsys):
    """``finray predict --check``: frames spread over the take, each with its mask share,
    confidence and flags, check.png, exit 0 for a good set-up and 1 for a bad one."""
    video = tmp_path / "take.mp4"
    write_video(video, [frame(d)[0] for d in np.linspace(0, 3, 12)], 10)
    args = ["predict", "--model", str(model / "model.ts"), str(video), "--check", "4"]
    assert main([*args, "--out", str(tmp_path / "good")]) == 0
    out = capsys.readouterr().out.strip().splitlines()
    assert out[0].startswith("finger found by colour")
    frames = [line for line in out if line.startswith("take_")]
    assert [f.split("\t")[0] for f in frames] == [
        "take_00000",
        "take_00003",
        "take_00006",
        "take_00009",
    ]
    assert all(f.endswith("\tok") for f in frames) and out[-1].startswith("set-up OK: 4 of 4")
    assert (tmp_path / "good" / "check.png").is_file()
    assert main([*args, "--out", str(tmp_path / "bad"), "--segmentation", "grey"]) == 1
    out = capsys.readouterr().out
    assert "fills_frame" in out and "set-up NOT OK: 0 of 4" in out
