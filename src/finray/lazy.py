"""Names of a package that load their module on first use (PEP 562): planning the DAG
or reading shards does not load torch, the rasterisers or VTK."""

from __future__ import annotations

import importlib


def lazy_exports(package: str, homes: dict[str, tuple[str, ...]], module_globals: dict):
    """``(__getattr__, __dir__, __all__)`` of ``package`` whose names ``homes`` lists by
    submodule (``{"loop": ("train", ...)}``); private names stay out of ``__all__``."""
    where = {name: module for module, names in homes.items() for name in names}

    def __getattr__(name: str):
        if name not in where:
            raise AttributeError(f"module {package!r} has no attribute {name!r}")
        return getattr(importlib.import_module(f".{where[name]}", package), name)

    def __dir__():
        return sorted(set(module_globals) | set(where))

    return __getattr__, __dir__, sorted(n for n in where if not n.startswith("_"))
