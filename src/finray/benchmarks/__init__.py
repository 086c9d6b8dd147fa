"""Studies and benchmarks: what the pipeline costs and how accurate it is for the cost
(results/benchmarks/). The studies' homes are ``studies/<name>/`` (rule file, scripts,
README of findings); their computing code is here, where the tests reach it. A top-level consumer like :mod:`finray.evaluate`: it may import
every stage; no stage imports it.

Modules
-------
fea       FEA mesh study (time against error, Pareto front) and the stability suite
network   network study (input size x width against error), training-time table
render    throughput of the render paths and of the per-frame pipeline
speed     FEA against network times, the pipeline's stage times, the studies' times
          and the DAG's wall time (from Snakemake's benchmark files)
budget    the training-budget study's tables and figure (CPU time against error)
fea_sweep the FEA sweep over the whole face
realtime  finray predict on live streams (the real-time study)
pareto    the one Pareto-front helper of the studies
timing    the one timer (wall and CPU time of a block or a callable)
device    one training epoch and the batch-1 latency on the device torch finds
          (``python -m finray.benchmarks.device``)
"""
