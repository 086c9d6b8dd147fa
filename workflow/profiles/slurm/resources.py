"""Measured resources per rule, from the benchmark files of a finished full run.

    python workflow/profiles/slurm/resources.py RESULTS_DIR [--check]

Reads every rule's ``benchmark:`` pattern from workflow/rules/*.smk, matches the files
under RESULTS_DIR/benchmarks and prints, per rule,
    mem_mb  = 1.5 x the largest max_rss (MB) over its jobs, rounded up to 100 MB
    runtime = ceil(2 x the longest wall time s / 60) minutes, at least 1
Rules without a benchmark get DEFAULT. The rules declare these numbers in their
``resources:``; --check exits 1 (one line per rule) where a rule's declaration differs.
"""

import argparse
import math
import re
import sys
from pathlib import Path

import pandas as pd

RULES = Path(__file__).resolve().parents[2] / "rules"
DEFAULT = {"mem_mb": 2000, "runtime": 10}  # no benchmark: light plotting/table jobs

_RULE = re.compile(r"^rule (\w+):", re.M)
_BENCH = re.compile(r'benchmark:\s*\n\s*f"\{RESULTS\}/benchmarks/([^"]+)"')
_RES = re.compile(r"resources:\s*\n((?:\s+\w+=\d+,?\s*\n)+)")


def rule_blocks():
    """{rule: its text} over workflow/rules/*.smk."""
    blocks = {}
    for smk in sorted(RULES.glob("*.smk")):
        text = smk.read_text()
        starts = [(m.group(1), m.start()) for m in _RULE.finditer(text)]
        for (name, a), (_, b) in zip(starts, starts[1:] + [("", len(text))]):
            blocks[name] = text[a:b]
    return blocks


def pattern_regex(pattern):
    """A benchmark f-string pattern ('render/{{object}}_h{{height}}.tsv') as a regex."""
    parts = re.split(r"\{\{\w+\}\}", pattern)
    return re.compile("^" + ".+".join(re.escape(p) for p in parts) + "$"), len("".join(parts))


def measured(results, blocks):
    """{rule: {mem_mb, runtime, jobs}} from RESULTS/benchmarks/**/*.tsv."""
    patterns = {
        name: pattern_regex(m.group(1))
        for name, text in blocks.items()
        if (m := _BENCH.search(text))
    }
    rows = {}
    for tsv in sorted((Path(results) / "benchmarks").rglob("*.tsv")):
        rel = tsv.relative_to(Path(results) / "benchmarks").as_posix()
        hits = [(lit, name) for name, (rx, lit) in patterns.items() if rx.match(rel)]
        if not hits:
            continue
        name = max(hits)[1]  # the most specific pattern (most literal text) wins
        rows.setdefault(name, []).append(pd.read_csv(tsv, sep="\t").iloc[-1])
    out = {}
    for name, rs in rows.items():
        df = pd.DataFrame(rs)
        rss = pd.to_numeric(df["max_rss"], errors="coerce").max()
        out[name] = {
            "mem_mb": int(math.ceil(1.5 * rss / 100.0) * 100),
            "runtime": max(1, math.ceil(2 * df["s"].max() / 60)),
            "jobs": len(df),
            "max_rss": rss,
            "max_s": df["s"].max(),
        }
    return out


def declared(text):
    """{mem_mb, runtime} as a rule block declares them ({} if it declares none)."""
    m = _RES.search(text)
    return {k: int(v) for k, v in re.findall(r"(\w+)=(\d+)", m.group(1))} if m else {}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("results", help="results/ of a finished full run")
    ap.add_argument("--check", action="store_true", help="compare with the rules")
    args = ap.parse_args(argv)
    if not (Path(args.results) / "benchmarks").is_dir():
        sys.exit(f"resources: no benchmarks/ under {args.results}")
    blocks = rule_blocks()
    meas = measured(args.results, blocks)
    bad = 0
    print(
        f"{'rule':30s} {'jobs':>4s} {'max_rss_MB':>10s} {'max_s':>8s} {'mem_mb':>6s} {'runtime':>7s}"
    )
    for name in blocks:
        want = meas.get(name, DEFAULT)
        print(
            f"{name:30s} {want.get('jobs', 0):4d} {want.get('max_rss', float('nan')):10.1f} "
            f"{want.get('max_s', float('nan')):8.1f} {want['mem_mb']:6d} {want['runtime']:7d}"
        )
        have = declared(blocks[name])
        if args.check and any(have.get(k) != want[k] for k in ("mem_mb", "runtime")):
            print(
                f"  MISMATCH {name}: declares {have}, measured "
                f"mem_mb={want['mem_mb']} runtime={want['runtime']}",
                file=sys.stderr,
            )
            bad += 1
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
