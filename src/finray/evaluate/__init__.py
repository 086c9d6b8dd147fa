"""Evaluation of predictions against the FEA ground truth."""
