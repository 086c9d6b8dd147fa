from finray.benchmarks.network import run_time_vs_error
from finray.logs import log_to

b, t = snakemake.params.benchmarks, snakemake.params.train
with log_to(snakemake.log[0]):
    table = run_time_vs_error(
        snakemake.input.shards,
        snakemake.output.table,
        snakemake.output.figure,
        snakemake.output.summary,
        sizes=b["train_sizes"],
        bases=b["train_base_channels"],
        configured=(*t["input_size"], t["base_channels"]),
        epochs=b["train_epochs"],
        every=b["train_every"],
        tolerance=b["train_tolerance"],
        budget_ms=b["train_budget_ms"],
        lr=b["train_lr"],
        latency_calls=b["latency_frames"],
        val_fraction=t["val_fraction"],
        batch_size=t["batch_size"],
        seed=t["seed"],
        bf16=t["bf16"],
        channels_last=t["channels_last"],
        schedule={k: t[k] for k in ("schedule", "warmup_frac", "bn_frames", "keep", "ema_decay")},
    )
    print(table.to_string())
