"""Compare two runs of the same DAG (for example local vs Slurm): exit 1 on any mismatch.

    python workflow/profiles/slurm/compare_runs.py RUN_A RUN_B

Compares the files under results/ and paper/ of both run directories, leaving out
logs/ and the per-job benchmark records (results/benchmarks/**/*.tsv):
- the same set of files;
- byte-identical files pass, after masking the write dates that meshio (PLY comment) and
  matplotlib (PDF /CreationDate) put into files;
- CSV/TSV, JSON and NPZ: every number equal to TOL (|a - b| <= TOL max(1, |a|, |b|),
  TOL = 1e-9 or --rtol), float32 arrays to max(TOL, 1e-6) (a few float32 ulps), every
  string equal; columns/keys named like a timing (TIMING) are listed, not compared;
- text files (md, txt, tex, html, pvd): equal line by line after masking the numbers on
  lines that name a timing, the numbers followed by a time unit (``12.3 s``, ``1.9 ms/frame``)
  and the cells of table columns (markdown or HTML) whose header names a timing;
- checkpoints (``model.pt``, ``model.ts``): every weight tensor bit-identical, the other
  entries as JSON (a checkpoint's training history holds its step times);
- any other differing file (PNG, VTU, ...) is a mismatch unless its path names a timing
  (a speed figure plots measured times) or it is a figure of TIMED_FIGURES.
"""

import json
import re
import sys
from pathlib import Path

import numpy as np
import pandas as pd

TOL = 1e-9
TIMING = re.compile(
    r"(time|timing|(^|_)ms(_|$)|(^|_)s(_per|$)|_s_|\d s/|load_average|seconds|latency|fps|throughput|speed|rss|wall|cpu"
    r"|duration|elapsed|per_s|hz|date|host|pareto|benchmark)",
    re.I,
)
TEXT = {".md", ".txt", ".tex", ".html", ".pvd", ".rst", ".yaml", ".j2"}
STAMPS = re.compile(rb"(comment Created by meshio[^\n]*|/(Creation|Mod)Date \(D:[^)]*\))")
NUM = re.compile(r"[-+]?\d*\.?\d+(?:[eE][-+]?\d+)?")
TIMED = re.compile(NUM.pattern + r"(?=\s*(?:ms|s|min|h)\b)")
# a table header that names a time unit: "(s)", "(min, sum)", "s/scene", "ms/frame"
UNIT_HEADER = re.compile(r"\((?:s|ms|min|h)\b|(?:^|\W)(?:s|ms|min)/")
# figures that plot measured times beside results (finray.evaluate.figures)
TIMED_FIGURES = {
    "material_generalisation": "its right panel plots the FEA's and the network's time per material"
}


def files(run):
    """Relative paths of the compared files of a run directory."""
    out = set()
    for top in ("results", "paper"):
        for p in (Path(run) / top).rglob("*"):
            rel = p.relative_to(run).as_posix()
            if not p.is_file() or "/logs/" in f"/{rel}" or ".snakemake" in rel:
                continue
            if rel.startswith("results/benchmarks/") and p.suffix == ".tsv":
                continue
            out.add(rel)
    return out


def close(a, b, tol=None):
    """Numbers equal to tol (default TOL; relative above 1)."""
    tol = TOL if tol is None else tol
    a, b = np.asarray(a, float), np.asarray(b, float)
    both_nan = np.isnan(a) & np.isnan(b)
    with np.errstate(invalid="ignore"):
        ok = np.abs(a - b) <= tol * np.maximum(1.0, np.maximum(np.abs(a), np.abs(b)))
    return bool(np.all(ok | both_nan))


def flat(obj, key=""):
    """{dotted key: leaf} of a JSON document or a checkpoint (tensors are leaves)."""
    if isinstance(obj, dict):
        return {k: v for kk, vv in obj.items() for k, v in flat(vv, f"{key}.{kk}").items()}
    if isinstance(obj, (list, tuple)):
        return {k: v for i, vv in enumerate(obj) for k, v in flat(vv, f"{key}[{i}]").items()}
    return {key: obj}


def compare_table(a, b, sep):
    """(problems, ignored timing columns) of two CSV/TSV files."""
    da, db = pd.read_csv(a, sep=sep), pd.read_csv(b, sep=sep)
    if list(da.columns) != list(db.columns) or da.shape != db.shape:
        return [f"columns/shape {list(da.columns)} {da.shape} vs {list(db.columns)} {db.shape}"], []
    bad, timing = [], []
    for c in da.columns:
        if TIMING.search(str(c)):
            if not da[c].equals(db[c]):
                timing.append(str(c))
            continue
        if pd.api.types.is_numeric_dtype(da[c]) and pd.api.types.is_numeric_dtype(db[c]):
            if not close(da[c], db[c]):
                bad.append(f"column {c}: max |diff| {np.nanmax(np.abs(da[c] - db[c])):.3g}")
        elif not da[c].astype(str).equals(db[c].astype(str)):
            # a text cell of a timing row (md-like tables) is timing as well
            rows = da[c].astype(str) != db[c].astype(str)
            bad.append(f"column {c}: {int(rows.sum())} cells differ")
    return bad, timing


def compare_json(a, b):
    """(problems, ignored timing keys) of two JSON files."""
    return _compare_flat(
        flat(json.loads(Path(a).read_text())), flat(json.loads(Path(b).read_text()))
    )


def _compare_flat(fa, fb):
    """(problems, ignored timing keys) of two {dotted key: leaf} documents."""
    if fa.keys() != fb.keys():
        return [f"keys differ: {sorted(fa.keys() ^ fb.keys())[:5]}"], []
    bad, timing = [], []
    for k in fa:
        va, vb = fa[k], fb[k]
        if va == vb:
            continue
        if TIMING.search(re.sub(r"\[\d+\]", "", k)):
            timing.append(k.lstrip("."))
        elif isinstance(va, (int, float)) and isinstance(vb, (int, float)) and close(va, vb):
            continue
        else:
            bad.append(f"{k.lstrip('.')}: {va!r} vs {vb!r}")
    return bad, timing


def compare_npz(a, b):
    """Problems of two NPZ files (arrays equal to TOL, others exactly)."""
    with np.load(a, allow_pickle=False) as za, np.load(b, allow_pickle=False) as zb:
        if set(za.files) != set(zb.files):
            return [f"arrays differ: {sorted(set(za.files) ^ set(zb.files))}"]
        bad = []
        for k in za.files:
            x, y = za[k], zb[k]
            if x.shape != y.shape:
                bad.append(f"{k}: shape {x.shape} vs {y.shape}")
            elif x.dtype.kind in "fiub" and y.dtype.kind in "fiub":
                f32 = np.float32 in (x.dtype, y.dtype)
                if not close(x, y, max(TOL, 1e-6) if f32 else None):
                    bad.append(f"{k}: max |diff| {np.nanmax(np.abs(x.astype(float) - y)):.3g}")
            elif not np.array_equal(x, y):
                bad.append(f"{k}: differs")
        return bad


def timed_columns(lines):
    """Per line, the indices of its table cells under a header that names a timing
    (markdown ``| a | b |`` tables, and HTML tables written a cell per line)."""
    out, md_head, html_head, col = [], None, [], -1
    for line in lines:
        t = line.strip()
        cols = set()
        if t.startswith("|"):
            cells = t.strip("|").split("|")
            if md_head is None:
                md_head = [
                    i
                    for i, c in enumerate(map(str.strip, cells))
                    if TIMING.search(c) or UNIT_HEADER.search(c)
                ]
            cols = set(md_head)
        else:
            md_head = None
        if t.startswith("<tr"):
            col = -1
        elif t.startswith("<thead"):
            html_head = []
        elif t.startswith("<th"):
            head = re.sub(r"<[^>]+>", "", t).strip()
            html_head.append(bool(TIMING.search(head) or UNIT_HEADER.search(head)))
        elif t.startswith("<td"):
            col += 1
            if col < len(html_head) and html_head[col]:
                cols = {0}
        out.append(cols)
    return out


def _mask(line, cols):
    """The line with its timed numbers and the numbers of its timed cells masked."""
    line = TIMED.sub("#", line)
    if line.strip().startswith("|"):  # cells without their padding (widths follow the numbers)
        cells = line.strip().split("|")
        line = "|".join(
            (NUM.sub("#", c) if i - 1 in cols else c).strip() for i, c in enumerate(cells)
        )
    elif cols:
        line = NUM.sub("#", line)
    return line


def compare_text(a, b):
    """(problems, timing lines) of two text files, numbers masked on timing lines, after
    time units and in timing columns."""
    la, lb = Path(a).read_text().splitlines(), Path(b).read_text().splitlines()
    if len(la) != len(lb):
        return [f"{len(la)} vs {len(lb)} lines"], []
    bad, timing = [], []
    for i, (x, y, cols) in enumerate(zip(la, lb, timed_columns(la)), 1):
        if x == y:
            continue
        if (TIMING.search(x) and NUM.sub("#", x) == NUM.sub("#", y)) or _mask(x, cols) == _mask(
            y, cols
        ):
            timing.append(f"line {i}")
        else:
            bad.append(f"line {i}: {x.strip()[:80]!r} vs {y.strip()[:80]!r}")
    return bad, timing


def compare_checkpoint(a, b):
    """(problems, timing keys) of two torch checkpoints (``.pt``: a dict with a state
    dict; ``.ts``: TorchScript): tensors bit-identical, other entries as JSON."""
    import torch

    def load(p):
        if p.suffix == ".ts":
            return {"state_dict": dict(torch.jit.load(str(p), map_location="cpu").state_dict())}
        return torch.load(p, map_location="cpu", weights_only=True)  # no code run

    fa, fb = flat(load(Path(a))), flat(load(Path(b)))
    ta = {k: v for k, v in fa.items() if isinstance(v, torch.Tensor)}
    tb = {k: v for k, v in fb.items() if isinstance(v, torch.Tensor)}
    if ta.keys() != tb.keys():
        return [f"tensors differ: {sorted(ta.keys() ^ tb.keys())[:5]}"], []
    bad = [f"{k}: tensor differs" for k in ta if not torch.equal(ta[k], tb[k])]
    more, timing = _compare_flat(
        {k: v for k, v in fa.items() if k not in ta}, {k: v for k, v in fb.items() if k not in tb}
    )
    return bad + more, timing


def main(argv=None):
    global TOL
    argv = list(sys.argv[1:] if argv is None else argv)
    if "--rtol" in argv:
        i = argv.index("--rtol")
        TOL = float(argv[i + 1])
        del argv[i : i + 2]
    if len(argv) != 2 or not all(Path(r, "results").is_dir() for r in argv):
        sys.exit("usage: compare_runs.py [--rtol 1e-9] RUN_A RUN_B (directories holding results/)")
    a, b = argv
    fa, fb = files(a), files(b)
    mismatches = [f"only in {a}: {p}" for p in sorted(fa - fb)]
    mismatches += [f"only in {b}: {p}" for p in sorted(fb - fa)]
    identical, timing_only = 0, []
    for rel in sorted(fa & fb):
        pa, pb = Path(a, rel), Path(b, rel)
        if STAMPS.sub(b"", pa.read_bytes()) == STAMPS.sub(b"", pb.read_bytes()):
            identical += 1
            continue
        suf, timing = pa.suffix.lower(), []
        try:
            if suf in (".csv", ".tsv"):
                bad, timing = compare_table(pa, pb, "," if suf == ".csv" else "\t")
            elif suf == ".json":
                bad, timing = compare_json(pa, pb)
            elif suf == ".npz":
                bad = compare_npz(pa, pb)
            elif suf in TEXT:
                bad, timing = compare_text(pa, pb)
            elif suf in (".pt", ".ts"):
                bad, timing = compare_checkpoint(pa, pb)
            elif TIMING.search(rel):
                bad, timing = [], ["whole file (its path names a timing)"]
            elif pa.stem in TIMED_FIGURES:
                bad, timing = [], [f"whole figure ({TIMED_FIGURES[pa.stem]})"]
            else:
                bad = ["bytes differ"]
        except (ValueError, OSError, RuntimeError, json.JSONDecodeError) as exc:
            bad = [f"unreadable: {exc}"]
        if bad:
            mismatches.append(f"{rel}: " + "; ".join(bad[:5]))
        else:
            kind = "equal to 1e-9" if not timing else "timings differ: " + ", ".join(timing[:6])
            timing_only.append(f"{rel}: {kind}")
    n = len(fa & fb)
    print(
        f"compare (rtol {TOL:g}): {len(fa)} vs {len(fb)} files; {n} in both: {identical} identical (write dates masked), "
        f"{len(timing_only)} equal apart from timings/roundoff, {len(mismatches)} mismatches"
    )
    for line in timing_only:
        print(f"  ok (not bit-identical) {line}")
    for line in mismatches:
        print(f"  MISMATCH {line}")
    return 1 if mismatches else 0


if __name__ == "__main__":
    sys.exit(main())
