"""Fixtures shared by several test modules (pytest finds them here; no module imports
another's fixture or helper: shared plain functions and constants are in helpers.py).
The tests mirror the package's stages, one folder each (geometry, fea, render, dataset,
train, predict, evaluate, emulator, recording, sim2real, benchmarks, workflow). Markers
(pyproject.toml): ``slow`` (the integration tests: the smoke workflow, provenance, the FEA
scenes, the runner, the CLI, tutorials run by Snakemake) and ``workflow`` (those that run
Snakemake); ``pytest -m "not slow"`` is the quick run, CI (.ci/run) runs everything."""

import pytest
import torch

from finray.dataset import DatasetParams, render_shard
from finray.model import FinRayNet, NetConfig
from finray.render import RenderParams, load_render_index, render_scene
from finray.train import export_torchscript

from helpers import PREPROCESS, write_synthetic_fea_result


@pytest.fixture(scope="module")
def render_png(tmp_path_factory):
    """A camera frame of the fabricated scene (helpers.write_synthetic_fea_result), front view."""
    tmp = tmp_path_factory.mktemp("render")
    res = write_synthetic_fea_result(tmp / "result.npz", n_frames=4)
    render_scene(
        res,
        tmp / "p0",
        0.0,
        params=RenderParams(frames_per_scene=3),
        scene={"object": "ellipse_16x9", "material": "steel", "height_mm": 30.0, "split": "shape"},
    )
    frames = load_render_index(tmp / "p0")["frames"]
    return tmp / "p0" / frames[-1]["image"]


@pytest.fixture(scope="module")
def scene(tmp_path_factory):
    """Two views of the fabricated scene at 20 and 30 mm (5 frames, 3 written as files
    each), their shards at ``size`` (64 x 32) and an untrained exported network."""
    size = (64, 32)
    tmp = tmp_path_factory.mktemp("camera")
    res = write_synthetic_fea_result(tmp / "result.npz", n_frames=5)
    rp = RenderParams(frames_per_scene=5, files_per_scene=3)
    params = DatasetParams(sizes=(size,))
    indices, shards = [], []
    for h in (20.0, 30.0):
        d = tmp / f"h{h:g}" / "p0"
        meta = render_shard(
            res,
            d,
            tmp / f"h{h:g}.npz",
            0.0,
            render_params=rp,
            params=params,
            scene={"object": "ellipse_16x9", "material": "steel", "height_mm": h, "split": "shape"},
        )
        assert meta["n_frames"] == 5
        indices.append(d / "index.json")
        shards.append(tmp / f"h{h:g}.npz")
    torch.manual_seed(0)
    net = FinRayNet(
        NetConfig(in_channels=1, base_channels=4, height=size[0], width=size[1], n_forces=2)
    )
    net.set_force_normalisation([3.0, -0.5], [2.0, 0.4])
    net.eval()
    export_torchscript(net, tmp / "model.ts", PREPROCESS, ["fx_N", "fy_N"])
    return {
        "tmp": tmp,
        "indices": indices,
        "shards": shards,
        "model": tmp / "model.ts",
        "size": size,
    }


@pytest.fixture(scope="module")
def small_model(tmp_path_factory):
    """A tiny untrained network (64 x 32 input) exported to model.ts (+ .json): the path."""
    torch.manual_seed(0)
    net = FinRayNet(NetConfig(in_channels=1, base_channels=4, height=64, width=32)).eval()
    d = tmp_path_factory.mktemp("model")
    export_torchscript(net, d / "model.ts", PREPROCESS)
    return d / "model.ts"


#: The longest test files (the smoke DAG and its studies, the provenance of every config
#: key), handed to the xdist workers first (--dist loadfile sends files in collection
#: order), so that the short files fill the other worker around them instead of one long
#: file running alone at the end.
FIRST = ("tests/workflow/test_workflow.py", "tests/workflow/test_provenance.py")


def pytest_collection_modifyitems(items):
    def rank(item):
        path = item.nodeid.split("::")[0]
        return FIRST.index(path) if path in FIRST else len(FIRST)

    items.sort(key=rank)  # stable: the order within and among the other files is kept
