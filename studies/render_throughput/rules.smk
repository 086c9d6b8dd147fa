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
    log:
        f"{RESULTS}/logs/studies/render_throughput.log",
    benchmark:
        f"{RESULTS}/benchmarks/studies/render_throughput.tsv"
    conda:
        "../../envs/finray.yaml"
    threads: 1
    resources:
        mem_mb=700,
        runtime=1,
    params:
        render=render_params(),
        dataset=section("dataset", keys=SHARD_KEYS),
        extrusion_mm=config["finger"]["extrusion_mm"],
    script:
        "render_benchmark.py"
