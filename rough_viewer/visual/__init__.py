"""What results look like: the one colour-map module (:mod:`.colormaps`) and the plotly
figure builders, pure functions from results to figures (:mod:`.grid` for grid
roughness, :mod:`.profiles` for profiles, :mod:`.bias` for scanner bias,
:mod:`.app` for the app's colour bar)."""
