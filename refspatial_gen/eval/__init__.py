"""Evaluation of model predictions on a refspatial-gen dataset (`refspatial-gen eval`, docs/eval.md)."""
