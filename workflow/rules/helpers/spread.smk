# Helpers of the spread and training-budget studies (spread.smk): a variant s<seed>_<type>
# retrains every model with that seed and numeric type (train.bf16: auto, fp32 = false,
# bf16 = true); s<seed>_<type>_<point> also with a point of benchmarks.training_budget.points.

SPREAD_TYPES = {"auto": "auto", "fp32": False, "bf16": True}


def train_dir(wildcards):
    """Where an experiment's models come from: the run's (results/train), or a seed
    variant's of the spread study (a ``variant`` wildcard, spread.smk)."""
    variant = getattr(wildcards, "variant", None)
    return f"{SPREAD}/{variant}/train" if variant else TRAIN


def spread_variant(seed, bf16, point=None):
    """The variant name of a seed, a train.bf16 value and a budget point (None: the run's)."""
    kind = {str(v).lower(): k for k, v in SPREAD_TYPES.items()}[str(bf16).lower()]
    return f"s{seed}_{kind}" + (f"_{point}" if point and point != "default" else "")


def spread_models():
    """The models a variant retrains (evaluate.spread.models; empty: every model), sorted."""
    return sorted(config["evaluate"]["spread"]["models"]) or model_names()


def variant_experiments():
    """The experiments a variant runs: those that compare at least one of its models."""
    return [
        e
        for e in EXPERIMENTS
        if experiment_setup(SimpleNamespace(experiment=e, variant="s0_auto"))["models"]
    ]


def manuscript_spread():
    """The spread study's summary where the manuscript quotes it (evaluate.spread.manuscript),
    else nothing: the default run does not wait for the study's trainings."""
    return [f"{SPREAD}/summary.json"] if config["evaluate"]["spread"]["manuscript"] else []


def spread_variants():
    """Every variant of evaluate.spread, seeds within each numeric type."""
    sp = config["evaluate"]["spread"]
    return [f"s{s}_{t}" for t in sp["types"] for s in sp["seeds"]]


def budget_points():
    """The training-budget study's points: "default" (the train section), then the config's."""
    return ["default"] + list(config["benchmarks"]["training_budget"]["points"])


def budget_variants():
    """point -> its variants (one per seed of benchmarks.training_budget, the run's bf16)."""
    seeds = config["benchmarks"]["training_budget"]["seeds"]
    return {
        p: [spread_variant(s, config["train"]["bf16"], p) for s in seeds] for p in budget_points()
    }


def spread_train_params(wildcards):
    """The run's train section with the variant's seed, bf16 and budget point, and the
    model's own settings (its epochs win over the point's)."""
    seed, kind, *point = wildcards.variant[1:].split("_")
    over = config["benchmarks"]["training_budget"]["points"][point[0]] if point else {}
    return canonical(
        {
            **section("train", drop=("models",)),
            **over,
            "seed": int(seed),
            "bf16": SPREAD_TYPES[kind],
            **model_overrides(wildcards.model),
        }
    )
