"""The fabricated FEA ``result.npz`` of the render and dataset tests
(``helpers.write_synthetic_fea_result``, TEST FIXTURE ONLY, never used by the pipeline)
honours the solver's ``result.npz`` contract."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from finray.geometry.mesh import signed_areas
from finray.render import load_fea_result

from helpers import write_synthetic_fea_result


@pytest.fixture(scope="module")
def synthetic_result(tmp_path_factory) -> Path:
    return write_synthetic_fea_result(tmp_path_factory.mktemp("fea") / "result.npz")


def test_fixture_follows_the_result_contract(synthetic_result):
    res = load_fea_result(synthetic_result)
    n, f = len(res.points), res.n_frames
    assert f == 6 and res.triangles.shape[1] == 6
    assert res.u_mm.shape == (f, n, 2) and res.u_mm.dtype == np.float32
    assert res.von_mises_MPa.shape == (f, n) and res.von_mises_MPa.dtype == np.float32
    assert (res.von_mises_MPa > 0).all()
    assert res.object_points_mm.shape[0] == f and res.object_edges.shape[1] == 2
    np.testing.assert_array_equal(res.u_mm[0], 0.0)
    # the analytic field keeps every element (and every linear sub-triangle) upright
    for k in range(f):
        assert (signed_areas(res.deformed_points(k), res.triangles) > 0).all()
    # the bend grows with the frame: the tip moves towards the object
    tip = np.argmax(res.points[:, 1])
    assert np.all(np.diff(res.u_mm[:, tip, 0]) < 0)
