"""MkDocs hooks: the configuration reference from the schema and the CLI reference from
the argparse parsers, rendered at build time into the pages that hold their markers.

A page holds ``<!-- finray:config-reference -->`` or ``<!-- finray:cli-reference -->``;
the hook replaces the marker with the generated Markdown, so the site never carries a
stale copy. ``tests/workflow/test_docs.py`` calls the same functions.
"""

from __future__ import annotations

import json
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
SCHEMA = ROOT / "workflow" / "schemas" / "config.schema.yaml"
CONFIG_MARKER = "<!-- finray:config-reference -->"
CLI_MARKER = "<!-- finray:cli-reference -->"


def _cell(text) -> str:
    return " ".join(str(text).split()).replace("|", "\\|")


def _resolve(node: dict, defs: dict) -> dict:
    ref = node.get("$ref")
    if ref and ref.startswith("#/$defs/"):
        merged = dict(defs[ref.rsplit("/", 1)[1]])
        merged.update({k: v for k, v in node.items() if k != "$ref"})
        return merged
    return node


def _type(node: dict) -> str:
    t = node.get("type")
    if isinstance(t, list):
        t = " or ".join(t)
    if "enum" in node:
        return "one of " + ", ".join(f"`{json.dumps(v)}`" for v in node["enum"])
    return str(t or "–")


def _default(node: dict) -> str:
    if "default" not in node:
        return "–"
    d = node["default"]
    if d == {} and node.get("type") == "object":
        return "–"
    return f"`{json.dumps(d)}`"


def _walk(props: dict, prefix: str, defs: dict, rows: list) -> None:
    for name, node in props.items():
        node = _resolve(node, defs)
        key = f"{prefix}{name}"
        sub = node.get("properties")
        if sub and node.get("type") == "object":
            if node.get("description"):
                rows.append((key, "object", "–", node["description"]))
            _walk(sub, key + ".", defs, rows)
            continue
        extra = node.get("additionalProperties")
        if isinstance(extra, dict) and node.get("type") == "object" and "$ref" in extra:
            rows.append((key, "object", _default(node), node.get("description", "")))
            item = _resolve(extra, defs)
            if item.get("properties"):
                _walk(item["properties"], key + ".<name>.", defs, rows)
            continue
        rows.append((key, _type(node), _default(node), node.get("description", "")))


def config_reference(schema_path: Path = SCHEMA) -> str:
    """Markdown: the schema's description, then one table per top-level section (key,
    type, default, meaning), every key the schema knows, in its order."""
    schema = yaml.safe_load(schema_path.read_text())
    defs = schema.get("$defs", {})
    out = [_cell(schema.get("description", "")), ""]
    for section, node in schema["properties"].items():
        node = _resolve(node, defs)
        rows: list = []
        _walk({section: node}, "", defs, rows)
        out += [f"## `{section}`", ""]
        if node.get("description") and node.get("properties"):
            out += [_cell(node["description"]), ""]
        out += ["| key | type | default | meaning |", "|---|---|---|---|"]
        out += [f"| `{k}` | {_cell(t)} | {_cell(d)} | {_cell(m)} |" for k, t, d, m in rows]
        out.append("")
    return "\n".join(out)


def cli_reference() -> str:
    """Markdown: ``finray --help`` and each subcommand's ``--help``, as argparse prints
    them (80 columns)."""
    import argparse
    import os

    os.environ["COLUMNS"] = "80"
    from finray.cli import build_parser

    parser = build_parser()
    out = ["## `finray`", "", "```text", parser.format_help().rstrip(), "```", ""]
    subs = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, sub in subs.choices.items():
        out += [f"## `finray {name}`", "", "```text", sub.format_help().rstrip(), "```", ""]
    return "\n".join(out)


def on_page_markdown(markdown: str, page, config, files, **kwargs) -> str:
    if CONFIG_MARKER in markdown:
        markdown = markdown.replace(CONFIG_MARKER, config_reference())
    if CLI_MARKER in markdown:
        markdown = markdown.replace(CLI_MARKER, cli_reference())
    return markdown
