"""Plotly figure builders: pure functions from core results to figures.

:mod:`rough_viewer.figures.grid` holds the grid-roughness figures (summary table,
histograms, semivariograms, face-plane maps) used by the report and the app.
"""
