"""2D plane-strain finite-element stage: a Fin Ray finger pushed by an object.

Units throughout: lengths mm, forces N (per mm of out-of-plane thickness unless a
name says otherwise), stresses and moduli MPa, energies N mm per mm of thickness.

Modules
-------
material   compressible neo-Hookean law (energy, first Piola, tangent, Cauchy,
           von Mises); the constants and their sources are the config's materials.
assembly   quadratic (6-node) and linear triangles, fused numba assembly into a
           CSR matrix whose pattern and scatter index are computed once.
contact    incremental potential contact (ipctk): barrier, lagged friction, CCD.
solver     Newton with CCD-bounded backtracking line search, sparse Cholesky with
           reused symbolic factorisation, adaptive load stepping.
simulate   the pure-compute entry point :func:`simulate` for the Fin Ray scene.
"""
from .material import NeoHookean
from .simulate import (DeformableObject, RigidObject, SimulationError, SimulationOptions,
                       SimulationResult, simulate)

__all__ = ["NeoHookean", "RigidObject", "DeformableObject",
           "SimulationOptions", "SimulationResult", "SimulationError", "simulate"]
