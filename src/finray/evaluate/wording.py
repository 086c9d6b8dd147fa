"""Words derived from numbers, for the manuscript: every comparative ("times smaller",
"about the same", "below the paper's range", "only") is computed from the values it
compares, with the tolerances stated here, so that the text turns when the numbers do."""

from __future__ import annotations

import math

#: Two values within this factor of each other are "about the same" (10 %).
SAME_FACTOR = 1.1
#: An overlap (IoU) below this is "only" that much (a small pitch should leave the
#: silhouette nearly unchanged).
HIGH_OVERLAP = 0.9
#: A predictor with R² above this explains "most" of the force's variance.
MOST_R2 = 0.5
#: Final forces of different objects at one height are "close" while their coefficient
#: of variation (std / mean) is at most this (%).
CLOSE_CV_PCT = 10.0

NUMBER_WORDS = ["no", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten"]


def _ok(*v) -> bool:
    return all(x is not None and math.isfinite(float(x)) for x in v)


def ratio(a: float, b: float) -> float | None:
    """``a / b``, None when either is missing or not finite, or b is not positive."""
    if not _ok(a, b) or b <= 0 or a < 0:
        return None
    return float(a) / float(b)


def compare(
    a: float, b: float, smaller: str = "smaller", larger: str = "larger", than: bool = True
) -> str:
    """How ``a`` compares with ``b``: ``"3.4 times smaller than"``, ``"about the same as"``
    (within :data:`SAME_FACTOR`) or ``"2.1 times larger than"``; ``than=False`` drops the
    connector. ``smaller``/``larger`` name the direction ("less"/"more" for times).
    ``"not comparable with"`` when a value is missing or not positive."""
    r = ratio(a, b)
    if r is None or r == 0:
        words, conn = "not comparable", " with"
    elif max(r, 1 / r) < SAME_FACTOR:
        words, conn = "about the same", " as"
    elif r < 1:
        words, conn = f"{1 / r:.1f} times {smaller}", " than"
    else:
        words, conn = f"{r:.1f} times {larger}", " than"
    return words + (conn if than else "")


def is_same(a: float, b: float) -> bool:
    """``a`` and ``b`` within :data:`SAME_FACTOR` of each other."""
    r = ratio(a, b)
    return r is not None and r > 0 and max(r, 1 / r) < SAME_FACTOR


def range_relation(values, ref) -> str:
    """Where the range of ``values`` lies against the range ``ref`` (both [lo, hi] or
    lists): ``"below"``, ``"within"``, ``"above"`` or ``"overlapping"``."""
    lo, hi = min(values), max(values)
    rlo, rhi = min(ref), max(ref)
    if hi < rlo:
        return "below"
    if lo > rhi:
        return "above"
    if lo >= rlo and hi <= rhi:
        return "within"
    return "overlapping"


def number_word(n: int) -> str:
    """``3`` -> ``"three"`` (up to ten), else the digits."""
    return NUMBER_WORDS[n] if 0 <= n < len(NUMBER_WORDS) else str(n)


def reach(usable_deg: float | None, pitches, paper_below_deg: float) -> str:
    """How far a network stays usable in pitch, against the paper's "usable below
    ``paper_below_deg``": ``usable_deg`` is the largest pitch up to which every tested
    pitch is within the threshold (None: not even 0°). The paper's claim covers the
    tested pitches below its limit; "only" is said only when ours falls short of them."""
    below = [float(p) for p in pitches if float(p) < paper_below_deg]
    paper = f"the paper's network (usable below {paper_below_deg:g}°)"
    if usable_deg is None:
        return f"at no pitch, short of {paper}"
    if below and usable_deg < max(below):
        return f"up to {usable_deg:g}° only, short of {paper}"
    if below and usable_deg == max(below):
        return f"up to {usable_deg:g}°, as {paper}"
    return f"up to {usable_deg:g}°, beyond {paper}"


def count(n: int, noun: str, plural: str | None = None) -> str:
    """``count(3, "shape")`` -> ``"three shapes"``, ``count(1, "shape")`` -> ``"one shape"``."""
    return f"{number_word(n)} {noun if n == 1 else (plural or noun + 's')}"


def jinja_globals() -> dict:
    """The helpers and tolerances, as the manuscript template sees them."""
    return {
        "compare": compare,
        "is_same": is_same,
        "range_relation": range_relation,
        "number_word": number_word,
        "count": count,
        "reach": reach,
        "ratio": ratio,
        "SAME_FACTOR": SAME_FACTOR,
        "HIGH_OVERLAP": HIGH_OVERLAP,
        "MOST_R2": MOST_R2,
        "CLOSE_CV_PCT": CLOSE_CV_PCT,
    }
