from pathlib import Path

from finray.dataset.window import InputWindow
from finray.logs import log_to
from finray.model import NetConfig
from finray.train import AugmentConfig, TrainConfig, pitch_geometry, train_from_shards

t, p = snakemake.params.train, snakemake.params
with log_to(snakemake.log[0]):
    h, w = t["input_size"]
    net = NetConfig(
        in_channels=1, base_channels=t["base_channels"], height=h, width=w, init=t["init"]
    )
    cfg = TrainConfig(
        epochs=t["epochs"],
        batch_size=t["batch_size"],
        lr=t["lr"],
        alpha_stress=t["alpha_stress"],
        alpha_force=t["alpha_force"],
        contact_weight=t["contact_weight"],
        contact_min_force_N=t["contact_min_force_N"],
        force_loss=t["force_loss"],
        force_floor_N=t["force_floor_N"],
        seed=t["seed"],
        split_seed=t["split_seed"],
        threads=snakemake.threads,
        bf16=t["bf16"],
        device=t["device"],
        channels_last=t["channels_last"],
        progress=False,
        schedule=t["schedule"],
        warmup_frac=t["warmup_frac"],
        bn_frames=t["bn_frames"],
        keep=t["keep"],
        ema_decay=t["ema_decay"],
        compare_running_bn=p.get("diagnostics", False),
    )
    d = p.dataset
    aug = AugmentConfig(**p.augment, **pitch_geometry(d, p.render, h, p.finger["extrusion_mm"]))
    occ = {k: tuple(v) for k, v in d["occlusion_levels"].items()}
    preprocess = InputWindow.from_sections(p.finger, d).to_json()
    train_from_shards(
        snakemake.input.shards,
        Path(snakemake.output.model).parent,
        net,
        cfg,
        aug,
        t["val_fraction"],
        occ,
        preprocess,
        forces=tuple(t["forces"]),
        frame_every=t["frame_every"],
        # train.models.<model>.start_from: that model's model.pt
        init=snakemake.input.init[0] if snakemake.input.init else None,
    )
