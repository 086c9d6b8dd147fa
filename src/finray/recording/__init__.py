"""Lab recordings: a real rig's takes (video + force log) in, dataset shards out.

- :mod:`~finray.recording.take` -- the recording format and its checks (:class:`TakeError`)
- :mod:`~finray.recording.colour` -- colour segmentation of the finger (HSV / Lab)
- :mod:`~finray.recording.finder` -- the one way to find the finger in camera frames
  (its colour, given or learned, or the renders' grey-level threshold), for ingest,
  predict and the live loop
- :mod:`~finray.recording.sync` -- the sensor clock aligned to the camera's
- :func:`ingest` -- ``finray ingest TAKE --out DIR``

A dataset-level stage: it uses the dataset stage's crop and shard format, never
training, evaluation or prediction.
"""

from .colour import ColourRange, learn_colour, segment_finger
from .finder import FingerFinder, finder_from_spec, learn_finder
from .ingest import IngestParams, ingest
from .sync import align_clocks, force_at_frames
from .take import TAKE_SCHEMA, TakeError, open_frames, read_forces, read_take_json

__all__ = [
    "TAKE_SCHEMA",
    "ColourRange",
    "FingerFinder",
    "IngestParams",
    "TakeError",
    "align_clocks",
    "finder_from_spec",
    "learn_finder",
    "force_at_frames",
    "ingest",
    "learn_colour",
    "open_frames",
    "read_forces",
    "read_take_json",
    "segment_finger",
]
