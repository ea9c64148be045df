"""Visualisation: matplotlib figures of runs (matplotlib is imported only by these modules)."""
