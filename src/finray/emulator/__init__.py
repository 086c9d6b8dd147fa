"""The emulated lab rig: writes takes in the recording format (:mod:`finray.recording.take`).

No public recording of a printed TPU Fin Ray finger with synchronised forces exists, so
this package stands in for the paper's rig (section 5.3): an "as-built" finger
simulated by the FEA stage, the gripper's motion, a perspective colour camera like an
Intel RealSense D435i's colour stream (:mod:`~finray.emulator.camera`, :mod:`~finray.emulator.studio`)
and a six-axis force sensor on its own clock (:mod:`~finray.emulator.sensor`). Every choice is
a ``lab:`` config key with its reason. Beside each take the emulator writes the truth
(masks, force, clock offset) under ``truth/`` for QA only: :mod:`finray.recording`
never imports this package and never reads ``truth/``.

- :mod:`~finray.emulator.motion` -- the gripper's push against time
- :mod:`~finray.emulator.sensor` -- the force sensor's log (noise, offset, gain, clock)
- :mod:`~finray.emulator.camera` -- pinhole camera, lens distortion, sensor noise, video
- :mod:`~finray.emulator.studio` -- the studio: the lit 3D set (pyvista) and its true finger mask
- :mod:`~finray.emulator.emulate` -- one take from an FEA result
"""
