"""Experiment definitions (*.json) and their driver run.py: `python3 -m experiments.run`."""
