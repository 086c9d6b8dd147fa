import json
from pathlib import Path

import pandas as pd

from finray.sim2real.rig_prior import force_gain, rig_prior
from finray.logs import log_to

p, inp = snakemake.params, snakemake.input
with log_to(snakemake.log[0]):
    gains = {}
    for (variant, obj, height), nom, var in zip(p.runs, inp.nominal, inp.variants):
        gains.setdefault(f"{obj}_h{height}", {})[variant] = force_gain(
            pd.read_csv(nom), pd.read_csv(var)
        )
    prior = rig_prior(gains, dict(p.spec), p.nominal_friction)
    Path(snakemake.output.json).write_text(json.dumps(prior, indent=1))
    print(
        json.dumps({k: prior[k] for k in ("gain_log_mean", "gain_log_sd", "gain_q5", "gain_q95")})
    )
