import json

from finray.logs import log_to
from finray.benchmarks.realtime import latency_report
from finray.render.scene import load_render_index

b = snakemake.params.benchmarks
with log_to(snakemake.log[0]):
    # the frames the render stage wrote as files (render.files_per_scene per view)
    images = [
        f"{idx.rsplit('/', 1)[0]}/{fr['image']}"
        for idx in snakemake.input.renders
        for fr in load_render_index(idx.rsplit("/", 1)[0])["frames"]
        if fr.get("image")
    ]
    out = latency_report(snakemake.input.model, images, b["latency_frames"], b["latency_repeats"])
    print(json.dumps({k: v for k, v in out.items() if k != "by_backend"}, indent=1))
    with open(snakemake.output.json, "w") as f:
        json.dump(out, f, indent=1)
