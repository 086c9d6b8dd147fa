from pathlib import Path

from finray.dataset import DatasetParams
from finray.logs import log_to
from finray.recording import IngestParams, TakeError, ingest

p = snakemake.params
d = DatasetParams.from_config(p.dataset)
params = IngestParams(sizes=d.sizes, window=d.window(p.base_width_mm), write_masks=True)
failed = None
with log_to(snakemake.log[0]):
    try:
        ingest(
            Path(snakemake.input.take).parent,
            Path(snakemake.output.shard).parent,
            params,
            log=lambda m: print(m, flush=True),
        )
    except TakeError as e:
        failed = f"finray ingest: {e}"
        print(failed)
if failed:
    raise SystemExit(failed)  # one line, no traceback
