"""The printed finger as built: the nominal model changed the way a print differs.

``lab.as_built``: walls and ribs ``thickness_delta_mm`` thicker, the finger's material
``youngs_modulus_scale`` times as stiff, the rig's friction; the object starts
``lab.motion.gap_mm`` off the finger and travels ``lab.motion.push_mm``; where
``viscoelastic``, the print's force relaxes and softens over the take
(``relax_fractions``, ``relax_times_s``, ``softening``: :mod:`finray.viscoelastic`).
"""

from __future__ import annotations

import copy


def as_built_finger(finger: dict, as_built: dict) -> dict:
    """The config's ``finger`` section of the printed finger."""
    out = copy.deepcopy(finger)
    d = float(as_built["thickness_delta_mm"])
    out["wall_thickness_mm"] = finger["wall_thickness_mm"] + d
    out["ribs"]["thickness_mm"] = finger["ribs"]["thickness_mm"] + d
    return out


def as_built_material(material: dict, as_built: dict) -> dict:
    """The finger material's constants as printed (``source`` dropped)."""
    out = {k: v for k, v in material.items() if k != "source"}
    out["youngs_modulus_MPa"] = material["youngs_modulus_MPa"] * float(
        as_built["youngs_modulus_scale"]
    )
    return out


def as_built_fea(fea: dict, as_built: dict, motion: dict) -> dict:
    """The config's ``fea`` section for the rig: its friction and push."""
    out = copy.deepcopy(fea)
    out["friction"] = float(as_built["friction"])
    out["push_mm"] = float(motion["push_mm"])
    return out


def as_built_print_law(as_built: dict) -> dict:
    """The print's time dependence as :meth:`finray.viscoelastic.PrintLaw.from_config`
    reads it: ``{}`` (elastic) where ``viscoelastic`` is off."""
    if not as_built.get("viscoelastic", False):
        return {}
    return {
        "fractions": [float(v) for v in as_built["relax_fractions"]],
        "times_s": [float(v) for v in as_built["relax_times_s"]],
        "softening": float(as_built["softening"]),
    }
