"""Experiments: conditions x seeds of training runs (compare) and their figures and tables (report)."""
