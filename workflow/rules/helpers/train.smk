# Helpers of the train rules (train.smk): each model's training shards and augmentation; the
# models an experiment compares.
from finray.config import (
    MODEL_TRAINING_KEYS,
    diversity_models,
    generated_training_objects,
    model_augment_settings,
    model_start,
)

# The diversity comparison (generated.compare_model): (paper-objects model, model), or None
# where no generated object trains. The paper-objects model is the job a config without
# the generated objects runs for that model: the same params, the paper objects' shards.
DIVERSITY = diversity_models(config)


GENERATED_TRAIN = frozenset(generated_training_objects(config))


def trained_model(name):
    """The train.models entry a trained model follows (the paper-objects model: its model's)."""
    return DIVERSITY[1] if DIVERSITY and name == DIVERSITY[0] else name


def train_shards(wildcards):
    """A model's training shards (front views of the train split, at its extra heights
    too); the paper-objects model of the diversity comparison gets those of the
    non-generated objects only."""
    exclude = GENERATED_TRAIN if DIVERSITY and wildcards.model == DIVERSITY[0] else ()
    return shard_files(
        splits=["train"], pitch=0.0, exclude_objects=exclude, model=trained_model(wildcards.model)
    )


def model_augment(wildcards):
    return canonical(
        model_augment_settings(config["train"]["models"][trained_model(wildcards.model)])
    )


def model_overrides(name):
    """What a model sets of its own training (finray.config.model_start): its ``epochs``,
    ``ema_decay`` and the model it starts from (``start_from``), only where it sets them,
    so that a model trained from new weights has the train section's params as before."""
    entry = config["train"]["models"][trained_model(name)]
    return {k: entry[k] for k in MODEL_TRAINING_KEYS if k in entry}


def model_train_params(wildcards):
    """The train section (less the models) with the model's own settings."""
    return canonical({**section("train", drop=("models",)), **model_overrides(wildcards.model)})


def model_init(wildcards):
    """The weights a model starts from: the model.pt of its start_from model trained
    beside it (the run's, or the same spread variant's), or nothing."""
    src = model_start(config, trained_model(wildcards.model))["from"]
    return [f"{train_dir(wildcards)}/{src}/model.pt"] if src else []


def model_file(name, train_dir=TRAIN):
    return f"{train_dir}/{name}/model.ts"


def eval_models(*names, train_dir=TRAIN):
    """The models an experiment compares (name -> TorchScript), those of the config only;
    in a variant of the spread or training-budget study, those it retrains."""
    keep = config["train"]["models"] if train_dir == TRAIN else spread_models()
    return {n: model_file(n, train_dir) for n in names if n in keep}
