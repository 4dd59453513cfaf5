"""Joint-angle constraints: the ConstraintSet, Eq. 12 extraction, analysis, plots."""
