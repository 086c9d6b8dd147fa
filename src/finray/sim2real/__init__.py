"""Sim-to-real: from a network trained on renders to a rig's camera and force sensor.

Modules
-------
adapt        a rig's ensemble of force heads re-fitted on a trained model's encoder
             (:func:`~finray.sim2real.adapt.fit_heads`), exported for ``finray predict``
calibration  the sensor model (gain, offset, noise) sampled with emcee from a rig's takes;
             per-frame predictive intervals and their coverage
             (:func:`~finray.sim2real.calibration.calibrate_takes`, ``finray calibrate``)
rig_prior    the gain a rig leaves unknown, as a log-normal prior from FEA variants of
             the finger (walls, friction)
experiment   the sim-to-real experiment: adapt and calibrate on 0, 1 or 2 context
             objects' takes, test on the others (``results/evaluate/sim2real/``)
rigs         the experiment over every emulated rig: the table, the figure, the acceptance

``adapt`` and ``calibration`` are at the train stage's rank (``finray predict`` applies a
calibration); ``experiment`` and ``rigs`` at evaluate's (they score and draw). This
``__init__`` imports none of them, so that importing one does not import the others.
"""
