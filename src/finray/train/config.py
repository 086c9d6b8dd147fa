"""Training settings and record: :class:`TrainConfig` (the loop), :class:`AugmentConfig`
(the on-the-fly augmentation), :class:`History` (what a run measured) and the pitch
augmentation's input geometry. Plain dataclasses: no torch (the workflow imports them
to plan the DAG)."""

from __future__ import annotations

from dataclasses import dataclass, field

from ..schema import schema_default


@dataclass
class TrainConfig:
    """The training loop's settings: the config's ``train`` keys (their defaults are the
    schema's) and the caller's run-time knobs, which are no config keys: ``threads`` (the
    job's cores), ``progress`` and ``log_every_s`` (how it reports), ``compare_running_bn``
    (a diagnostic the spread study turns on)."""

    epochs: int = schema_default("train.epochs")
    batch_size: int = schema_default("train.batch_size")
    lr: float = schema_default("train.lr")  # the peak of the cosine (the paper: a constant 1e-4)
    alpha_stress: float = schema_default("train.alpha_stress")
    alpha_force: float = schema_default("train.alpha_force")
    # the contact-height term's weight (0: no contact head, the models before it); its
    # MSE (normalised like the force) over the frames with a contact height whose |fx|
    # is above contact_min_force_N (N)
    contact_weight: float = schema_default("train.contact_weight")
    contact_min_force_N: float = schema_default("train.contact_min_force_N")
    # the force term's frame weights: "absolute" (every frame alike: the error in N) or
    # "relative" (each frame's squared error over its scene's largest |fx|, floored at
    # force_floor_N, squared; weights of mean 1): near the clamped base a scene ends at
    # 40 N, at the tip at 2 N, and an absolute loss spends the network on the first
    force_loss: str = schema_default("train.force_loss")
    force_floor_N: float = schema_default("train.force_floor_N")
    # the training's draws: initial weights, batch order, augmentation
    seed: int = schema_default("train.seed")
    # the validation scenes (part of the data, not of the training's draw: a seed study
    # varies the training on the same data)
    split_seed: int = schema_default("train.split_seed")
    threads: int = 1
    # "auto": bfloat16 autocast where the device runs it natively
    bf16: bool | str = schema_default("train.bf16")
    # "auto" (the GPU when torch sees one), "cpu" or "cuda"
    device: str = schema_default("train.device")
    channels_last: bool = schema_default("train.channels_last")
    progress: bool = True  # a tqdm bar (interactive use); the log gets lines either way
    log_every_s: float = 60.0  # a progress line in the log at most this often (s)
    # "cosine" (warm-up, then cosine to 0) or "constant" (the paper's)
    schedule: str = schema_default("train.schedule")
    # of all steps, linear warm-up of the cosine schedule
    warmup_frac: float = schema_default("train.warmup_frac")
    # augmented training frames per batch-norm re-estimate (0: keep training's)
    bn_frames: int = schema_default("train.bn_frames")
    # the kept epoch: lowest "val_force_rmse" (fx), "val_loss", or "last"
    keep: str = schema_default("train.keep")
    # > 0: validate and keep an exponential moving average of the weights (this decay per
    # step) instead of the trained weights
    ema_decay: float = schema_default("train.ema_decay")
    # also validate with training's running batch-norm averages before each re-estimate
    # (History.val_force_rmse_running_bn_N; a diagnostic: one more validation pass)
    compare_running_bn: bool = False


@dataclass
class History:
    epoch: list = field(default_factory=list)
    train_loss: list = field(default_factory=list)
    train_stress_mse: list = field(default_factory=list)
    train_force_mse: list = field(default_factory=list)
    val_loss: list = field(default_factory=list)
    val_force_rmse_N: list = field(default_factory=list)  # of the first force component (fx)
    val_force_rmse_components_N: list = field(default_factory=list)  # per epoch, every component
    wall_time_s: list = field(default_factory=list)
    epoch_time_s: list = field(default_factory=list)  # training loop + validation (s)
    precision: str = ""  # "bfloat16" or "float32", as resolved from TrainConfig.bf16
    precision_reason: str = ""
    # train.bf16: auto on a CPU with bfloat16 hardware: each type's measured step (CPU
    # ms, median) and the steps timed (finray.train.precision_trial); None: not measured
    precision_trial_ms: dict | None = None
    device: str = ""  # where it trained: "cpu (<CPU>)" or "cuda:0 (<GPU>)"
    step_ms: float = float("nan")  # median training step, wall (batch, augmentation included)
    step_cpu_ms: float = float("nan")  # the same in the thread's CPU time (less load-dependent)
    best_epoch: int = (
        0  # the epoch whose weights are kept (TrainConfig.keep; train loss without validation)
    )
    lr: list = field(default_factory=list)  # the learning rate at the end of each epoch
    val_force_rmse_running_bn_N: list = field(
        default_factory=list
    )  # TrainConfig.compare_running_bn
    force_mean_N: list = field(default_factory=list)  # the force normalisation (training frames)
    force_std_N: list = field(default_factory=list)
    # the contact head's (TrainConfig.contact_weight > 0): the masked normalised MSE per
    # epoch, the validation RMSE (mm) on the masked frames, the normalisation (mm) and the
    # number of training frames in the mask
    train_contact_mse: list = field(default_factory=list)
    val_contact_rmse_mm: list = field(default_factory=list)
    contact_mean_mm: float | None = None
    contact_std_mm: float | None = None
    n_contact_frames: int = 0


@dataclass
class AugmentConfig:
    """On-the-fly training augmentation (kornia + the dataset's disc occlusion)."""

    affine_p: float = 0.5
    degrees: float = 2.0  # rotation jitter (deg)
    translate: float = 0.02  # fraction of the image size
    scale: float = 0.03  # relative
    perspective_p: float = 0.0
    perspective: float = 0.1  # kornia distortion scale
    salt_pepper_p: float = 0.5
    salt_pepper_amount: tuple[float, float] = (0.0, 0.05)  # fraction of pixels
    occlusion_p: float = 0.0  # probability of a random occluding disc
    occlusion_levels: tuple[str, ...] = ("low", "medium", "high")
    pitch_p: float = 0.0  # probability of a camera pitch (finray.dataset.pitch)
    pitch_max_deg: float = 30.0  # pitch drawn uniformly in [0, pitch_max_deg]
    # probability that a sample is its frame's randomised camera view (the shards'
    # camera_input_HxW, finray.dataset.camera_views) instead of the front view; the
    # stress target stays the front view's map either way
    camera_p: float = 0.0
    # geometry of the input for the pitch: set by the training script from the config
    mm_per_px: float = 1.25  # image-plane mm per input pixel
    pitch_centre_row: float = 31.5  # input row of the camera's rotation axis
    extrusion_mm: float = schema_default("finger.extrusion_mm")


def pitch_geometry(dataset: dict, render: dict, height_px: int, extrusion_mm: float) -> dict:
    """Input geometry the pitch augmentation needs, from the config sections
    ``dataset`` (crop) and ``render`` (camera window, whose centre is the pitch axis)."""
    y0, y1 = dataset["crop_y_mm"]
    mm_per_px = (y1 - y0) / height_px
    yc = 0.5 * sum(render["window_y_mm"])
    return {
        "mm_per_px": mm_per_px,
        "pitch_centre_row": (y1 - yc) / mm_per_px - 0.5,
        "extrusion_mm": float(extrusion_mm),
    }


SCHEDULES = ("cosine", "constant")


KEEP = ("val_force_rmse", "val_loss", "last")
FORCE_LOSS = ("absolute", "relative")
