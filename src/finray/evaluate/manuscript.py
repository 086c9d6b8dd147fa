"""The manuscript: a Jinja2 template (``paper/manuscript.md.j2``) filled from
``results/summary.json`` (no number is typed by hand; the comparatives come from
:mod:`finray.evaluate.wording`), rendered to HTML."""

from __future__ import annotations

import json
import math
from pathlib import Path

from .wording import jinja_globals, number_word


def _fmt(v, digits: int = 2) -> str:
    if v is None:
        return "n/a"
    return f"{v:.{digits}f}"


def render_text(template, summary: dict, extra: dict | None = None) -> str:
    """The filled template (Markdown); an undefined key is an error (StrictUndefined)."""
    import jinja2

    env = jinja2.Environment(undefined=jinja2.StrictUndefined, keep_trailing_newline=True)
    env.filters["f"] = _fmt
    env.filters["pct"] = lambda v, d=1: _fmt(v, d)
    env.filters["g"] = lambda v, d=2: "n/a" if v is None else f"{v:.{d}g}"  # 0.001, 3.4e-07
    env.filters["degs"] = lambda v: ", ".join(f"{x:g}°" for x in v) if v else "no pitch"
    env.filters["nword"] = number_word
    env.filters["exp"] = math.exp
    env.globals.update(jinja_globals())
    return env.from_string(Path(template).read_text()).render(s=summary, **(extra or {}))


def render_manuscript(template, summary_json, out_md, out_html, extra: dict | None = None) -> str:
    """Fill the template and write Markdown and a standalone HTML page (figures are
    referenced relative to the manuscript, as ``figures/<name>.png``)."""
    import markdown

    text = render_text(template, json.loads(Path(summary_json).read_text()), extra)
    Path(out_md).write_text(text)
    body = markdown.markdown(text, extensions=["tables", "toc"])
    css = (
        "body{max-width:52em;margin:2em auto;font-family:Georgia,serif;line-height:1.45;"
        "padding:0 1em}img{max-width:100%}table{border-collapse:collapse;margin:1em 0}"
        "td,th{border:1px solid #bbb;padding:.25em .6em;text-align:right}"
        "td:first-child,th:first-child{text-align:left}code{font-size:90%}"
    )
    Path(out_html).write_text(
        "<!DOCTYPE html>\n<html><head><meta charset='utf-8'>"
        f"<title>finray</title><style>{css}</style></head><body>\n"
        f"{body}\n</body></html>\n"
    )
    return text
