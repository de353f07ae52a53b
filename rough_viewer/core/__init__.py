"""Compute core: pure functions on numpy arrays. No viser, no plotly, no printing."""
