"""Rebuild ``tests/data/summary_full.json`` (the full config's summary, a test fixture)
from a finished full run, with the summary code of this checkout (read by
tests/workflow/test_manuscript.py, test_workflow.py, tests/evaluate/test_diversity.py
and test_spread.py):

    PYTHONPATH=src python tests/data/make_summary_full.py RESULTS_DIR [--config config/config.yaml]

The same inputs as the workflow's ``summary`` rule (workflow/rules/paper.smk). The FEA
scene table is rebuilt from the scenes' own ``summary.json`` files, so that a run whose
``fea_scenes.csv`` predates a new column still gives every key.
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path

from finray.config import load_config
from finray.evaluate.summary import build_summary, lab_summary
from finray.fea.figures import scene_table

ROOT = Path(__file__).resolve().parents[2]
EXPERIMENTS = ["shape", "material", "occlusion", "pitch", "viewpoint"]  # evaluate.smk's


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", type=Path)
    ap.add_argument("--config", type=Path, default=ROOT / "config" / "config.yaml")
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("summary_full.json"))
    a = ap.parse_args()
    cfg = load_config(a.config)
    r = a.results
    with tempfile.TemporaryDirectory() as tmp:
        scenes = Path(tmp) / "fea_scenes.csv"
        scene_table(sorted(r.glob("fea/*/*/h*/summary.json")), scenes)
        histories = {p.parent.name: p for p in sorted(r.glob("train/*/history.json"))}
        s = build_summary(
            r / "evaluate",
            EXPERIMENTS,
            r / "evaluate" / "baseline" / "fit.json",
            r / "evaluate" / "speed" / "speed.json",
            # the FEA cost study's table where it was built (STUDY_NODES)
            p if (p := r / "benchmarks" / "fea_pareto.csv").exists() else None,
            histories,
            cfg["evaluate"]["usable_nrmse_pct"],
            config=cfg,
            fea_scenes_csv=scenes,
            manifest_csv=r / "dataset" / "manifest.csv",
        )
    # the emulated lab takes, with the set-up the summary rule passes (lab.smk, paper.smk)
    s["lab"] = lab_summary(
        r / "lab" / "qa.json",
        r / "lab" / "qa.csv",
        {k: cfg["lab"][k] for k in ("as_built", "motion", "camera", "sensor")},
    )
    s["sim2real"] = json.loads((r / "evaluate" / "sim2real" / "summary.json").read_text())
    if cfg["lab"]["rigs"]["count"]:  # sim-to-real on the drawn emulated rigs (rigs.smk)
        s["sim2real_rigs"] = json.loads(
            (r / "evaluate" / "sim2real" / "rigs" / "summary.json").read_text()
        )
    a.out.write_text(json.dumps(s, indent=1) + "\n")
    print(f"wrote {a.out} ({a.out.stat().st_size} bytes)")


if __name__ == "__main__":
    main()
