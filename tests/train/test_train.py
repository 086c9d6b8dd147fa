"""Training loop: determinism, learning, checkpoint and TorchScript parity."""

import numpy as np
import pytest
import torch

from finray.model import NetConfig
from finray.train import (
    TrainConfig,
    evaluate,
    export_torchscript,
    load_checkpoint,
    save_checkpoint,
    train,
    training_curves,
)

from helpers import CFG, toy


@pytest.mark.parametrize("bf16", [False, True])
def test_two_trainings_give_identical_losses(bf16):
    # the type pinned: `auto` times both on the network, and on this toy network they
    # tie, so that a loaded machine's timing noise could pick a different type per run
    x, s, f = toy()
    runs = [
        train(
            x,
            s,
            f,
            (x[:16], s[:16], f[:16]),
            NetConfig(height=32, width=16, base_channels=4),
            TrainConfig(**{**CFG, "bf16": bf16}),
            log=lambda m: None,
        )[1]
        for _ in range(2)
    ]
    assert runs[0].precision == ("bfloat16" if bf16 else "float32")
    assert runs[0].train_loss == runs[1].train_loss
    assert runs[0].val_loss == runs[1].val_loss


def test_training_reduces_the_loss():
    x, s, f = toy(256)
    _, hist = train(
        x,
        s,
        f,
        None,
        NetConfig(height=32, width=16, base_channels=4),
        TrainConfig(**{**CFG, "epochs": 4, "bf16": False}),
        log=lambda m: None,
    )
    assert hist.train_loss[-1] < 0.7 * hist.train_loss[0]


def test_nan_data_is_refused():
    x, s, f = toy(32)
    f[3] = np.nan
    with pytest.raises(ValueError, match="NaN"):
        train(x, s, f, None, NetConfig(height=32, width=16, base_channels=4), TrainConfig(**CFG))


def test_checkpoint_and_torchscript_parity(tmp_path):
    x, s, f = toy(64)
    model, hist = train(
        x,
        s,
        f,
        None,
        NetConfig(height=32, width=16, base_channels=4),
        TrainConfig(**CFG),
        log=lambda m: None,
    )
    save_checkpoint(model, hist, tmp_path / "m.pt")
    back, ck = load_checkpoint(tmp_path / "m.pt")
    export_torchscript(back, tmp_path / "m.ts")
    ts = torch.jit.load(str(tmp_path / "m.ts"))
    xt = torch.as_tensor(x[:8])
    with torch.no_grad():
        s1, f1 = model.float().eval().to(memory_format=torch.contiguous_format)(xt)
        s2, f2 = ts(xt)
    assert (f1 - f2).abs().max() < 1e-4
    assert (s1 - s2).abs().max() < 1e-4
    assert ck["history"]["train_loss"] == hist.train_loss
    # the force comes out in N: mean of the predictions near the data's mean
    assert abs(float(f1.mean()) - float(f.mean())) < 3 * float(f.std())


def test_cosine_schedule_warms_up_peaks_and_ends_at_zero():
    from finray.train import lr_factor

    total = 1000
    f = [lr_factor(k, total, "cosine", 0.05) for k in range(total)]
    assert f[0] == pytest.approx(1 / 51) and f[49] == pytest.approx(50 / 51)
    assert max(f) == pytest.approx(1.0) and f.index(max(f)) == 50
    assert all(a >= b for a, b in zip(f[50:], f[51:]))  # no rise after the warm-up
    assert f[-1] < 1e-4
    assert f[50 + 475] == pytest.approx(0.5, abs=1e-2)  # half-way down the cosine
    assert {lr_factor(k, total, "constant") for k in range(total)} == {1.0}
    with pytest.raises(ValueError, match="train.schedule"):
        lr_factor(0, total, "step")


def test_batchnorm_re_estimate_is_the_plain_average_over_the_frames():
    from finray.model import FinRayNet
    from finray.train import recalibrate_batchnorm

    torch.manual_seed(0)
    model = FinRayNet(NetConfig(in_channels=1, height=32, width=16, base_channels=4)).eval()
    x = torch.rand(300, 1, 32, 16)
    with torch.no_grad():
        z = model.force_head[:3](model.encode(x)[0])  # the first batch-norm's input
    n = recalibrate_batchnorm(model, x.split(64), torch.device("cpu"), False, False)
    bn = model.force_head[3]
    assert n == 300
    # per batch the mean and the unbiased variance, averaged over the batches (update_bn's
    # estimate; the last batch is short)
    assert torch.allclose(
        bn.running_mean, torch.stack([b.mean(0) for b in z.split(64)]).mean(0), atol=1e-5
    )
    var = torch.stack([b.var(0) for b in z.split(64)]).mean(0)
    assert torch.allclose(bn.running_var, var, rtol=1e-4)
    assert bn.momentum == 0.1 and not model.training  # both restored


def test_kept_epoch_follows_train_keep():
    x, s, f = toy()
    val = (x[:16], s[:16], f[:16])
    net = NetConfig(height=32, width=16, base_channels=4)
    _, last = train(x, s, f, val, net, TrainConfig(**CFG, keep="last"), log=lambda m: None)
    assert last.best_epoch == 2 and len(last.lr) == 2 and last.lr[-1] < 1e-6
    _, best = train(
        x, s, f, val, net, TrainConfig(**CFG, keep="val_force_rmse"), log=lambda m: None
    )
    assert best.best_epoch == 1 + int(np.argmin(best.val_force_rmse_N))
    with pytest.raises(ValueError, match="train.keep"):
        train(x, s, f, val, net, TrainConfig(**CFG, keep="best"), log=lambda m: None)


def test_validation_scenes_follow_split_seed_not_seed(tmp_path, monkeypatch):
    """The validation scenes are part of the data (``train.split_seed``): a seed study
    trains every seed on the same scenes."""
    import finray.train.stage as stage

    n_scenes, per = 20, 3
    ids = np.repeat([f"scene{k:02d}" for k in range(n_scenes)], per)
    images = np.repeat(np.arange(n_scenes, dtype="f4"), per)[:, None, None, None] * np.ones(
        (1, 1, 32, 16), "f4"
    )
    fake = {
        "images": images,
        "stress": np.zeros_like(images),
        "force_N": np.zeros((len(ids), 1), "f4"),
        "scene_id": ids,
    }
    monkeypatch.setattr(stage, "load_split", lambda *a, **k: fake)

    class Stop(Exception):
        pass

    def held_out(seed, split_seed):
        def capture(images, stress, force, val, *a, **k):
            raise Stop({f"scene{int(v):02d}" for v in val[0][:, 0, 0, 0]})

        monkeypatch.setattr(stage, "train", capture)
        with pytest.raises(Stop) as stop:
            stage.train_from_shards(
                [],
                tmp_path,
                NetConfig(height=32, width=16),
                TrainConfig(seed=seed, split_seed=split_seed, contact_weight=0.0),
                None,
                0.1,
                log=lambda m: None,
            )
        return stop.value.args[0]

    same = held_out(0, 0)
    assert len(same) == 2 and same == stage.validation_scenes(ids, 0.1, 0)
    assert held_out(1, 0) == same and held_out(2, 0) == same
    assert held_out(0, 5) == stage.validation_scenes(ids, 0.1, 5) != same


def test_training_starts_from_the_given_weights():
    """``init_state``: the network starts from another's weights and force scale. At a
    learning rate of zero its weights stay those (only batch-norm statistics move); from
    new weights they are not those."""
    x, s, f = toy(64)
    net = NetConfig(height=32, width=16, base_channels=4)
    start, _ = train(x, s, f, None, net, TrainConfig(**CFG), log=lambda m: None)
    x2, s2, f2 = toy(64, seed=1)  # other data: another force scale of its own
    still, hist = train(
        x2,
        s2,
        f2,
        None,
        net,
        TrainConfig(**{**CFG, "lr": 0.0, "seed": 3}),
        log=lambda m: None,
        init_state=start.state_dict(),
    )
    fresh, _ = train(
        x2, s2, f2, None, net, TrainConfig(**{**CFG, "lr": 0.0, "seed": 3}), log=lambda m: None
    )
    for (name, a), b, c in zip(start.named_parameters(), still.parameters(), fresh.parameters()):
        assert torch.equal(a, b), name
        assert not torch.equal(a, c), name
    assert torch.equal(still.force_mean_N, start.force_mean_N)
    assert hist.force_mean_N == start.force_mean_N.tolist()


def test_a_start_of_another_network_is_refused(tmp_path, monkeypatch):
    """``train_from_shards(init=...)`` with a checkpoint of another network (here: other
    channel counts) stops with one line before training."""
    import finray.train.stage as stage

    x, s, f = toy(32)
    model, hist = train(
        x,
        s,
        f,
        None,
        NetConfig(height=32, width=16, base_channels=4),
        TrainConfig(**CFG),
        log=lambda m: None,
    )
    save_checkpoint(model, hist, tmp_path / "start.pt")
    ids = np.repeat([f"scene{k}" for k in range(4)], 8)
    fake = {"images": x[:, :1], "stress": s, "force_N": f, "scene_id": ids}
    monkeypatch.setattr(stage, "load_split", lambda *a, **k: fake)
    monkeypatch.setattr(stage, "train", lambda *a, **k: pytest.fail("trained"))
    with pytest.raises(ValueError, match=r"start\.pt: its network .* is not the one to train"):
        stage.train_from_shards(
            [],
            tmp_path / "out",
            NetConfig(height=32, width=16, base_channels=8),
            TrainConfig(**CFG),
            None,
            0.25,
            log=lambda m: None,
            init=tmp_path / "start.pt",
        )


def toy_contact(n=128, seed=0):
    """A learnable contact height: a bright line across a dim image at the contact's row
    (mm above the bottom edge of an 80 mm window); forces in [0, 3) N drawn apart."""
    rng = np.random.default_rng(seed)
    x = 0.2 * rng.random((n, 1, 32, 16)).astype("f4")
    row = rng.integers(2, 30, n)
    x[np.arange(n), 0, row] = 1.0
    x[np.arange(n), 0, row - 1] = 0.8
    contact = (80.0 * (1 - (row + 0.5) / 32)).astype("f4")
    f = (3.0 * rng.random(n)).astype("f4")[:, None]
    return x, x.copy(), f, contact


CONTACT_NET = NetConfig(in_channels=1, height=32, width=16, base_channels=4, contact=True)


@pytest.mark.slow
def test_the_contact_head_learns_a_height_it_can_see():
    """Trained on the toy's heights, the head's validation RMSE (mm, over the masked
    frames) is a fraction of the heights' spread; the history records it."""
    x, s, f, c = toy_contact(256)
    cfg = TrainConfig(**{**CFG, "epochs": 8, "lr": 3e-3, "contact_weight": 1.0})
    val = toy_contact(128, seed=1)
    model, hist = train(x, s, f, val, CONTACT_NET, cfg, log=lambda m: None, contact_mm=c)
    keep = np.abs(val[2][:, 0]) > cfg.contact_min_force_N
    assert hist.val_contact_rmse_mm[-1] < 0.4 * val[3][keep].std()
    assert hist.train_contact_mse[-1] < 0.5 * hist.train_contact_mse[0]
    ev = evaluate(
        model, *(torch.as_tensor(a) for a in val[:3]), cfg, contact_mm=torch.as_tensor(val[3])
    )
    err = (ev["contact_pred_mm"].numpy() - val[3])[keep]
    assert ev["contact_rmse_mm"] == pytest.approx(float(np.sqrt(np.mean(err**2))), rel=1e-4)


def test_the_contact_loss_sees_the_masked_frames_only():
    """Frames without a height (NaN) or pushed less than contact_min_force_N add nothing:
    other labels there leave the training identical; the normalisation is the masked
    frames' mean and standard deviation."""
    x, s, f, c = toy_contact(64)
    f[::3] = 0.05  # below 0.2 N
    c[1::3] = np.nan
    other = c.copy()
    other[::3] = 1e4
    keep = (np.abs(f[:, 0]) > 0.2) & np.isfinite(c)
    # one type for both (`auto` may time the toy network's two types as a tie either way)
    cfg = TrainConfig(**{**CFG, "contact_weight": 2.0, "bf16": False})
    a, ha = train(x, s, f, None, CONTACT_NET, cfg, log=lambda m: None, contact_mm=c)
    b, hb = train(x, s, f, None, CONTACT_NET, cfg, log=lambda m: None, contact_mm=other)
    assert ha.train_loss == hb.train_loss and np.isfinite(ha.train_loss).all()
    for (name, p), q in zip(a.state_dict().items(), b.state_dict().values()):
        assert torch.equal(p, q), name
    assert ha.n_contact_frames == keep.sum()
    assert float(a.contact_mean_mm) == pytest.approx(c[keep].mean(), rel=1e-5)
    assert float(a.contact_scale_mm) == pytest.approx(c[keep].std(ddof=1), rel=1e-4)


def test_the_contact_head_needs_heights_and_its_weight():
    x, s, f, c = toy_contact(32)
    on = TrainConfig(**{**CFG, "contact_weight": 1.0})
    with pytest.raises(ValueError, match="no training frame has a contact height"):
        train(x, s, f, None, CONTACT_NET, on, log=lambda m: None, contact_mm=np.full(32, np.nan))
    with pytest.raises(ValueError, match="needs the frames' contact heights"):
        train(x, s, f, None, CONTACT_NET, on, log=lambda m: None)
    with pytest.raises(ValueError, match="do not go together"):
        train(x, s, f, None, CONTACT_NET, TrainConfig(**CFG), log=lambda m: None, contact_mm=c)


def test_contact_training_in_bfloat16_autocast():
    """bfloat16 autocast (train.bf16: true, emulated here if need be) trains the contact
    head too: finite losses, a finite validation RMSE."""
    x, s, f, c = toy_contact(48)
    cfg = TrainConfig(**{**CFG, "epochs": 1, "bf16": True, "contact_weight": 1.0})
    _, hist = train(
        x, s, f, toy_contact(16, seed=1), CONTACT_NET, cfg, log=lambda m: None, contact_mm=c
    )
    assert hist.precision == "bfloat16"
    assert np.isfinite(hist.train_contact_mse).all() and np.isfinite(hist.val_contact_rmse_mm).all()


@pytest.mark.slow
def test_contact_checkpoint_torchscript_and_onnx_parity(tmp_path):
    """The contact model through its checkpoint, TorchScript (contact, force_contact,
    forward_contact beside forward and force) and ONNX (contact_mm outputs) gives the
    eager model's heights; the JSON says it has the head and its force threshold."""
    import json

    import onnxruntime as ort

    from finray.train import export_onnx, force_onnx_path

    x, s, f, c = toy_contact(64)
    cfg = TrainConfig(**{**CFG, "contact_weight": 1.0, "contact_min_force_N": 0.3})
    model, hist = train(
        x, s, f, toy_contact(16, seed=1), CONTACT_NET, cfg, log=lambda m: None, contact_mm=c
    )
    training_curves(hist, tmp_path / "curves.png")  # a third panel: the contact RMSE
    save_checkpoint(model, hist, tmp_path / "m.pt")
    back, ck = load_checkpoint(tmp_path / "m.pt")
    assert back.cfg.contact and ck["history"]["contact_mean_mm"] == hist.contact_mean_mm
    export_torchscript(back, tmp_path / "m.ts", contact_min_force_N=0.3)
    export_onnx(back, tmp_path / "m.onnx")
    meta = json.loads((tmp_path / "m.ts.json").read_text())
    assert meta["contact"] is True and meta["contact_min_force_N"] == 0.3
    ts = torch.jit.load(str(tmp_path / "m.ts"))
    xt = torch.as_tensor(x[:8])
    with torch.no_grad():
        s0, f0, c0 = model.forward_contact(xt)
        s1, f1 = ts(xt)
        f2, c2 = ts.force_contact(xt)
        s3, f3, c3 = ts.forward_contact(xt)
        c4 = ts.contact(xt)
    for a, b in ((c0, c2), (c0, c3), (c0, c4), (f0, f1), (f0, f2), (f0, f3), (s0, s1), (s0, s3)):
        assert (a - b).abs().max() < 1e-3
    full = ort.InferenceSession(str(tmp_path / "m.onnx"))
    force = ort.InferenceSession(str(force_onnx_path(tmp_path / "m.onnx")))
    s5, f5, c5 = full.run(["stress_log", "force_N", "contact_mm"], {"image": x[:8]})
    f6, c6 = force.run(["force_N", "contact_mm"], {"image": x[:8]})
    for a, b in ((c0, c5), (c0, c6), (f0, f5), (f0, f6)):
        assert np.abs(a.numpy() - b).max() < 1e-3


def test_relative_force_weights_divide_by_each_scenes_largest_force():
    from finray.train.data import scene_force_weights

    ids = ["a"] * 3 + ["b"] * 3 + ["c"] * 2
    fx = np.array([0.0, 10.0, 40.0, 0.0, -1.0, 2.0, 0.1, 0.2])  # peaks 40, 2 and 0.2 N
    w = scene_force_weights(ids, fx, floor_N=1.0)
    assert w.mean() == pytest.approx(1.0)
    raw = np.array([1 / 40**2] * 3 + [1 / 2**2] * 3 + [1.0] * 2)  # c: floored at 1 N
    np.testing.assert_allclose(w, raw / raw.mean(), rtol=1e-6)


def test_frame_stiffness_is_the_slope_of_the_force_along_each_scenes_travel():
    from finray.train.data import frame_stiffness

    u = np.linspace(0.0, 4.0, 41)
    # two scenes interleaved and shuffled: |fx| = 3 u (a) and 0.5 u^2 (b, pushed in -x)
    ids = np.array(["a"] * 41 + ["b"] * 41 + ["c"])
    uu = np.concatenate([u, u, [1.0]])
    fx = np.concatenate([3.0 * u, -0.5 * u**2, [2.0]])
    order = np.random.default_rng(0).permutation(len(ids))
    k = frame_stiffness(ids[order], uu[order], fx[order])
    back = np.empty_like(k)
    back[order] = k
    np.testing.assert_allclose(back[:41], 3.0)
    np.testing.assert_allclose(back[42:81], u[1:40], rtol=1e-9)  # d(u^2/2)/du = u inside
    assert np.isnan(back[82])  # one frame: no slope


def test_uniform_force_weights_train_as_the_plain_loss():
    x, s, f = toy()
    net = NetConfig(height=32, width=16, base_channels=4)
    plain = train(x, s, f, None, net, TrainConfig(**CFG, bf16=False), log=lambda m: None)[1]
    ones = train(
        x,
        s,
        f,
        None,
        net,
        TrainConfig(**CFG, bf16=False),
        log=lambda m: None,
        force_weight=np.ones(len(x), "f4"),
    )[1]
    np.testing.assert_allclose(ones.train_loss, plain.train_loss, rtol=1e-5)
    with pytest.raises(ValueError, match="force weights"):
        train(x, s, f, None, net, TrainConfig(**CFG), log=lambda m: None, force_weight=np.ones(3))


def test_weight_averaging_keeps_the_moving_average_of_the_trained_weights():
    """A decay near 0 averages over the last step only: the model kept is the trained one;
    a decay near 1 keeps the first step's weights (the average starts there); training
    itself is unchanged."""
    x, s, f = toy()
    val = (x[:16], s[:16], f[:16])
    net = NetConfig(height=32, width=16, base_channels=4)
    cfg = dict(CFG, bf16=False, keep="last")
    runs = {
        d: train(x, s, f, val, net, TrainConfig(**cfg, ema_decay=d), log=lambda m: None)
        for d in (0.0, 1e-12, 0.999999)
    }
    plain, last, slow = (runs[d][0].state_dict() for d in (0.0, 1e-12, 0.999999))
    for k in plain:
        torch.testing.assert_close(last[k], plain[k])
    assert runs[0.999999][1].train_loss == runs[0.0][1].train_loss
    moved = [k for k in plain if k.endswith("weight") and not torch.equal(plain[k], slow[k])]
    assert moved  # the slow average is not the trained weights
    first = train(
        x, s, f, val, net, TrainConfig(**{**cfg, "epochs": 1, "lr": 0.0}), log=lambda m: None
    )[0].state_dict()
    for k in moved:  # ... it is the first step's: within one Adam step (at most lr) of the
        # initial weights (lr 0 keeps them), where training moved them further
        assert (slow[k] - first[k]).abs().max() <= 1.001 * cfg["lr"]
        assert (plain[k] - first[k]).abs().max() > 2 * cfg["lr"]


def test_the_weight_average_is_torchs_moving_average():
    """WeightAverage against torch.optim.swa_utils.AveragedModel with its EMA function,
    over a few random moves of the weights: the same average."""
    from torch.optim.swa_utils import AveragedModel, get_ema_multi_avg_fn

    from finray.model import FinRayNet
    from finray.train.loop import WeightAverage

    torch.manual_seed(0)
    model = FinRayNet(NetConfig(height=32, width=16, base_channels=4))
    ours = WeightAverage(model, 0.9)
    torchs = AveragedModel(model, multi_avg_fn=get_ema_multi_avg_fn(0.9))
    for _ in range(5):
        with torch.no_grad():
            for p in model.parameters():
                p.add_(torch.randn_like(p))
        ours.update()
        torchs.update_parameters(model)
    for mine, theirs, trained in zip(
        ours.module.parameters(), torchs.module.parameters(), model.parameters()
    ):
        torch.testing.assert_close(mine, theirs, rtol=0, atol=0)
        assert not torch.equal(mine, trained)
    assert ours.updates == 5
