"""COPC (Cloud Optimized Point Cloud, copc.io, version 1.0) files: a LAZ 1.4 file
whose variable-size chunks are the nodes of an octree, listed by a hierarchy EVLR.

- :mod:`.octree`: the cube, integer voxel coordinates, node keys and the
  level-of-detail selection (pure functions on numpy arrays);
- :mod:`.writer`: the file layout (header, COPC info VLR, laszip VLR, one LAZ chunk
  per node, chunk table, hierarchy EVLR);
- :mod:`.index`: the out-of-core build from LAS/LAZ inputs (``rough-viewer index``).
"""
