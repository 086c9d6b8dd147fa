import json
from pathlib import Path

from finray.evaluate.lab_takes import lab_qa, qa_figure
from finray.logs import log_to

inp, out = snakemake.input, snakemake.output
with log_to(snakemake.log[0]):
    per_take, per_frame, summary = lab_qa(
        [Path(t).parent.parent for t in inp.takes],
        [Path(s).parent for s in inp.shards],
        inp.model,
        snakemake.params.size,
        other_models=dict(zip(snakemake.params.others, inp.others)),
    )
    per_take.to_csv(out.takes, index=False, float_format="%.6g")
    per_frame.to_csv(out.frames, index=False, float_format="%.6g")
    Path(out.summary).write_text(json.dumps(summary, indent=1))
    qa_figure(
        out.figure,
        per_take,
        per_frame,
        "Emulated lab takes (not recordings): sensor, true force and the plain model; mask IoU",
    )
    print(per_take.to_string())
