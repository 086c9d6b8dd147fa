"""Network inputs of the randomised camera views (the ``camera`` model's training images).

Per frame: one camera of :class:`~finray.render.camera_views.CameraViews` sees the
extruded finger (:meth:`~finray.render.perspective.PerspectiveRaster.image`: depth-tested,
flat-shaded by the headlight as the pyvista render is, over the window the finger spans),
and the input is made as :class:`~finray.predict.Predictor` makes it from a camera frame:
:func:`~finray.dataset.imageops.segment` (the same threshold; the morphology's size
limits in pixels of the camera's whole frame, as on a full frame), the same
base-anchored crop (:func:`~finray.dataset.imageops.base_anchored_box`) and area
resampling to each size. (The threshold's histogram holds the window's background, not
the whole frame's: the background class's mean moves by a fraction of a grey level.)
The stress target stays the front view's map of the frame.
"""

from __future__ import annotations

import numpy as np

from ..geometry.mesh import TriMesh
from ..render.camera_views import VIEW_COLUMNS, CameraViews
from ..render.perspective import PerspectiveRaster
from .imageops import EmptyMaskError, segment
from .window import InputWindow
from .params import DatasetParams, size_key


class CameraViewPreparer:
    """Camera-view inputs of the frames of one scene (one raster, reused per frame).

    ``add(frame, points2d)`` draws the frame's camera and keeps its inputs;
    ``stacked()`` gives ``camera_input_HxW`` (F, H, W) uint8 per size and
    ``camera_view`` (F, len(VIEW_COLUMNS)) float64."""

    def __init__(
        self,
        mesh: TriMesh,
        extrusion_mm: float,
        views: CameraViews,
        params: DatasetParams,
        window: InputWindow,
        scene_id: str,
        look=None,
    ):
        from ..render.params import RenderParams

        self.raster = PerspectiveRaster(mesh, extrusion_mm, views.supersample, corners_only=True)
        self.look = look or RenderParams()  # colours and light
        self.views, self.params, self.scene_id = views, params, scene_id
        self.window = window
        self._inputs: dict[str, list] = {size_key(s): [] for s in params.sizes}
        self._rows: list[np.ndarray] = []

    def mask(self, points2d: np.ndarray, camera) -> np.ndarray:
        """The camera's finger mask over the raster's window (h, w) bool, segmented as
        :func:`~finray.dataset.imageops.segment` segments the whole frame."""
        rgb, _ = self.raster.image(points2d, camera, self.look)
        kw = dict(self.window.segment)
        scale = camera.width * camera.height / (rgb.shape[0] * rgb.shape[1])  # of the whole frame
        kw["min_object_frac"] *= scale
        kw["max_hole_frac"] *= scale
        return segment(rgb, **kw)

    def prepare(self, frame: int, points2d: np.ndarray) -> tuple[dict[str, np.ndarray], np.ndarray]:
        cam, row = self.views.sample(self.scene_id, frame)
        mask = self.mask(points2d, cam)
        try:
            inputs = self.window.inputs(mask, self.params.sizes)
        except EmptyMaskError:
            raise ValueError(
                f"{self.scene_id} frame {frame}: the camera view {dict(zip(VIEW_COLUMNS, row))} "
                "sees no finger"
            ) from None
        return {size_key(s): v for s, v in inputs.items()}, row

    def add(self, frame: int, points2d: np.ndarray) -> None:
        inputs, row = self.prepare(frame, points2d)
        for k, v in inputs.items():
            self._inputs[k].append(v)
        self._rows.append(row)

    def stacked(self) -> dict[str, np.ndarray]:
        out = {f"camera_input_{k}": np.stack(v) for k, v in self._inputs.items()}
        out["camera_view"] = np.stack(self._rows)
        return out
