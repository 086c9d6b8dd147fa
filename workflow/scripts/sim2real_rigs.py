import json
from pathlib import Path

from finray.sim2real.rigs import write_rigs
from finray.logs import log_to

inp = snakemake.input
with log_to(snakemake.log[0]):
    # the configured rig beside the drawn ones, where the rule has it (not the selection's)
    default = getattr(inp, "default", None)
    summaries = {"default": json.loads(Path(default).read_text())} if default else {}
    summaries |= {Path(p).parent.name: json.loads(Path(p).read_text()) for p in inp.rigs}
    print(
        json.dumps(
            write_rigs(summaries, snakemake.params.rigs, snakemake.output)["by_context"], indent=1
        )
    )
