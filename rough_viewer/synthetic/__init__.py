"""Synthetic scans used by the demos and the tests (pure numpy).

- :mod:`.board`: the 2012 paper's hemisphere board, ray-cast for any rotation,
  with its closed-form theoretical roughness.
- :mod:`.outcrop`: a vertical basalt exposure like the 2011 paper's Box Canyon,
  with fractures, a rubbly flow margin, a bend in the face and scanner effects,
  plus the ground truth of which points lie in fractures or rubble.

``python -m rough_viewer.synthetic`` regenerates the bundled demo files.
"""

from rough_viewer.synthetic.board import (
    PAPER_ROTATIONS_DEG,
    PAPER_THEORETICAL_ROUGHNESS_M,
    BoardScan,
    HemisphereBoard,
    board_rotation,
    board_scan,
    board_theoretical_roughness,
    hemisphere_board,
    hemisphere_roughness,
)

__all__ = [
    "PAPER_ROTATIONS_DEG",
    "PAPER_THEORETICAL_ROUGHNESS_M",
    "BoardScan",
    "HemisphereBoard",
    "board_rotation",
    "board_scan",
    "board_theoretical_roughness",
    "hemisphere_board",
    "hemisphere_roughness",
]
