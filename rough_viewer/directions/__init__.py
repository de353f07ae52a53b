"""Roughness by direction of one surface (docs/directions.md): the profile sets
(:mod:`rough_viewer.profiles`) and the TIN parameters (:mod:`rough_viewer.tin`) at a
step of azimuths in one face frame."""
