from pathlib import Path

from finray.geometry.build import build_finger
from finray.logs import log_to

with log_to(snakemake.log[0]):
    summary = build_finger(
        {"finger": snakemake.params.finger, "mesh": snakemake.params.mesh},
        Path(snakemake.output.npz).parent,
    )
    print(summary["quality"])
