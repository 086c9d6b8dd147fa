"""The rig's head ensemble: fitting, export, the Predictor's members, and `finray
predict --calibration` / `finray calibrate` errors."""

import csv
import json

import numpy as np
import pytest
import torch

from finray.sim2real.adapt import (
    HeadEnsemble,
    HeadFit,
    SimAnchor,
    encoder_features,
    export_ensemble,
    fit_heads,
    head_forces,
)
from finray.cli import main
from finray.model import FinRayNet, NetConfig
from finray.predict import InputError, Predictor
from helpers import PREPROCESS


@pytest.fixture(scope="module")
def net():
    torch.manual_seed(0)
    m = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32, n_forces=2))
    m.set_force_normalisation([3.0, -0.5], [2.0, 0.5])
    m.train()
    with torch.no_grad():
        m(torch.rand(8, 1, 64, 32))  # batch-norm running statistics
    return m.eval()


def test_heads_learn_a_rig_that_differs_from_the_simulation(net):
    """A rig whose force is 1.5 times the simulation's: the fitted heads follow it, and
    the simulation's head is untouched."""
    x = torch.rand(256, 1, 64, 32)
    f = encoder_features(net, x)
    sim = net.force(x)[:, 0].detach().numpy()
    rig = 1.5 * sim + 0.3
    before = [p.clone() for p in net.force_head.parameters()]
    heads = fit_heads(net, f, rig, HeadFit(members=3, steps=300, lr=3e-3))
    pred = head_forces(net, heads, f)
    assert pred.shape == (3, 256)
    err0, err = np.sqrt(np.mean((sim - rig) ** 2)), np.sqrt(np.mean((pred.mean(0) - rig) ** 2))
    assert err < 0.25 * err0
    assert all(torch.equal(a, b) for a, b in zip(before, net.force_head.parameters()))
    assert pred.std(0).mean() > 0  # bootstrap samples: the members differ


@pytest.mark.slow
def test_decayed_heads_spread_by_the_data_not_the_optimiser(net):
    """150 copies of one rest frame whose sensor reads 0.01 N noise: the bootstrap leaves
    their mean open by 0.01 / sqrt(150) = 0.8 mN, and that is the decayed heads' spread
    there; at a constant learning rate the heads scatter several times as far, by where
    their last mini-batches left them (and the fit is no better for it). The whole head
    is fitted (layers 0), where the jitter shows most; fitting the last layers only, the
    decayed spread is the same."""
    g = torch.Generator().manual_seed(1)
    rest = torch.rand(1, 1, 64, 32, generator=g).expand(150, -1, -1, -1)
    x = torch.cat([rest, torch.rand(150, 1, 64, 32, generator=g)])
    f = encoder_features(net, x)
    noise = 0.01 * np.random.default_rng(0).standard_normal(300)
    rig = 1.5 * net.force(x)[:, 0].detach().numpy() + 0.3 + noise
    se = 0.01 / np.sqrt(150)
    out = {}
    for decay, layers in ((False, 0), (True, 0), ("last layers", 3)):
        fit = HeadFit(members=4, steps=300, lr=1e-2, lr_decay=bool(decay), layers=layers)
        P = head_forces(net, fit_heads(net, f, rig, fit), f)
        out[decay] = (P[:, :150].std(0, ddof=1).mean(), np.sqrt(np.mean((P.mean(0) - rig) ** 2)))
    assert 0.5 * se < out[True][0] < 2 * se
    assert 0.5 * se < out["last layers"][0] < 2 * se
    assert out[False][0] > 3 * se
    assert out[True][1] < 1.05 * out[False][1]


def test_sim_anchor_maps_the_simulation_to_the_rig(net):
    """The simulated frames join the context frames with their force mapped by the gain
    and offset that map the no-context heads' reading to the context's sensor: a rig
    reading 1.7 times the heads plus 0.4 N gets ``frames`` simulated forces 1.7 F + 0.4 N."""
    g = torch.Generator().manual_seed(2)
    heads0 = fit_heads(
        net,
        encoder_features(net, torch.rand(32, 1, 64, 32, generator=g)),
        np.linspace(0, 4, 32),
        HeadFit(members=2, steps=5),
    )
    f_sim, sim_N = (
        encoder_features(net, torch.rand(50, 1, 64, 32, generator=g)),
        np.linspace(0, 9, 50),
    )
    f = encoder_features(net, torch.rand(20, 1, 64, 32, generator=g))
    rig = 1.7 * head_forces(net, heads0, f).mean(0) + 0.4
    feats, force = SimAnchor(f_sim, sim_N, tuple(heads0), frames=30).with_context(
        net, f, rig, seed=0
    )
    assert feats.shape == (20 + 30, f.shape[1]) and force.shape == (50,)
    assert torch.equal(feats[:20], f) and np.allclose(force[:20], rig, atol=1e-5)
    rows = [int(np.flatnonzero((f_sim == r).all(1).numpy())[0]) for r in feats[20:]]
    np.testing.assert_allclose(force[20:], 1.7 * sim_N[rows] + 0.4, rtol=1e-4, atol=1e-4)


def test_a_sim_anchor_of_no_frames_changes_nothing(net):
    f = encoder_features(net, torch.rand(24, 1, 64, 32))
    y = np.linspace(0, 3, 24)
    anchor = SimAnchor(f, y, tuple(fit_heads(net, f, y, HeadFit(members=1, steps=2))), frames=0)
    fit = HeadFit(members=2, steps=10)
    np.testing.assert_array_equal(
        head_forces(net, fit_heads(net, f, y, fit), f),
        head_forces(net, fit_heads(net, f, y, fit, anchor=anchor), f),
    )


def test_fit_heads_rejects_bad_labels(net):
    f = encoder_features(net, torch.rand(4, 1, 64, 32))
    with pytest.raises(ValueError, match="NaN"):
        fit_heads(net, f, [1.0, np.nan, 1.0, 1.0], HeadFit(members=1, steps=1))
    with pytest.raises(ValueError, match="as many forces"):
        fit_heads(net, f, [1.0, 2.0], HeadFit(members=1, steps=1))


@pytest.fixture(scope="module")
def ensemble(net, tmp_path_factory):
    x = torch.rand(64, 1, 64, 32)
    heads = fit_heads(
        net, encoder_features(net, x), np.linspace(0, 5, 64), HeadFit(members=3, steps=20)
    )
    d = tmp_path_factory.mktemp("ens")
    export_ensemble(HeadEnsemble(net, heads), d / "rig.model.ts", PREPROCESS, {"takes": ["t"]})
    return net, heads, d


def test_exported_ensemble_in_the_predictor(ensemble):
    """The export's members are the heads' forces, its force their mean, its stress map
    the simulation network's."""
    net, heads, d = ensemble
    p = Predictor(d / "rig.model.ts")
    assert p.ensemble == 3 and p.backend == "torchscript" and p.force_names == ["fx_N"]
    x = np.random.default_rng(0).random((5, 1, 64, 32)).astype(np.float32)
    members = p.run_members(x)
    want = head_forces(net, heads, encoder_features(net, x)).T
    assert np.allclose(members, want, atol=1e-5)
    stress, force = p.run(x)
    assert np.allclose(force[:, 0], members.mean(1), atol=1e-5)
    assert np.allclose(stress, net(torch.from_numpy(x))[0].detach().numpy(), atol=1e-5)
    with pytest.raises(InputError, match="TorchScript only"):
        Predictor(d / "rig.model.ts", backend="onnx")


def test_predict_with_calibration(ensemble, render_png, tmp_path, capsys):
    """`finray predict --calibration` prints each frame's calibrated force and interval
    and writes them to forces.csv; a --model that is not the calibrated one is refused."""
    _, _, d = ensemble
    rng = np.random.default_rng(0)
    samples = np.column_stack(
        [
            rng.normal(2.0, 0.01, 500),
            rng.normal(0.5, 0.01, 500),
            np.full(500, np.log(0.1)),
            np.full(500, np.log(0.01)),
            np.full(500, np.log(0.01)),  # kappa 0.01: the spread hardly counts
            np.full(500, np.log(200.0)),
        ]
    )  # nu 200: nearly normal
    cal = d / "calibration.json"
    cal.write_text(
        json.dumps(
            {
                "model": "rig.model.ts",
                "level": 0.9,
                "posterior": {"names": [], "samples": samples.tolist()},
            }
        )
    )
    rc = main(
        [
            "predict",
            "--calibration",
            str(cal),
            str(render_png),
            "--out",
            str(tmp_path / "p"),
            "--force-only",
        ]
    )
    assert rc == 0
    line = capsys.readouterr().out.strip().splitlines()[-1]
    assert "calibrated" in line and "90 %" in line
    row = next(csv.DictReader(open(tmp_path / "p" / "forces.csv")))
    fx, f, lo, hi = (float(row[k]) for k in ("fx_N", "force_N", "lo_N", "hi_N"))
    assert f == pytest.approx(2.0 * fx + 0.5, abs=0.05)  # the posterior's gain and offset
    sd = np.hypot(0.1, 0.01 * f)  # sigma and rho g mu; 500 draws: quantiles within ~20 %
    assert lo < f < hi and hi - lo == pytest.approx(2 * 1.645 * sd, rel=0.2)
    rc = main(
        [
            "predict",
            "--calibration",
            str(cal),
            "--model",
            str(tmp_path / "other.ts"),
            str(render_png),
            "--out",
            str(tmp_path / "q"),
        ]
    )
    assert rc == 2 and "is not the model" in capsys.readouterr().err


def test_calibrate_errors_are_one_line(tmp_path, capsys):
    rc = main(
        [
            "calibrate",
            str(tmp_path),
            "--model",
            str(tmp_path / "model.pt"),
            "--out",
            str(tmp_path / "c.json"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "model.pt" in err


def test_fit_heads_fits_the_last_layers_only(net):
    """layers=3: the head's first two linear layers (and its batch-norm statistics) are
    the simulation's, bit for bit; the last three are fitted; layers=0 fits all."""
    x = torch.rand(64, 1, 64, 32, generator=torch.Generator().manual_seed(2))
    f, y = encoder_features(net, x), np.linspace(0, 5, 64)
    sim = [m for m in net.force_head if isinstance(m, torch.nn.Linear)]
    for layers, kept in ((3, 2), (0, 0)):
        head = fit_heads(net, f, y, HeadFit(members=1, steps=30, layers=layers))[0]
        lin = [m for m in head if isinstance(m, torch.nn.Linear)]
        assert len(lin) == len(sim) and not any(p.requires_grad for p in head.parameters())
        for i, (a, b) in enumerate(zip(lin[:-1], sim[:-1])):
            assert torch.equal(a.weight, b.weight) == (i < kept)
        bn = [m for m in head if isinstance(m, torch.nn.BatchNorm1d)]
        assert all(
            torch.equal(a.running_mean, b.running_mean)
            for a, b in zip(bn, [m for m in net.force_head if isinstance(m, torch.nn.BatchNorm1d)])
        )


def test_calibrate_checks_every_take_before_ingesting_any(net, tmp_path, capsys):
    """A good take, then one without forces.csv: refused in one line before the good one
    is ingested (ingesting takes ~25 s each: a bad last take used to cost them all)."""
    from finray.train import History, export_torchscript, save_checkpoint
    from recording_synth import write_take

    save_checkpoint(net, History(), tmp_path / "model.pt")
    export_torchscript(net, tmp_path / "model.ts", PREPROCESS)
    write_take(
        tmp_path / "good", size=(320, 240), duration_s=1.0, starts=(0.2,), ramp=0.3, hold=0.1
    )
    write_take(tmp_path / "bad", size=(320, 240), duration_s=1.0, starts=(0.2,), ramp=0.3, hold=0.1)
    (tmp_path / "bad" / "forces.csv").unlink()
    rc = main(
        [
            "calibrate",
            str(tmp_path / "good"),
            str(tmp_path / "bad"),
            "--model",
            str(tmp_path / "model.pt"),
            "--out",
            str(tmp_path / "c.json"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "forces.csv" in err, err
    assert not (tmp_path / "c.ingest").exists() and not (tmp_path / "c.json").exists()


def test_epochs_give_the_same_passes_over_any_number_of_frames():
    """With epochs, a head's steps follow its frames (two context objects get twice one's
    steps); without, they are fixed."""
    fit = HeadFit(epochs=60, batch=64)
    assert fit.n_steps(900) == 844 and fit.n_steps(1800) == 1688
    assert fit.n_steps(1) == 1
    assert HeadFit(steps=400).n_steps(1800) == 400


def test_heads_come_back_from_their_weights(net, tmp_path):
    """A fitted head saved as its state dict (as the no-context fit's file holds it) and
    rebuilt on the model gives the same forces, bit for bit."""
    from finray.sim2real.adapt import head_from_state

    x = torch.rand(32, 1, 64, 32, generator=torch.Generator().manual_seed(3))
    f = encoder_features(net, x)
    heads = fit_heads(net, f, np.linspace(0, 4, 32), HeadFit(members=2, steps=20))
    torch.save([h.state_dict() for h in heads], tmp_path / "heads.pt")
    again = [head_from_state(net, s) for s in torch.load(tmp_path / "heads.pt", weights_only=True)]
    np.testing.assert_array_equal(head_forces(net, again, f), head_forces(net, heads, f))
    assert not any(p.requires_grad for h in again for p in h.parameters())


def _one_head_at_a_time(model, features, force_N, fit):
    """fit_heads as a loop over the members, each its own Adam (the reference)."""
    import copy

    from torch import nn

    from finray.sim2real.adapt import _single_output

    target = (
        torch.tensor(force_N, dtype=torch.float32) - model.force_mean_N[0]
    ) / model.force_scale_N[0]
    template = _single_output(model.force_head, 0).eval()
    linear = [i for i, mod in enumerate(template) if isinstance(mod, nn.Linear)]
    start = linear[-fit.layers] if 0 < fit.layers < len(linear) else 0
    with torch.no_grad():
        z = template[:start](features) if start else features.clone()
    n, steps, heads = len(target), fit.n_steps(len(target)), []
    for m in range(fit.members):
        gen = torch.Generator().manual_seed(fit.seed * 1000 + m)
        tail = copy.deepcopy(template[start:])
        opt = torch.optim.Adam(tail.parameters(), lr=fit.lr)
        decay = torch.optim.lr_scheduler.CosineAnnealingLR(opt, steps)
        pool = torch.randint(0, n, (n,), generator=gen)
        for _ in range(steps):
            idx = pool[torch.randint(0, n, (min(fit.batch, n),), generator=gen)]
            loss = ((tail(z[idx])[:, 0] - target[idx]) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            decay.step()
        heads.append(nn.Sequential(*template[:start], *tail).requires_grad_(False))
    return heads


@pytest.mark.parametrize("layers", [3, 0])
def test_members_fitted_together_as_one_at_a_time(net, layers):
    """The members are fitted in one batched loop: each gets the frames, the gradient and
    the Adam steps it would get alone (last layers, or every layer with the batch norms'
    affine), to float rounding."""
    torch.manual_seed(1)  # the frames, whatever ran before (a quick run leaves tests out)
    x = torch.rand(96, 1, 64, 32)
    f = encoder_features(net, x)
    rig = 1.5 * net.force(x)[:, 0].detach().numpy() + 0.3
    fit = HeadFit(members=3, steps=120, batch=32, lr=3e-3, seed=2, layers=layers)
    together = head_forces(net, fit_heads(net, f, rig, fit), f)
    alone = head_forces(net, _one_head_at_a_time(net, f, rig, fit), f)
    assert np.abs(together - alone).max() < 1e-4 * np.abs(rig).max()
    assert np.abs(together[0] - together[1]).max() > 1e-3  # the members differ


def test_calibrate_refuses_a_missing_no_context_file(net, tmp_path, capsys):
    from recording_synth import write_take

    write_take(tmp_path / "t", size=(320, 240), duration_s=1.0, starts=(0.2,), ramp=0.3, hold=0.1)
    rc = main(
        [
            "calibrate",
            str(tmp_path / "t"),
            "--model",
            str(tmp_path / "model.pt"),
            "--no-context",
            str(tmp_path / "none.pt"),
            "--out",
            str(tmp_path / "c.json"),
        ]
    )
    err = capsys.readouterr().err.strip()
    assert rc == 2 and len(err.splitlines()) == 1 and "--no-context" in err, err
    assert not (tmp_path / "c.ingest").exists() and not (tmp_path / "c.json").exists()


def test_the_no_context_file_keeps_the_simulated_frames(net, tmp_path):
    """save_no_context keeps the simulated frames' features (float16) and forces, and
    SimAnchor.from_file gives them back with the heads; a file written without them, or of
    another encoder, is refused in one line."""
    from finray.errors import CalibrationError
    from finray.sim2real.experiment import save_no_context

    f = encoder_features(net, torch.rand(16, 1, 64, 32, generator=torch.Generator().manual_seed(4)))
    y = np.linspace(0, 2, 16)
    heads = fit_heads(net, f, y, HeadFit(members=2, steps=5))
    result = {
        "heads": [h.state_dict() for h in heads],
        "calibration": {},
        "simulated_test": {},
        "anchor": {"features": f.half(), "force_N": torch.tensor(y, dtype=torch.float32)},
    }
    save_no_context(result, tmp_path / "nc.pt")
    anchor = SimAnchor.from_file(net, tmp_path / "nc.pt", 40)
    assert anchor.frames == 40 and SimAnchor.from_file(net, tmp_path / "nc.pt", 0) is None
    np.testing.assert_allclose(anchor.features.numpy(), f.numpy(), rtol=1e-3, atol=1e-3)
    np.testing.assert_allclose(anchor.force_N, y, rtol=1e-6)
    np.testing.assert_array_equal(
        head_forces(net, list(anchor.heads), f), head_forces(net, heads, f)
    )
    torch.save({"heads": result["heads"], "info": "{}"}, tmp_path / "old.pt")
    with pytest.raises(CalibrationError, match="no simulated frames"):
        SimAnchor.from_file(net, tmp_path / "old.pt", 40)
    result["anchor"]["features"] = torch.zeros(16, 3).half()
    save_no_context(result, tmp_path / "other.pt")
    with pytest.raises(CalibrationError, match="not of this model's encoder"):
        SimAnchor.from_file(net, tmp_path / "other.pt", 40)
