"""finray: contact force and stress of a soft Fin Ray finger from camera images,
learned from finite-element simulations. Units: mm, N, MPa, degrees."""

__version__ = "0.1.0"
