"""Simulation versus recordings: recordings, the simulator and the candidate physics that
explain a residual (METHODS section 6)."""
