# The render-throughput study (studies/render_throughput/README.md): the 2D rasteriser
# against pyvista's 3D renderer on one scene, frames per second each.
#   snakemake --cores 2 render_throughput


localrules:
    render_throughput,


rule render_throughput:
    input:
        study_files("render_throughput"),


rule render_benchmark:
    input:
        result=render_benchmark_input,
    output:
        json=f"{RESULTS}/benchmarks/render_throughput.json",
    params:
        render=render_params(),
        dataset=section("dataset", keys=SHARD_KEYS),
        extrusion_mm=config["finger"]["extrusion_mm"],
    log:
        f"{RESULTS}/logs/render/benchmark.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/render_throughput.tsv"
    threads: 1
    resources:
        mem_mb=700,
        runtime=1,
    conda:
        "../../envs/finray.yaml"
    script:
        "render_benchmark.py"
