"""Emulated rigs drawn from ranges: a rig is one data point, a user's rig another.

``lab.rigs`` names how many rigs to draw besides the configured one (``count``, the
reported rigs, and ``selection`` more after them, on which settings are chosen), from
which seed, and the ranges: :func:`draw_rig` returns rig ``i``'s whole ``lab`` section, the
configured one with these drawn (from a generator seeded by ``seed`` and ``i``):

- ``uniform``: ``{"<section>.<key>": [low, high]}``, a value uniform in the range (each
  element of a list value drawn apart, e.g. the sensor's three biases), or a [low, high]
  per element of a list value (the print's relaxation times); the print's time
  dependence (:data:`LATE_DRAWS`) is drawn last;
- ``choice``: ``{"<section>.<key>": [option, ...]}``, one option (e.g. the frame size);
- ``colours``: the finger's hue (deg), the object's hue offset from it (deg, kept far
  from the finger's, as a lab would paint it), saturation, value and the background's
  grey, as ranges; colours are linear RGB;
- ``object_scale``: each object's size scaled by one factor in the range;
- ``height_jitter_mm``: each contact height moved by up to this much (whole mm);
- ``height_span_mm``: ``[low, high]`` instead: the rig's contact heights (as many as
  ``heights_mm``) drawn over the finger's face, one (whole mm) in each of as many equal
  parts of the span, its low end raised to where every (scaled) object clears the
  clamped base by ``BASE_CLEARANCE_MM``.

Every drawn rig is emulated: its ``camera.model`` says so and which draw it is.
"""

from __future__ import annotations

import colorsys
import copy

import numpy as np


#: mm between the clamped base and an object's lowest point at a drawn height
BASE_CLEARANCE_MM = 1.0

#: ``uniform`` keys drawn after every other draw (the print's time dependence, added
#: after the rest): the rigs' other values are those they were drawn before it
LATE_DRAWS = ("as_built.relax_fractions", "as_built.relax_times_s", "as_built.softening")


def span_heights(rng: np.random.Generator, objects: dict, span_mm, n: int) -> list[float]:
    """``n`` contact heights (whole mm), one drawn in each of ``n`` equal parts of
    ``span_mm`` = [low, high], the low end raised so that every object of ``objects``
    clears the base by :data:`BASE_CLEARANCE_MM`."""
    from ..geometry.objects import object_shape

    reach = max(-object_shape(o, 0.5).bounds[1] for o in objects.values())
    lo, hi = max(float(span_mm[0]), reach + BASE_CLEARANCE_MM), float(span_mm[1])
    edges = np.linspace(lo, hi, n + 1)
    a = np.ceil(edges[:-1]).astype(int)
    b = np.r_[np.ceil(edges[1:-1]).astype(int) - 1, int(np.floor(hi))]
    if np.any(b < a):
        raise ValueError(
            f"lab.rigs.height_span_mm {list(span_mm)}: from {lo:.1f} mm (where every "
            f"object clears the base) it holds fewer than {n} whole-mm heights"
        )
    return [float(rng.integers(x, y + 1)) for x, y in zip(a, b)]


def rig_names(rigs: dict) -> list[str]:
    """The reported rigs: ``rig1`` .. ``rig<count>``."""
    return [f"rig{i}" for i in range(1, int(rigs.get("count", 0)) + 1)]


def selection_rig_names(rigs: dict) -> list[str]:
    """The rigs drawn after the reported ones, ``rig<count + 1>`` .. ``rig<count +
    selection>``: settings are chosen on these, so that the reported rigs stay unseen."""
    n = int(rigs.get("count", 0))
    return [f"rig{i}" for i in range(n + 1, n + int(rigs.get("selection", 0)) + 1)]


def rig_index(name: str) -> int:
    """``rig3`` -> 3 (one line on anything else)."""
    if not name.startswith("rig") or not name[3:].isdigit() or int(name[3:]) < 1:
        raise ValueError(f"a drawn rig is named rig1, rig2, ..., not {name!r}")
    return int(name[3:])


def _parent(d: dict, path: str) -> tuple[dict, str]:
    """The dict that holds ``path``'s last key, and that key (one line if lab has none)."""
    *head, last = path.split(".")
    for k in head:
        d = d.get(k) if isinstance(d, dict) else None
    if not isinstance(d, dict) or last not in d:
        raise ValueError(f"lab.rigs draws {path!r}, which lab has no value for")
    return d, last


def _set(d: dict, path: str, value) -> None:
    parent, key = _parent(d, path)
    parent[key] = value


def _get(d: dict, path: str):
    parent, key = _parent(d, path)
    return parent[key]


def _hsv(h_deg: float, s: float, v: float) -> list[float]:
    return [round(float(c), 4) for c in colorsys.hsv_to_rgb((h_deg % 360.0) / 360.0, s, v)]


def _scale_object(spec: dict, s: float) -> dict:
    out = copy.deepcopy(spec)
    for key in ("diameter_mm", "side_mm", "width_mm", "height_mm", "wall_mm"):
        if key in out:
            out[key] = round(float(out[key]) * s, 2)
    if "vertices_mm" in out:
        out["vertices_mm"] = [
            [round(float(x) * s, 2), round(float(y) * s, 2)] for x, y in out["vertices_mm"]
        ]
    return out


def draw_rig(lab: dict, index: int) -> dict:
    """Rig ``index`` (1, 2, ...) of ``lab["rigs"]``: the ``lab`` section with its drawn
    values (see the module's text); deterministic in ``lab["rigs"]["seed"]`` and
    ``index``. The result has no ``rigs`` key."""
    spec = lab.get("rigs") or {}
    n = int(spec.get("count", 0)) + int(spec.get("selection", 0))
    if not 1 <= index <= n:
        raise ValueError(f"lab.rigs draws {n} rigs (count and selection), not rig {index}")
    rng = np.random.default_rng([int(spec.get("seed", 0)), index])
    out = copy.deepcopy({k: v for k, v in lab.items() if k != "rigs"})
    out["seed"] = int(lab.get("seed", 0)) + 1000 * index  # the takes' noise: the rig's own
    uniform = spec.get("uniform", {})
    late = sorted(k for k in uniform if k in LATE_DRAWS)
    for path in sorted(k for k in uniform if k not in LATE_DRAWS):
        _draw_uniform(rng, out, path, uniform[path])
    for path, options in sorted(spec.get("choice", {}).items()):
        _set(out, path, copy.deepcopy(options[int(rng.integers(len(options)))]))
    col = spec.get("colours")
    if col:
        hue = rng.uniform(*col["finger_hue_deg"])
        sat, val = rng.uniform(*col["saturation"], 2), rng.uniform(*col["value"], 2)
        look = out["look"]
        look["finger_rgb"] = _hsv(hue, sat[0], val[0])
        look["object_rgb"] = _hsv(hue + rng.uniform(*col["object_hue_offset_deg"]), sat[1], val[1])
        grey = float(rng.uniform(*col["background_grey"]))
        look["background_rgb"] = [round(grey, 4)] * 3
    if spec.get("object_scale"):
        out["objects"] = {
            name: _scale_object(o, float(rng.uniform(*spec["object_scale"])))
            for name, o in sorted(out["objects"].items())
        }
    jitter = int(spec.get("height_jitter_mm", 0))
    if spec.get("height_span_mm"):
        out["heights_mm"] = span_heights(
            rng, out["objects"], spec["height_span_mm"], len(out["heights_mm"])
        )
    elif jitter:
        heights = [float(h) + int(rng.integers(-jitter, jitter + 1)) for h in out["heights_mm"]]
        if len(set(heights)) < len(heights):
            raise ValueError(f"rig {index}: height_jitter_mm {jitter} made two heights equal")
        out["heights_mm"] = heights
    for path in late:  # after every other draw: adding them left those as they were
        _draw_uniform(rng, out, path, uniform[path])
    out["camera"]["model"] = f"emulated rig {index} of lab.rigs (seed {spec.get('seed', 0)})"
    return out


def _draw_uniform(rng: np.random.Generator, out: dict, path: str, bounds) -> None:
    """``path``'s value drawn uniform in ``bounds``: [low, high] (each element of a list
    value apart), or a [low, high] per element of a list value."""
    old = _get(out, path)
    if bounds and isinstance(bounds[0], (list, tuple)):
        if not isinstance(old, list) or len(old) != len(bounds):
            raise ValueError(
                f"lab.rigs.uniform.{path}: {len(bounds)} ranges for a value of "
                f"{len(old) if isinstance(old, list) else 1} element(s)"
            )
        value = [round(float(rng.uniform(lo, hi)), 4) for lo, hi in bounds]
    elif isinstance(old, list):
        value = rng.uniform(bounds[0], bounds[1], len(old)).round(4).tolist()
    else:
        value = round(float(rng.uniform(bounds[0], bounds[1])), 4)
    _set(out, path, value)
