"""Score camera-model trainings on the held-out shapes over the face: per-height NRMSE,
unseen overall, paper heights (20/30/40), contact RMSE. Usage: score.py <exp_dir>..."""

import sys
import pandas as pd
from finray.evaluate.summary import face_summary
from finray.evaluate.metrics import force_metrics

for d in sys.argv[1:]:
    s = face_summary(d)
    if s is None:
        print(d, "no face heights")
        continue
    for p, rows in s["by_height"].items():
        print(f"== {d} [{p}]")
        print("  h: " + " ".join(f"{r['height_mm']:.0f}:{r['nrmse_pct']:.2f}" for r in rows))
        bad = [r["height_mm"] for r in rows if r["unseen"] and r["nrmse_pct"] > 3]
        u, se = s["unseen"][p], s["seen"][p]
        f = pd.read_csv(f"{d}/frames.csv")
        f = f[(f["path"] == "shard") & (f.iloc[:, 0].astype(str) == "all")]
        paper = f["height_mm"].astype(float).isin([20.0, 30.0, 40.0])
        m = force_metrics(f["fx_N"][paper], f[f"pred_{p}"][paper])
        print(
            f"  unseen NRMSE {u['nrmse_pct']:.2f} % (RMSE {u['rmse_N']:.3f} N, n {u['n']}), "
            f"contact {u.get('contact_rmse_mm', float('nan')):.2f} mm; bands > 3 %: {bad}; "
            f"paper heights {m['nrmse_pct']:.2f} %"
        )
