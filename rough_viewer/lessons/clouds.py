"""The clouds a lesson's scene names: a demo (or a face part of an outcrop demo, cut
out with the demo's truth) or the 2012 board at a rotation."""

from __future__ import annotations

from rough_viewer.io import PointCloud
from rough_viewer.lessons import PARTS, Scene
from rough_viewer.vocabulary import InputError


def scene_cloud(scene: Scene) -> PointCloud:
    """The points of ``scene``'s cloud (metres). InputError for a scene that keeps
    the cloud shown, or a part the demo does not have."""
    from rough_viewer.synthetic import demos

    if scene.cloud_key is None:
        raise InputError("this scene keeps the cloud shown")
    if scene.cloud == "board":
        return demos.load_demo("board", alpha_deg=scene.alpha, beta_deg=scene.beta)
    if not scene.part:
        return demos.load_demo(scene.cloud)
    cloud, truth = demos.load_demo_with_truth(scene.cloud)
    if truth.face is None or scene.part not in truth.face_names:
        raise InputError(f"the {scene.cloud} demo has no part {scene.part!r}; "
                         f"its parts: {', '.join(truth.face_names) or 'none'}")
    part = cloud.subset(truth.face == truth.face_names.index(scene.part))
    if part.n < 3:
        raise InputError(f"the {scene.part} of the {scene.cloud} demo has no points")
    return part


__all__ = ["PARTS", "scene_cloud"]
