"""The train stage: :class:`~finray.model.FinRayNet` trained on the dataset's shards.

Modules
-------
config    TrainConfig (the loop), AugmentConfig (the augmentation), History (what a run
          measured), the pitch augmentation's input geometry; no torch.
augment   TrainAugment: jitter, camera view, occlusion, pitch, salt and pepper.
loop      train(): Adam on the paper's loss, the learning-rate schedule, batch-norm
          re-estimates, validation, the kept epoch.
data      the shards as network tensors (load_split), the validation scenes.
export    checkpoint, TorchScript and ONNX files.
stage     train_from_shards(): the stage's entry point (shards -> files), its curves.

The names below load their module on first use (PEP 562), so that planning the DAG
(``from finray.train.config import pitch_geometry``) imports no torch.
"""

from __future__ import annotations

from ..lazy import lazy_exports

_HOMES = {
    "config": ("TrainConfig", "History", "AugmentConfig", "pitch_geometry", "SCHEDULES", "KEEP"),
    "augment": ("TrainAugment",),
    "loop": (
        "train",
        "evaluate",
        "lr_factor",
        "recalibrate_batchnorm",
        "seed_everything",
        "_autocast",
    ),
    "data": ("FORCE_COMPONENTS", "load_split", "validation_scenes"),
    "export": (
        "save_checkpoint",
        "load_checkpoint",
        "export_torchscript",
        "export_onnx",
        "force_onnx_path",
    ),
    "stage": ("train_from_shards", "training_curves"),
}
__getattr__, __dir__, __all__ = lazy_exports(__name__, _HOMES, globals())
