"""The experiments' metrics tables, read back without running a network: which rows are
an experiment's headline, the variants' keys, the usable pitch range. No torch (the
workflow imports the summary, which reads them, to plan the DAG)."""

from __future__ import annotations

import pandas as pd

#: ``(path, frames)`` of the metrics rows: the shard inputs on every test frame (the
#: headline numbers), the shard inputs on the rendered frames only, the camera
#: path on those frames, and the camera path on all of an experiment's frames where it
#: has no shard path (viewpoint: the headline). The key names the variant in ``metrics.json`` and the summary.
PATH_KEYS = {
    ("shard", "all"): None,
    ("shard", "rendered"): "shard_rendered",
    ("camera", "rendered"): "camera",
    ("camera", "all"): None,
}  # the viewpoint experiment: camera frames only


def headline_rows(metrics: pd.DataFrame) -> pd.DataFrame:
    """The rows on all test frames: the shard path's, or the camera path's where it is the
    experiment's only one (viewpoint); every row of a table from before the camera
    path, which has no ``path`` column."""
    if "path" not in metrics:
        return metrics
    return metrics[metrics["frames"] == "all"]


def usable_range(metrics: pd.DataFrame, predictor: str, threshold_pct: float) -> float | None:
    """Largest pitch (deg) up to which every pitch's force NRMSE is <= the threshold
    (None when even pitch 0 is above it). Conditions are named by their pitch."""
    m = headline_rows(metrics)
    m = m[(m["group"] == "all") & (m["predictor"] == predictor)].copy()
    m["pitch"] = m["condition"].astype(float)
    usable = None
    for _, r in m.sort_values("pitch").iterrows():
        if r["nrmse_pct"] > threshold_pct:
            break
        usable = float(r["pitch"])
    return usable
