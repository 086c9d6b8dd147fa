"""Image files of the render stage: RGB PNG (8 bit) and float32 OpenEXR (lossless)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

#: Channels of the stress EXR: the transformed stress (premultiplied by coverage)
#: and the finger's coverage of each pixel.
EXR_CHANNELS = ("stress", "coverage")


def write_png(path: str | Path, rgb: np.ndarray) -> None:
    """Write an (H, W, 3) uint8 image as an 8-bit RGB PNG."""
    from PIL import Image

    rgb = np.asarray(rgb)
    if rgb.dtype != np.uint8 or rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"expected an (H, W, 3) uint8 image, got {rgb.shape} {rgb.dtype}")
    Image.fromarray(np.ascontiguousarray(rgb), mode="RGB").save(
        path, optimize=False, compress_level=6
    )


def read_png(path: str | Path) -> np.ndarray:
    """Read a PNG as (H, W, 3) uint8 (grey or RGBA files are converted to RGB)."""
    from PIL import Image

    with Image.open(path) as im:
        return np.asarray(im.convert("RGB"))


def write_exr(path: str | Path, channels: dict[str, np.ndarray], meta: dict | None = None) -> None:
    """Write float32 (H, W) channels to a single-part scanline OpenEXR file with
    lossless ZIP compression; ``meta`` is stored as a JSON string attribute
    ``finray`` in the header."""
    import OpenEXR

    chans = {}
    shape = None
    for name, arr in channels.items():
        a = np.ascontiguousarray(arr, dtype=np.float32)
        if a.ndim != 2:
            raise ValueError(f"channel {name!r} must be 2D, got {a.shape}")
        if shape is not None and a.shape != shape:
            raise ValueError("all channels need the same shape")
        shape = a.shape
        chans[name] = a
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    if meta is not None:
        header["finray"] = json.dumps(meta, sort_keys=True)
    with OpenEXR.File(header, chans, num_threads=0) as f:  # 0: no worker threads
        f.write(str(path))


def read_exr(path: str | Path) -> tuple[dict[str, np.ndarray], dict]:
    """Channels (name -> (H, W) float32) and the ``finray`` metadata of an EXR file."""
    import OpenEXR

    with OpenEXR.File(str(path), separate_channels=True, num_threads=0) as f:
        # copy while the file's channel objects are alive: their pixel arrays are
        # views into memory the binding frees with them
        channels = f.channels()
        chans = {
            name: np.array(c.pixels, dtype=np.float32, copy=True) for name, c in channels.items()
        }
        hdr = f.header()
        meta = json.loads(hdr["finray"]) if "finray" in hdr else {}
    return chans, meta
