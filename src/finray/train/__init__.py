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

import importlib

_HOMES = {
    "config": ("TrainConfig", "History", "AugmentConfig", "pitch_geometry", "SCHEDULES", "KEEP"),
    "augment": ("TrainAugment",),
    "loop": ("train", "evaluate", "lr_factor", "recalibrate_batchnorm", "seed_everything",
             "_autocast"),
    "data": ("FORCE_COMPONENTS", "load_split", "validation_scenes"),
    "export": ("save_checkpoint", "load_checkpoint", "export_torchscript", "export_onnx",
               "force_onnx_path"),
    "stage": ("train_from_shards", "training_curves"),
}
_WHERE = {name: module for module, names in _HOMES.items() for name in names}
__all__ = sorted(n for n in _WHERE if not n.startswith("_"))


def __getattr__(name: str):
    if name not in _WHERE:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    return getattr(importlib.import_module(f".{_WHERE[name]}", __name__), name)


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
