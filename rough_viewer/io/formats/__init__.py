"""The file formats, one module each: LAS/LAZ (:mod:`.las`, writing with per-point
fields :mod:`.las_out`), E57, PLY, STL, text and NumPy, DEM rasters, meshes, the CRS of
a file and the per-point fields written beside the points."""
