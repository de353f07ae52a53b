"""The scanner behind a cloud (docs/scanner.md): where the scanners stood
(:mod:`.positions`), the geometry of each cell seen from them (:mod:`.geometry`: scans,
range, incidence, density) and the per-cell trust built on the bias model
(:mod:`.trust`)."""
