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
linear     sparse Cholesky (four backends) with reused symbolic analysis.
problem    the discrete problem of a load step (:class:`~finray.fea.problem.Model`).
newton     Newton with a CCD-bounded backtracking line search.
stepping   adaptive load stepping with a predictor and lagged friction.
errors     the stage's errors (:class:`SimulationError`).
simulate   the pure-compute entry point :func:`simulate` for the Fin Ray scene.
scene      the stage's entry point :func:`~finray.fea.scene.run_scene`: one scene
           from the config to its files.
"""

from .material import NeoHookean
from ..errors import SimulationError
from .simulate import DeformableObject, RigidObject, SimulationOptions, SimulationResult, simulate

__all__ = [
    "NeoHookean",
    "RigidObject",
    "DeformableObject",
    "SimulationOptions",
    "SimulationResult",
    "SimulationError",
    "simulate",
]
