"""Measurements of a state: the angle of repose of a pile, confidence intervals over seeds."""
