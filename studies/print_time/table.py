from finray.logs import log_to
from finray.sim2real.rigs import write_print_time

inp, p = snakemake.input, snakemake.params
with log_to(snakemake.log[0]):
    # the inputs come in the rule's order: variant by variant, each rig in turn
    n = len(p.rigs)
    pairs = {
        (v, r): (inp.dynamic[i * n + j], inp.static[i * n + j])
        for i, v in enumerate(p.variants)
        for j, r in enumerate(p.rigs)
    }
    write_print_time(pairs, snakemake.output)
