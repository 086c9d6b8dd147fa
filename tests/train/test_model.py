"""Architecture of the network: shapes, skip connections, force units, export parity."""

import pytest
import torch

from finray.model import FinRayNet, NetConfig, count_parameters


@pytest.mark.parametrize("h,w,base", [(64, 32, 16), (128, 64, 8)])
def test_output_shapes(h, w, base):
    net = FinRayNet(NetConfig(height=h, width=w, base_channels=base)).eval()
    x = torch.rand(2, 3, h, w)
    stress, force = net(x)
    assert stress.shape == (2, 1, h, w)
    assert force.shape == (2, 1)
    latent, skips = net.encode(x)
    assert latent.shape == (2, 8 * base, h // 16, w // 16)
    assert [s.shape[1] for s in skips] == [base, 2 * base, 4 * base, 8 * base]
    print(f"parameters ({h}x{w}, base {base}): {count_parameters(net)}")


def test_skip_connections_carry_fine_detail():
    """The stress map depends on the full-resolution encoder features (skip 1):
    perturbing one input pixel changes the output at that pixel even when the
    latent is held fixed."""
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(height=64, width=32, base_channels=8)).eval()
    x = torch.rand(1, 3, 64, 32)
    h, skips = net.encode(x)
    x2 = x.clone()
    x2[0, :, 40, 20] += 1.0
    _, skips2 = net.encode(x2)
    y1 = h
    y2 = h  # same latent: only the skips differ
    for step, s1, s2 in zip(net.up, reversed(skips), reversed(skips2)):
        y1, y2 = step(y1, s1), step(y2, s2)
    assert (net.stress_out(y1) - net.stress_out(y2)).abs()[0, 0, 38:43, 18:23].max() > 0
    # every decoder step concatenates a skip of the matching resolution
    for step, skip in zip(net.up, reversed(skips)):
        assert step.conv[0].in_channels == step.reduce[1].out_channels + skip.shape[1]


def test_force_head_layers():
    net = FinRayNet(NetConfig())
    linear = [m for m in net.force_head if isinstance(m, torch.nn.Linear)]
    assert [m.out_features for m in linear] == [128, 64, 32, 8, 1]
    kinds = [type(m).__name__ for m in net.force_head]
    assert kinds[1:5] == ["Linear", "Sigmoid", "BatchNorm1d", "Linear"]
    assert kinds.count("BatchNorm1d") == 2


def test_force_in_newtons():
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(base_channels=4)).eval()
    x = torch.rand(3, 3, 64, 32)
    _, f_norm = net.forward_normalised(x)
    net.set_force_normalisation([2.5], [4.0])
    _, f = net(x)
    torch.testing.assert_close(f, f_norm * 4.0 + 2.5)
    torch.testing.assert_close(net.normalise_force(f), f_norm)


def test_bad_input_size():
    with pytest.raises(ValueError, match="divisible by 16"):
        NetConfig(height=60, width=30)


def test_force_path_skips_only_the_decoder():
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(base_channels=4)).eval()
    net.set_force_normalisation([1.5], [3.0])
    x = torch.rand(4, 3, 64, 32)
    with torch.no_grad():
        torch.testing.assert_close(net.force(x), net(x)[1])


def test_he_init_keeps_the_scale_and_bfloat16_gradients_follow_float32():
    """With He-normal convolutions the latent keeps the input's scale, and the force
    head's first batch-norm sees inputs that bfloat16 resolves: one batch's gradients in
    bfloat16 autocast point where float32's do. PyTorch's default init shrank the latent
    ~10^4-fold and left the force head's bfloat16 gradients uncorrelated with float32's."""
    import torch

    from finray.model import FinRayNet, NetConfig

    torch.manual_seed(0)
    x = (torch.rand(16, 1, 64, 32) > 0.5).float()
    s_t, f_t = torch.randn(16, 1, 64, 32), torch.randn(16, 2)

    def grads(init, bf16):
        torch.manual_seed(1)
        m = FinRayNet(NetConfig(in_channels=1, n_forces=2, init=init)).train()
        with torch.autocast("cpu", dtype=torch.bfloat16, enabled=bf16):
            s, f = m.forward_normalised(x)
        (((s.float() - s_t) ** 2).mean() + 10 * ((f.float() - f_t) ** 2).mean()).backward()
        return m, {n: p.grad.flatten() for n, p in m.named_parameters() if n.endswith("weight")}

    def cosine(a, b):
        return float(a @ b / (a.norm() * b.norm()))

    step = 2.0**-8  # bfloat16's resolution at 0.5, where the sigmoid starts
    for init, lo, hi in (("he", step, 1.0), ("torch", 0.0, step)):
        m, _ = grads(init, False)
        with torch.no_grad():  # the first batch-norm's input: its spread over the batch
            spread = float(m.force_head[:3](m.encode(x)[0]).std(0).mean())
        assert lo < spread < hi, (init, spread)
    _, g16 = grads("he", True)
    _, g32 = grads("he", False)
    # the least over every layer: 0.86 on a Zen 4 (AVX-512 BF16), 0.78 on an Intel Xeon
    # whose bfloat16 kernels run on AMX, 0.77-0.84 with seeds 2 and 3 on either: rounding
    # differs between kernels, while PyTorch's init stays below 0.05 in the force head
    assert min(cosine(g16[n], g32[n]) for n in g32) > 0.7
    _, g16 = grads("torch", True)
    _, g32 = grads("torch", False)
    assert cosine(g16["force_head.4.weight"], g32["force_head.4.weight"]) < 0.5
    with pytest.raises(ValueError, match="init"):
        NetConfig(init="xavier")


def test_contact_head_is_a_head_of_its_own_in_mm():
    """The contact head reads the latent beside the force head (which keeps its layers,
    what finray.sim2real.adapt re-fits), its height comes in mm through its own normalisation, and
    the paths agree: contact, force_contact (no decoder) and forward_contact. Drawn
    after the other layers, it leaves their initial weights those of a model without it."""
    torch.manual_seed(0)
    plain = FinRayNet(NetConfig(base_channels=4))
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(base_channels=4, contact=True)).eval()
    both = net.state_dict()
    for name, a in plain.state_dict().items():
        assert torch.equal(a, both[name]), name
    assert [m.out_features for m in net.force_head if isinstance(m, torch.nn.Linear)][-1] == 1
    net.set_force_normalisation([1.5], [3.0])
    x = torch.rand(4, 3, 64, 32)
    with torch.no_grad():
        _, _, c_norm = net.forward_normalised_all(x)
        net.set_contact_normalisation(35.0, 12.0)
        c = net.contact(x)
        f2, c2 = net.force_contact(x)
        s3, f3, c3 = net.forward_contact(x)
        s, f = net(x)
    assert c.shape == (4,)
    torch.testing.assert_close(c, c_norm * 12.0 + 35.0)
    torch.testing.assert_close(net.normalise_contact(c), c_norm)
    for a, b in ((c2, c), (c3, c), (f2, f), (f3, f), (s3, s)):
        torch.testing.assert_close(a, b)


def test_a_model_without_the_contact_head_loads_and_predicts_force(tmp_path):
    """A checkpoint written before the contact head (no ``contact`` in its net_config, no
    contact buffers) loads as a model without it; its force is as before, and asking it
    for a contact height says why not."""
    from finray.train import load_checkpoint

    torch.manual_seed(0)
    old = FinRayNet(NetConfig(in_channels=1, base_channels=4)).eval()
    cfg = old.config_dict()
    del cfg["contact"]
    torch.save(
        {"net_config": cfg, "state_dict": old.state_dict(), "history": {}, "extra": {}},
        tmp_path / "old.pt",
    )
    model, _ = load_checkpoint(tmp_path / "old.pt")
    assert not model.cfg.contact and not hasattr(model, "contact_head")
    x = torch.rand(2, 1, 64, 32)
    with torch.no_grad():
        torch.testing.assert_close(model.force(x), old.force(x))
        assert model.forward_normalised_all(x)[2] is None
        with pytest.raises(RuntimeError, match="no contact head"):
            model.contact(x)
