from pathlib import Path

from finray.emulator.emulate import emulate_take
from finray.logs import log_to
from finray.viscoelastic import PrintLaw

wc, p = snakemake.wildcards, snakemake.params
with log_to(snakemake.log[0]):
    emulate_take(
        snakemake.input.result,
        Path(snakemake.output.take).parent,
        p.lab,
        object_name=wc.object,
        height_mm=float(wc.height),
        extrusion_mm=p.extrusion_mm,
        seed=p.seed,
        print_law=PrintLaw.from_config(p.print_law),
        log=lambda m: print(m, flush=True),
    )
