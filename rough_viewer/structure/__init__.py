"""Structural geology from the grid: fracture zones, joint sets, joints, the
exposure face and the roughness of each set.

Built on :mod:`rough_viewer.grid` (the one grid, its planes and orientations) and,
for the roughness of a set along its dip and strike, on :mod:`rough_viewer.profiles`
and :mod:`rough_viewer.tin`; none of them imports this package.

- :mod:`.zones`: fracture zones (connected cells above the threshold) and their traces.
- :mod:`.sets`: joint sets from the cells' poles, their planes (patches) and spacing.
- :mod:`.joints`: patches that are one discontinuity grouped into joints; spacing,
  persistence and the rock-mass figures.
- :mod:`.face`: whether a set lies parallel to the exposure face.
- :mod:`.set_roughness`: the roughness of each set at the cell and joint scales.
"""
