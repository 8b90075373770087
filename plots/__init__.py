"""Figures, claims and the report drawn from a results folder: `python3 -m plots.report`."""
