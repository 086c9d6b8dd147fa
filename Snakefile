# finray: one command rebuilds the study (see README.md). Stages live in workflow/rules.
from snakemake.utils import min_version

min_version("9.0")


# The config is config/config.yaml unless --configfile names another one, which then
# replaces it (no merge: config/smoke.yaml is a whole, tiny config). See common.smk.

report: "workflow/report/workflow.rst"


include: "workflow/rules/common.smk"
# each stage's helpers (functions only), before any rule reads them
include: "workflow/rules/helpers/geometry.smk"
include: "workflow/rules/helpers/fea.smk"
include: "workflow/rules/helpers/render.smk"
include: "workflow/rules/helpers/train.smk"
include: "workflow/rules/helpers/evaluate.smk"
include: "workflow/rules/helpers/spread.smk"
include: "workflow/rules/helpers/lab.smk"
include: "workflow/rules/helpers/targets.smk"
include: "workflow/rules/helpers/runner.smk"
include: "workflow/rules/geometry.smk"
include: "workflow/rules/fea.smk"
include: "workflow/rules/fea_benchmarks.smk"
include: "workflow/rules/render.smk"
include: "workflow/rules/dataset.smk"
include: "workflow/rules/train.smk"
include: "workflow/rules/evaluate.smk"
include: "workflow/rules/paper.smk"
include: "workflow/rules/train_benchmarks.smk"
include: "workflow/rules/lab.smk"
include: "workflow/rules/rigs.smk"
include: "workflow/rules/rig_prior.smk"
include: "workflow/rules/spread.smk"


onstart:
    # Snakemake's default job-rate limit makes its scheduler spin, and its benchmark files
    # read a long job's CPU time up to 30 s low (helpers/runner.smk)
    drop_default_rate_limit(workflow)
    sample_benchmarks_every(0.5)


rule all:
    input:
        all_targets(),
    default_target: True
