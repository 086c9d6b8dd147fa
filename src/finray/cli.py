"""The ``finray`` command line. Lengths in mm, angles in degrees."""

from __future__ import annotations

import argparse
import math
import os
import re
import sys
from pathlib import Path

from . import __version__
from .errors import BadInput, ConfigError, FinrayError, GeometryError, UsageError


class _Parser(argparse.ArgumentParser):
    """An argument parser whose errors are one line, ``<prog>: <message>`` (exit code
    2), as every other bad input of ``finray``."""

    def error(self, message):
        self.exit(2, f"{self.prog}: {message}\n")

    def parse_args(self, args=None, namespace=None):
        """argparse's, with an unknown argument refused by the subcommand's parser
        (``finray geometry: unrecognized arguments: --bogus``), as its other errors
        (argparse's own names ``finray`` only)."""
        args, extra = self.parse_known_args(args, namespace)
        if extra:
            subs = self._subparsers._group_actions[0].choices if self._subparsers else {}
            parser = subs.get(getattr(args, "command", None), self)
            parser.error(f"unrecognized arguments: {' '.join(extra)}")
        return args


class _Once(argparse._StoreAction):
    """An option that takes one value: given again, it is refused (the last one once
    won silently). :func:`build_parser` makes every single-valued option one."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = namespace.__dict__.setdefault("_given_once", {})
        if self.dest in given:
            raise argparse.ArgumentError(
                None,
                f"{option_string} takes one value, got {given[self.dest]} and {values}",
            )
        given[self.dest] = values
        super().__call__(parser, namespace, values, option_string)


#: the number options (argparse dests) of every subcommand: (unit in words, lowest,
#: whether the lowest itself is allowed, highest or None); checked by :func:`_check_numbers`
_NUMBERS = {
    "size_mm": ("mm", 0, False, None),
    "minor_mm": ("mm", 0, False, None),
    "wall_mm": ("mm", 0, False, None),
    "angle_deg": ("degrees", -360, True, 360),
    "fillet_mm": ("mm", 0, True, None),
    "height_mm": ("mm", 0, False, None),
    "mesh_size_mm": ("mm", 0, False, None),
    "check": ("frames", 1, True, None),
    "threads": ("threads (this machine's CPUs)", 1, True, os.cpu_count() or 1),
}


def _check_numbers(args) -> None:
    """Every number given on the command line finite and in its range, or a one-line
    :class:`UsageError` with its unit (``--angle-deg nan`` once ended in a GEOS
    exception, ``--threads 99999999999`` in an overflow)."""

    def shown(v) -> str:
        return str(v) if isinstance(v, int) else f"{v:g}"

    for dest, (unit, lo, lo_ok, hi) in _NUMBERS.items():
        value = getattr(args, dest, None)
        for v in value if isinstance(value, list) else [value]:
            if v is None or isinstance(v, bool):
                continue
            opt = "--" + dest.replace("_", "-")
            if isinstance(v, float) and not math.isfinite(v):  # an int: any size
                raise UsageError(f"{opt} must be a finite number of {unit}, got {shown(v)}")
            if hi is not None and not lo <= v <= hi:
                raise UsageError(f"{opt} must be between {lo} and {hi} {unit}, got {shown(v)}")
            if v < lo or (v == lo and not lo_ok):
                raise UsageError(
                    f"{opt} must be {'>=' if lo_ok else '>'} {lo} {unit}, got {shown(v)}"
                )


def _positive(args, *names: str) -> None:
    """Refuse options (argparse dests) given as 0 or below, or not finite: a size, a
    count or a thread number of 0 makes no sense (and once silently took the default)."""
    import math

    for n in names:
        v = getattr(args, n, None)
        if v is not None and not (math.isfinite(v) and v > 0):
            raise UsageError(f"--{n.replace('_', '-')} must be > 0, got {v:g}")


def _add_overwrite(p, what: str = "an earlier run's outputs in --out") -> None:
    p.add_argument(
        "--overwrite",
        action="store_true",
        help=f"replace {what}, once the new ones are complete (refused without it)",
    )


def _staged(args, **kw):
    """The run's outputs at ``--out`` under one policy (:class:`finray.outputs.Staged`):
    written beside it under a temporary name, moved into place when complete; a used
    ``--out`` refused without ``--overwrite``."""
    from .outputs import Staged

    # what the run reads: --overwrite never replaces a folder that holds one of them
    names = ("take", "source", "model", "calibration", "no_context", "config", "object_file")
    inputs = [getattr(args, n, None) for n in names] + list(getattr(args, "takes", None) or [])
    inputs = [Path(str(p)) for p in inputs if p is not None]
    return Staged(args.out, getattr(args, "overwrite", False), inputs=inputs, **kw)


GEOMETRY_HELP = """\
Build the finger mesh and place objects at contact heights.

Without --object/--object-file, every object of the config is placed at every
contact height and a gallery figure is drawn. Outputs in --out: finger.npz/.vtu/
.json, finger_surface.ply/.npz and objects/<name>_h<height>.npz/.vtu
(.vtu and .ply open in ParaView).

examples:
  finray geometry --out results/geometry
  finray geometry --object circle --size-mm 20 --height-mm 30 --out /tmp/scene --plot
  finray geometry --object-file part.json --height-mm 20 --out /tmp/part
"""


def _add_object_options(p, object_help: str) -> None:
    """Options that describe one object (shared by geometry and simulate)."""
    p.add_argument("--object", choices=["circle", "square", "ring", "ellipse"], help=object_help)
    p.add_argument(
        "--object-file",
        type=Path,
        help="polygon: JSON list of [x, y] in mm around the reference point",
    )
    p.add_argument(
        "--size-mm", type=float, help="circle/ring diameter, square side or ellipse width (mm)"
    )
    p.add_argument("--minor-mm", type=float, help="ellipse height before rotation (mm)")
    p.add_argument("--wall-mm", type=float, default=2.0, help="ring wall thickness (mm, default 2)")
    p.add_argument(
        "--angle-deg",
        type=float,
        default=0.0,
        help="rotation of the object about its reference point (deg, counter-clockwise)",
    )
    p.add_argument(
        "--fillet-mm",
        type=float,
        default=None,
        help="corner fillet of squares and polygons (mm; squares default 0.5)",
    )


def _geometry_parser(sub) -> None:
    p = sub.add_parser(
        "geometry",
        help="build the finger mesh and place the objects",
        description=GEOMETRY_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="YAML config (default: config/config.yaml of the source tree)",
    )
    p.add_argument("--out", type=Path, required=True, help="output directory")
    _add_object_options(p, "build only this object kind instead of the config's objects")
    p.add_argument(
        "--height-mm",
        type=float,
        action="append",
        help="contact height of the reference point (mm); repeat for several "
        "(default: the config's heights_mm)",
    )
    p.add_argument("--mesh-size-mm", type=float, help="target element edge length (mm)")
    p.add_argument(
        "--deformable", action="store_true", help="mesh the object (default: rigid, boundary only)"
    )
    p.add_argument("--plot", action="store_true", help="also draw a PNG of each scene")
    _add_overwrite(p)
    p.set_defaults(func=_run_geometry)


def _raw_config(path: Path | None) -> dict:
    """The config mapping of ``--config``; without it, the source tree's config if there
    is one, else ``{}``. A ``--config`` that does not exist is an error."""
    from .config import check_config, default_config_path, read_config_file

    if path is None:
        path = default_config_path()
        if not path.is_file():
            return {}
    raw = read_config_file(path)
    # the schema of every config (unknown keys, types, ranges, finite numbers) before
    # any work; the mapping itself is returned as read
    check_config(raw, whole=False)
    return raw


def _object_spec(args) -> tuple[str, dict] | None:
    _positive(args, "size_mm", "minor_mm", "wall_mm", "mesh_size_mm")
    if args.fillet_mm is not None and not args.fillet_mm >= 0:
        raise UsageError(f"--fillet-mm must be >= 0, got {args.fillet_mm:g}")
    if args.object_file is not None:
        spec = {"type": "polygon_file", "path": str(args.object_file)}
        name = args.object_file.stem
    elif args.object is not None:
        if args.size_mm is None:
            raise UsageError("--size-mm is required with --object")
        kind = args.object
        spec = {"type": kind}
        if kind in ("circle", "ring"):
            spec["diameter_mm"] = args.size_mm
        if kind == "ring":
            spec["wall_mm"] = args.wall_mm
        if kind == "square":
            spec["side_mm"] = args.size_mm
        if kind == "ellipse":
            spec["width_mm"] = args.size_mm
            spec["height_mm"] = args.minor_mm if args.minor_mm is not None else args.size_mm / 2
        name = f"{kind}_{_word(args.size_mm)}mm"
    else:
        return None
    if args.angle_deg:
        spec["angle_deg"] = args.angle_deg
        name += f"_a{_word(args.angle_deg)}"
    if args.fillet_mm is not None and spec["type"] in ("square", "polygon_file"):
        spec["fillet_mm"] = args.fillet_mm
    # an object's name is a word of letters, digits, _ and - (a config key, a file name)
    return re.sub(r"[^A-Za-z0-9_-]", "_", name), spec


def _word(value: float) -> str:
    """A number as a name's word: 16.5 -> 16p5."""
    return f"{value:g}".replace(".", "p")


def _run_geometry(args) -> int:
    from .config import validate_config

    raw = _raw_config(args.config)
    one = _object_spec(args)
    if one is not None:
        raw["objects"] = {one[0]: one[1]}
    if args.height_mm is not None:
        raw["heights_mm"] = args.height_mm
    if args.mesh_size_mm is not None:
        raw.setdefault("mesh", {})["size_mm"] = args.mesh_size_mm
    if not raw.get("objects"):
        raise UsageError("no config found; give --config or --object")
    cfg = validate_config(raw, base_dir=Path.cwd())
    with _staged(args) as st:
        _geometry(args, cfg, one, st.path, lambda m: print(st.shown(m)))
    return 0


def _geometry(args, cfg: dict, one, out: Path, say) -> None:
    """``finray geometry``'s files into ``out``; ``say``: a progress line."""
    from .geometry.build import build_finger, build_object
    from .geometry.gallery import gallery, scene_figure
    from .geometry.mesh import TriMesh

    summary = build_finger(cfg, out)
    q = summary["quality"]
    say(
        f"finger: {q['n_triangles']} P{q['order']} triangles, {q['n_nodes']} nodes, "
        f"min angle {q['min_angle_deg']:.1f} deg -> {out / 'finger.npz'}"
    )
    finger = TriMesh.load(out / "finger.npz")
    placed = {}
    for name, spec in cfg["objects"].items():
        deformable = args.deformable or any(
            not cfg["materials"][m]["rigid"] for m in spec["materials"]
        )
        for h in cfg["heights_mm"]:
            f = out / "objects" / f"{name}_h{h:g}.npz"
            obj = build_object(cfg, name, h, f, deformable)
            placed.setdefault(name, []).append(obj)
            ref = obj.meta["reference_point_mm"]
            say(f"{name} at {h:g} mm: reference point ({ref[0]:.3f}, {ref[1]:.3f}) mm -> {f}")
            if args.plot:
                scene_figure(finger, obj, f.with_suffix(".png"))
    if one is None:
        gallery(
            finger,
            placed,
            out / "gallery.pdf",
            out / "gallery.png",
            {n: s["split"] for n, s in cfg["objects"].items()},
        )
        say(f"gallery -> {out / 'gallery.pdf'}")


SIMULATE_HELP = """\
Simulate one scene: the object pushed 10 mm (fea.push_mm) in +x into the clamped
finger. Writes forces.csv (displacement_mm, fx_N, fy_N: force of the object on the
20 mm finger, N), summary.json, result.npz and a ParaView series (finger.pvd).

examples:
  finray simulate --object circle --size-mm 20 --height-mm 30 --material steel --out /tmp/c20
  finray simulate --object ring --size-mm 15 --wall-mm 2 --material neoprene --height-mm 20 --out /tmp/ring
"""


def _simulate_parser(sub) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate one object pushed into the finger (FEA)",
        description=SIMULATE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="YAML config for the finger, mesh, materials and solver "
        "(default: config/config.yaml of the source tree)",
    )
    p.add_argument("--out", type=Path, required=True, help="output directory")
    _add_object_options(p, "object kind (or --object-file)")
    p.add_argument(
        "--height-mm",
        type=float,
        required=True,
        action="append",
        help="contact height of the object's reference point (mm; one: "
        "finray geometry places an object at several)",
    )
    p.add_argument(
        "--material",
        default="steel",
        help="object material, a key of the config's materials (default steel: rigid)",
    )
    p.add_argument("--mesh-size-mm", type=float, help="element edge length of the finger (mm)")
    p.add_argument("--no-vtu", action="store_true", help="skip the ParaView series")
    _add_overwrite(p)
    p.set_defaults(func=_run_simulate)


def _run_simulate(args) -> int:
    import json
    import logging

    from .config import object_is_meshed, validate_config
    from .errors import SimulationError
    from .fea.scene import run_scene
    from .geometry.build import finger_from_config
    from .geometry.finger import mesh_finger
    from .geometry.objects import object_geometry

    raw = _raw_config(args.config)
    one = _object_spec(args)
    if one is None:
        raise UsageError("give --object or --object-file")
    if len(args.height_mm) > 1:
        raise UsageError(
            f"--height-mm takes one height, got {len(args.height_mm)} "
            f"({', '.join(f'{h:g}' for h in args.height_mm)}): simulate each "
            "on its own (finray geometry places an object at several)"
        )
    args.height_mm = args.height_mm[0]
    name, spec = one
    known = raw.get("materials") if isinstance(raw.get("materials"), dict) else None
    if known is not None and args.material not in known:  # the flag, not an internal key
        raise UsageError(
            f"--material {args.material}: not a material of the config (one of "
            f"{', '.join(sorted(known))})"
        )
    spec["materials"] = [args.material]
    raw["objects"] = {name: spec}
    raw["heights_mm"] = [args.height_mm]
    if args.mesh_size_mm is not None:
        raw.setdefault("mesh", {})["size_mm"] = args.mesh_size_mm
    cfg = validate_config(raw, base_dir=Path.cwd())
    if object_is_meshed(cfg, name) and spec["type"] != "ring":  # was a ValueError in the FEA
        raise UsageError(
            f"--material {args.material} is deformable, which only a ring can be (the FEA "
            "pushes a deformable object at its inner edge): give --object ring or a rigid one"
        )
    # a failed solve's report (summary.json, partial_forces.csv) is its output
    staged = _staged(args, keep=(SimulationError,))
    staged.check()  # before the meshing
    m = cfg["mesh"]
    finger = mesh_finger(
        finger_from_config(cfg), m["size_mm"], m["min_angle_deg"], m["order"], m["arc_chord_mm"]
    )
    obj = object_geometry(
        name,
        cfg["objects"][name],
        finger_from_config(cfg),
        args.height_mm,
        m["size_mm"],
        object_is_meshed(cfg, name),
        cfg["placement"]["gap_mm"],
        m["min_angle_deg"],
    )
    scene = {
        "scene": f"{name}_{args.material}_h{args.height_mm:g}",
        "object": name,
        "material": args.material,
        "height_mm": args.height_mm,
    }
    # the solver's progress lines (frame k/n, travel, elapsed) on stderr
    logger = logging.getLogger("finray")
    progress, level = logging.StreamHandler(sys.stderr), logger.level
    logger.addHandler(progress)
    logger.setLevel(logging.INFO)
    try:
        with staged:
            out = run_scene(
                cfg,
                finger,
                obj,
                args.material,
                staged.path,
                scene,
                vtu=not args.no_vtu,
                shown_dir=args.out,
            )
    finally:  # a SimulationError: main's exit code 1
        logger.removeHandler(progress)
        logger.setLevel(level)
    print(json.dumps({k: v for k, v in out.items() if k != "solver"}, indent=1))
    return 0


PREDICT_HELP = """\
Predict the contact force (N) and the stress map of each frame of an image, a folder
of images, a video or a live source (PyAV): a camera (/dev/video0, or 0) or a network
stream (rtsp://, udp://, tcp://, http://), read until it ends or Ctrl-C, the newest
frame each time (frames that come while the network is busy are dropped and counted).
The finger is segmented and cropped as in the dataset
stage, anchored on its clamped base, so camera frames of any size work. Writes
forces.csv (frame[,t_s],fx_N,fy_N[,contact_mm]: the model's force outputs and, for a
model trained with the contact head, the contact height in mm (on the finger, from its
clamped base), a video frame's time; a row as each frame completes) and, per frame,
<name>_stress.exr (log10(1 + sigma / stress_ref), the model's reference, 1 kPa by
default) and <name>_stress.png. The finger is found by its colour, learned from the
first frames (or --finger-colour), or by the renders' grey-level threshold where that
finds the same finger (segmentation.json says which). Each frame is checked against
what the model was trained on (column valid of forces.csv: ok, or its flags, e.g.
off_frame, low_confidence, shape, force_range, contact_range, near_base; a warning
counts them at the end). A frame that cannot be predicted (corrupt, no finger) is reported on stderr
and skipped, the others are written (exit code 1); bad input, or a source where the
finger is never found, stops with one line (exit code 2).
The network runs in ONNX Runtime when model.onnx and model.force.onnx lie beside
model.ts (faster), else in TorchScript; on a CUDA GPU (--device) in TorchScript.

examples:
  # every image of a folder, with the camera model of a full run
  finray predict --model results/train/camera/model.ts frames/ --out pred/
  # a video, forces only (no stress maps), on two threads
  finray predict --model results/train/camera/model.ts take.mp4 --out pred/ --force-only --threads 2
  # calibrated forces with their 90 % interval, from `finray calibrate`'s output
  finray predict --calibration rig/calibration.json take.mp4 --out pred/
  # a video to watch: annotated.mp4 (stress over the finger, force arrow) and forces.png
  finray predict --model results/train/camera/model.ts take.mp4 --out pred/ --annotate
  # a live camera (V4L2) until Ctrl-C, annotated; or a network stream
  finray predict --model results/train/camera/model.ts /dev/video0 --out live/ --annotate --no-maps
  finray predict --model results/train/camera/model.ts rtsp://192.168.1.20:8554/cam --out live/
  # check a set-up first: the mask and the validity of 6 frames (check.png)
  finray predict --model results/train/camera/model.ts take.mp4 --out check/ --check
"""


def _predict_parser(sub) -> None:
    p = sub.add_parser(
        "predict",
        help="force and stress map from camera images",
        description=PREDICT_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument(
        "--model",
        type=Path,
        help="exported model (model.ts, with model.ts.json beside it); with "
        "--calibration, its adapted model by default",
    )
    p.add_argument(
        "--calibration",
        type=Path,
        help="calibration.json of finray calibrate: each frame's force also "
        "calibrated, with its predictive interval",
    )
    p.add_argument(
        "source",
        help="image, folder of images, video, or a live source: a camera "
        "device (/dev/video0, or its index 0) or a network stream "
        "(rtsp://, udp://, tcp://, http:// ...), read until it ends or Ctrl-C",
    )
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument("--threads", type=int, default=1, help="intra-op threads (default 1)")
    p.add_argument(
        "--backend",
        choices=["auto", "onnx", "torchscript"],
        default="auto",
        help="network runtime: ONNX Runtime, TorchScript, or auto (ONNX Runtime "
        "when model.onnx is there; default)",
    )
    p.add_argument(
        "--device",
        choices=["auto", "cpu", "cuda"],
        default="auto",
        help="where the network runs: auto (a CUDA GPU when torch sees one, else "
        "the CPU; default), cpu, or cuda (stops with one line without a GPU)",
    )
    p.add_argument(
        "--force-only",
        action="store_true",
        help="forces (N) only, no stress maps (skips the stress decoder)",
    )
    p.add_argument(
        "--show",
        action="store_true",
        help="also show the annotated frames in a window as they come (implies "
        "--annotate; where there is no display, one line says so and the "
        "files are written as without it)",
    )
    p.add_argument(
        "--no-maps",
        dest="maps",
        action="store_false",
        help="no per-frame stress map files (a long video or a stream; "
        "--annotate still draws the maps)",
    )
    _add_overwrite(p)
    p.add_argument(
        "--annotate",
        action="store_true",
        help="also each frame with its stress map drawn over the finger (MPa, log "
        "scale), the force arrow (N) and the calibrated force: "
        "<name>_annotated.png, for a video annotated.mp4; and forces.png, the "
        "force against time",
    )
    p.add_argument(
        "--segmentation",
        choices=["auto", "colour", "grey"],
        default="auto",
        help="how the finger is found: auto (its colour learned from the first "
        "frames, or the grey-level threshold of the renders where that finds "
        "the same finger; default), colour (learned), grey (the threshold)",
    )
    p.add_argument(
        "--finger-colour",
        metavar="COLOUR",
        help="the finger's colour: a name (red, orange, yellow, green, cyan, blue, "
        'purple, magenta), a JSON range {"space": "hsv", "lo": [...], '
        '"hi": [...]}, or a saved segmentation (segmentation.json of an '
        "earlier run, ingest.json, calibration.json)",
    )
    p.add_argument(
        "--check",
        nargs="?",
        type=int,
        const=6,
        metavar="N",
        help="check the set-up instead of predicting: N frames (default 6) spread "
        "over the source, each with its mask, the segmentation's confidence "
        "and its validity; check.png in --out (exit code 1 when a frame fails)",
    )
    p.set_defaults(func=_run_predict)


def _invalid(row: dict) -> list[str]:
    """``["NOT VALID: <flags>"]`` for a flagged row (:mod:`finray.validity`), else []."""
    return (
        [f"NOT VALID: {row['valid'].replace('+', ', ')}"] if row.get("valid", "ok") != "ok" else []
    )


def _force_line(row: dict) -> str:
    """``<frame>\t[t 1.2345 s\t]fx 1.2345 N\tfy -0.2345 N[\tcontact 34.12 mm][\tNOT VALID:
    <flags>]`` of a predicted row."""
    t = [f"t {row['t_s']:.4f} s"] if row.get("t_s") is not None else []
    c = [f"contact {row['contact_mm']:.2f} mm"] if "contact_mm" in row else []
    return "\t".join(
        [
            row["frame"],
            *t,
            *(f"{k.removesuffix('_N')} {v:.4f} N" for k, v in row.items() if k.endswith("_N")),
            *c,
            *_invalid(row),
        ]
    )


def _calibrated_line(row: dict) -> str:
    """``<frame>\tfx 1.2345 N\tcalibrated 1.30 N [1.10, 1.50] 90 %[\tNOT VALID: <flags>]``."""
    return "\t".join(
        [
            f"{row['frame']}\tfx {row['fx_N']:.4f} N\tcalibrated {row['force_N']:.4f} N "
            f"[{row['lo_N']:.4f}, {row['hi_N']:.4f}] {100 * row['level']:.0f} %",
            *_invalid(row),
        ]
    )


def _run_predict(args) -> int:
    _positive(args, "threads")
    with _staged(args) as staged:
        args.into = staged.path  # where the run writes; --out once complete
        return _predict(args)


def _predict(args) -> int:
    from .predict import predict_files

    cal = None
    if args.calibration is not None:
        from .sim2real.calibration import read_calibration

        cal = read_calibration(args.calibration)
        cal_model = args.calibration.parent / cal.get("model", "")
        if args.model is None:
            args.model = cal_model
        elif args.model.resolve() != cal_model.resolve():
            raise UsageError(
                f"--model {args.model} is not the model {args.calibration} "
                f"calibrates ({cal_model}): leave --model out"
            )
    if args.model is None:
        raise UsageError("give --model (or --calibration)")
    if (args.annotate or args.show) and args.force_only:
        raise UsageError("--annotate and --show draw the stress map: leave out --force-only")
    # held: --show's line and the notes, said with the first frame's line (a run refused
    # at a door says one line)
    window, held = None, []

    def say(msg: str | None = None, err: bool = True) -> None:
        """A line (stderr, or stdout), after the held one."""
        while held:
            print(held.pop(0), file=sys.stderr, flush=True)
        if msg is not None:
            print(msg, file=sys.stderr if err else sys.stdout, flush=True)

    if args.show:
        from .annotate import Window

        args.annotate = True
        try:
            window = Window(f"finray predict {args.source}")
        except RuntimeError as exc:
            held.append(f"finray predict: --show: {exc}; writing the annotated files only")
    if args.check is not None:
        code = _check(args, cal)
        say()
        return code
    line = _calibrated_line if cal is not None else _force_line
    out = predict_files(
        args.model,
        args.source,
        args.into,
        args.threads,
        args.backend,
        args.force_only,
        calibration=cal,
        on_frame=lambda r: say(line(r), err=False),
        on_skip=lambda name, msg: say(f"finray predict: skipped {msg}"),
        device=args.device,
        annotate=args.annotate,
        maps=args.maps,
        on_annotated=window.show if window else None,
        segmentation=args.segmentation,
        finger_colour=args.finger_colour,
        on_note=lambda msg: held.append(f"finray predict: note: {msg}"),
    )
    say()
    if window is not None:
        window.close()
    if out["flagged"]:
        from .validity import FLAGS

        n_bad = sum(r["valid"] != "ok" for r in out["rows"])
        print(
            f"finray predict: warning: {n_bad} of {len(out['rows'])} frames flagged, not to be "
            "trusted (column valid of forces.csv): "
            + "; ".join(f"{k} {v} ({FLAGS.get(k, k)})" for k, v in out["flagged"].items()),
            file=sys.stderr,
        )
    if "received" in out:  # a live source: what it sent, what could be kept up with
        print(
            f"finray predict: {len(out['rows'])} frames predicted of {out['received']} received "
            f"({out['dropped']} dropped while the network was busy"
            + ("; stopped by Ctrl-C" if out["interrupted"] else "; the stream ended")
            + f"), forces in {Path(args.out) / 'forces.csv'}",
            file=sys.stderr,
        )
    if out["skipped"]:
        n = len(out["rows"]) + len(out["skipped"])
        print(
            f"finray predict: {len(out['skipped'])} of {n} frames skipped; the other "
            f"{len(out['rows'])} are in {Path(args.out) / 'forces.csv'}",
            file=sys.stderr,
        )
        return 1
    return 0


def _check(args, cal) -> int:
    """``finray predict --check``: the set-up's report (:func:`finray.predict.check_setup`)."""
    from .predict import check_setup

    rep = check_setup(
        args.model,
        args.source,
        args.into,
        args.check,
        args.segmentation,
        args.finger_colour,
        cal,
        args.backend,
        args.device,
    )
    print(f"finger found by {rep['finder']}")
    for note in rep["notes"]:
        print(f"note: {note}")
    for r in rep["frames"]:
        print(
            f"{r['frame']}\tmask {100 * r['mask_frac']:.1f} % of the frame\tconfidence "
            f"{r['confidence']:.2f}\tfx {r['fx_N']:.3f} N\t{r['valid']}"
        )
    n_ok = sum(r["valid"] == "ok" for r in rep["frames"])
    print(
        f"set-up {'OK' if rep['ok'] else 'NOT OK'}: {n_ok} of {len(rep['frames'])} frames "
        f"valid; masks in {Path(args.out) / 'check.png'}"
    )
    return 0 if rep["ok"] else 1


INGEST_HELP = """\
Ingest a lab take (one folder: a video or frames/ + frames.csv, the sensor's
forces.csv, take.json; see docs/guide/recordings.md) into a dataset shard.
The finger is colour-segmented (take.json's finger_colour, or learned from the
first frames), cropped in the same base-anchored window as predict, and the
sensor clock is aligned to the camera's by cross-correlating the push force with
the finger's deformation. Writes shard.npz (force labels from the sensor, no stress
map), frames.csv, sync.json (offset_s, uncertainty_s), ingest.json and qa.png.
Progress on stdout; bad input stops with one line on stderr (exit code 2).

example:
  finray ingest lab/rhombus_h20 --out results/ingest/rhombus_h20
"""


def _ingest_parser(sub) -> None:
    p = sub.add_parser(
        "ingest",
        help="lab take (video + force log) -> dataset shard",
        description=INGEST_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("take", type=Path, help="take folder (video or frames/, forces.csv, take.json)")
    p.add_argument("--out", type=Path, required=True, help="output directory")
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="YAML config whose dataset sizes and crop (mm) and finger base width "
        "(mm) to use (default: config/config.yaml of the source tree)",
    )
    _add_overwrite(p)
    p.set_defaults(func=_run_ingest)


def _ingest_params(raw: dict):
    """Ingest's settings from a config mapping: the dataset's sizes and the input window
    of its ``finger`` and ``dataset`` sections (never ``lab:``)."""
    from .config import section_params
    from .dataset.params import DatasetParams
    from .dataset.window import InputWindow
    from .recording import IngestParams

    d = section_params("dataset", DatasetParams.from_config, raw.get("dataset"))
    return IngestParams(
        sizes=d.sizes, window=InputWindow.from_sections(raw.get("finger"), raw.get("dataset"))
    )


def _run_ingest(args) -> int:
    from .recording import ingest

    params = _ingest_params(_raw_config(args.config))
    with _staged(args) as st:
        ingest(args.take, st.path, params, log=lambda m: print(st.shown(m), flush=True))
    return 0


CALIBRATE_HELP = """\
Calibrate a simulation-trained model to a rig from its takes (each a folder as
finray ingest reads). The takes are ingested, the rig gets its own ensemble of
force heads on the model's frozen encoder (fitted on every take's frames), and
the sensor model F_sensor = g F_pred + b + e is sampled with emcee on
cross-fitted predictions (see finray.sim2real.calibration). A printed finger's
force relaxes in a hold and softens in later cycles while its image stays: F_pred
is read through that law (two relaxation terms and a softening), fitted on the
takes' force logs at the frames' times, so give takes that hold and cycle.
Writes calibration.json
(posterior samples, summary, convergence diagnostics), the adapted model
<out>.model.ts that finray predict --calibration runs (on frames segmented by the
takes' finger colour), <out>.corner.png and the ingested takes under
<out>.ingest/. Settings: the config's evaluate.sim2real.

example:
  finray calibrate lab/cylinder_h20 lab/cylinder_h30 --model results/train/camera/model.pt \\
      --out rig/calibration.json
  finray predict --calibration rig/calibration.json video.mp4 --out rig/pred --force-only
"""


def _calibrate_parser(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="fit a model and its force calibration to a rig's takes",
        description=CALIBRATE_HELP,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("takes", type=Path, nargs="+", help="take folders (as finray ingest reads)")
    p.add_argument(
        "--model",
        type=Path,
        required=True,
        help="the simulation-trained model: model.pt (or its model.ts, beside it)",
    )
    p.add_argument("--out", type=Path, required=True, help="calibration.json to write")
    p.add_argument(
        "--no-context",
        type=Path,
        default=None,
        help="the same model's no-context fit (results/evaluate/sim2real/no_context.pt): "
        "where the config's evaluate.sim2real.sim_replay_frames is above 0 (it is 0 "
        "by default), that many of its simulated frames are fitted beside the takes",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="YAML config (dataset crop, finger base width, evaluate.sim2real; "
        "default: config/config.yaml of the source tree)",
    )
    _add_overwrite(p, "an earlier calibration at --out (and its <out>.* files)")
    p.set_defaults(func=_run_calibrate)


def _run_calibrate(args) -> int:
    from .sim2real.calibration import calibrate_takes
    from .sim2real.experiment import Sim2RealConfig

    from .config import section_params

    raw = _raw_config(args.config)
    c = section_params(
        "evaluate.sim2real",
        Sim2RealConfig.from_params,
        (raw.get("evaluate") or {}).get("sim2real") or {},
    )
    if args.no_context is not None and not args.no_context.is_file():
        raise UsageError(f"--no-context: no file at {args.no_context}")
    if args.no_context is not None and not c.sim_replay_frames:
        print(
            "--no-context: evaluate.sim2real.sim_replay_frames is 0, so the heads are fitted "
            "on the takes alone",
            flush=True,
        )
    if args.out.name in ("", ".", ".."):  # a folder: no file name to write (was a ValueError)
        raise UsageError(f"--out {str(args.out)!r} is a folder: give a file, calibration.json")
    # calibration.json and its companions <stem>.model.ts(.json), .corner.png, .ingest/
    staged = _staged(args, kind="file", siblings=(f"{args.out.with_suffix('').name}.",))
    with staged:
        cal = calibrate_takes(
            args.takes,
            args.model,
            staged.path,
            _ingest_params(raw),
            c.heads,
            c.folds,
            c.priors,
            c.sampler,
            c.level,
            log=lambda m: print(staged.shown(m), flush=True),
            no_context=args.no_context,
            replay_frames=c.sim_replay_frames,
        )
    sm, dg = cal["summary"], cal["diagnostics"]
    times = cal["priors"]["relax_times_s"]
    named = ("gain", "offset_N", "sigma_N", "rho", "kappa", "nu", "relax_fast", "relax_slow")
    for k in (*named, "softening"):
        fixed = cal.get("fixed", {})
        if k in fixed:  # held (prior sd 0): the heads are fitted to the sensor
            print(f"{k}: {fixed[k]:.4g} (fixed)")
        else:
            print(f"{k}: {sm[k]['median']:.4g} (95 % {sm[k]['q2.5']:.4g} to {sm[k]['q97.5']:.4g})")
    if cal.get("history_base_N") is not None:
        print(
            f"the print's time dependence: relax_fast and relax_slow of the force relaxing "
            f"in {times[0]:g} and {times[1]:g} s, softening below a take's largest force so "
            "far (finray predict --calibration applies it over the frames' times)"
        )
    print(
        f"chain: {dg['steps']} steps x {dg['walkers']} walkers, {dg['steps_over_tau_min']:.0f} "
        f"autocorrelation times, acceptance {dg['acceptance_fraction']['mean']:.2f}"
        f"{'' if dg['ok'] else ' -- NOT CONVERGED: see diagnostics'}"
    )
    print(f"wrote {args.out} and {cal['model']}")
    return 0 if dg["ok"] else 1


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="finray",
        description="Force and stress of a soft Fin Ray finger from camera images, "
        "learned from finite-element simulations. Units: mm, N, MPa, deg.",
    )
    parser.add_argument("--version", action="version", version=f"finray {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", required=True)
    _geometry_parser(sub)
    _simulate_parser(sub)
    _predict_parser(sub)
    _ingest_parser(sub)
    _calibrate_parser(sub)
    for p in sub.choices.values():  # every option that takes one value: once
        for action in p._actions:
            if type(action) is argparse._StoreAction and action.option_strings:
                action.__class__ = _Once
    return parser


def _interrupted(command: str, signum: int, committed: list) -> int:
    """The line of a run stopped by SIGINT (Ctrl-C) or SIGTERM; its exit code (128 + the
    signal's number: 130, 143). The outputs are complete or absent
    (:mod:`finray.outputs`); ``committed``: the ones moved into place before it came."""
    import signal

    what = "terminated" if signum == signal.SIGTERM else "interrupted"
    where = f"the outputs were complete: {', '.join(map(str, committed))}"
    print(
        f"finray {command}: {what}; {where if committed else 'nothing written'}",
        file=sys.stderr,
    )
    return 128 + signum


def main(argv: list[str] | None = None) -> int:
    """Run a subcommand: 0 done, 1 failed part way (solver, skipped frames), 2 bad input
    (one line on stderr that names the subcommand); 130 and 143 stopped by SIGINT
    (Ctrl-C) and SIGTERM, with the outputs complete or none (:mod:`finray.outputs`)."""
    args = build_parser().parse_args(argv)
    from .outputs import COMMITTED, Terminated, catch_signals

    n_committed = len(COMMITTED)

    def stop(signum: int):  # the command's process: ends where the signal comes
        code = _interrupted(args.command, signum, COMMITTED[n_committed:])
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)

    with catch_signals(stop if argv is None else None) as caught:
        try:
            code = _main(args)
        except KeyboardInterrupt as exc:
            signum = 15 if isinstance(exc, Terminated) else 2
            code = _interrupted(args.command, signum, COMMITTED[n_committed:])
        except BaseException:
            if caught.signum is None:
                raise
            # an error that the signal caused (an import cut short: ImportError)
            code = _interrupted(args.command, caught.signum, COMMITTED[n_committed:])
        if argv is None:  # the command's process: the work is done, its code stands
            import signal

            for s in (signal.SIGINT, signal.SIGTERM):
                signal.signal(s, signal.SIG_IGN)
    return code


def _main(args) -> int:
    """:func:`main` once the signals are caught."""
    try:
        _check_numbers(args)
        return args.func(args)
    except (ConfigError, GeometryError) as exc:
        print(f"finray {args.command}: config error: {exc}", file=sys.stderr)
        return 2
    except BadInput as exc:  # finray.errors: every check at the door
        print(f"finray {args.command}: {exc}", file=sys.stderr)
        return 2
    except FinrayError as exc:  # failed part way (an FEA scene: SimulationError)
        print(f"finray {args.command}: {exc}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
