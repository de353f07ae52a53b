"""The clouds a lesson's scene names: a demo (or a face part of an outcrop demo, cut
out with the demo's truth) or the 2012 board at a rotation.

The last :data:`KEPT` clouds are kept (one process-wide cache): thirty tabs on one
step read its cloud once and show the same points, not thirty copies.
"""

from __future__ import annotations

import functools
import threading

from rough_viewer.io import PointCloud
from rough_viewer.lessons import PARTS, Scene
from rough_viewer.vocabulary import InputError

#: Scene clouds kept in memory (a board scan is about 10 MB, the small outcrop 5 MB).
KEPT = 6
#: One read at a time: tabs that ask at once (a classroom's workers) get one cloud.
_READING = threading.Lock()


def scene_cloud(scene: Scene) -> PointCloud:
    """The points of ``scene``'s cloud (metres; the same object for the same cloud
    while it is among the last :data:`KEPT`). InputError for a scene that keeps the
    cloud shown, or a part the demo does not have."""
    if scene.cloud_key is None:
        raise InputError("this scene keeps the cloud shown")
    board = scene.cloud == "board"
    with _READING:
        return _read(scene.cloud, "" if board else scene.part,
                     float(scene.alpha) if board else 0.0, float(scene.beta) if board else 0.0)


@functools.lru_cache(maxsize=KEPT)
def _read(name: str, part: str, alpha: float, beta: float) -> PointCloud:
    from rough_viewer.synthetic import demos

    if name == "board":
        return demos.load_demo("board", alpha_deg=alpha, beta_deg=beta)
    if not part:
        return demos.load_demo(name)
    cloud, truth = demos.load_demo_with_truth(name)
    if truth.face is None or part not in truth.face_names:
        raise InputError(f"the {name} demo has no part {part!r}; "
                         f"its parts: {', '.join(truth.face_names) or 'none'}")
    cut = cloud.subset(truth.face == truth.face_names.index(part))
    if cut.n < 3:
        raise InputError(f"the {part} of the {name} demo has no points")
    return cut


__all__ = ["PARTS", "scene_cloud"]
