"""Saved views in the app: what the app shows as a :class:`~rough_viewer.report.view.View`,
and a view put back on an app.

A view file (:mod:`rough_viewer.report.view`) records the input (path, size, content
hash), the grid, the map, units, threshold, colour settings, open panels, picked
profiles, zone settings and the camera. The features fill it: each that has a part
in saved views (:class:`rough_viewer.app.host.SavedViewPart`) gives the view's fields
it owns (``snapshot()``) and puts them back as a job (``restore(view)``). This
module composes them and knows no feature's fields:

- :func:`view_of`: the view of what an app shows (the Export folder's "Download
  view" and "Save view beside the input"); fields no mounted feature fills keep the
  values of the view the session was opened with;
- :func:`open_view`: ``rough-viewer serve --view VIEW.json`` before any server starts:
  read and validate the (untrusted) view file, find its input, apply the data-folder
  rule, and say whether the input changed or moved (:class:`OpenedView`);
- :func:`apply_view`: on a built app, a :class:`RestoreViewJob` that asks every
  feature to restore its part (the map: controls, colours and camera; profiles;
  zones) and pins the notice.

The data-folder rule (as for ``serve INPUT``): the browser may only ever read files
in the data folder, and a view names its input itself, so a view's input must lie in
the data folder: ``--data-dir``, or by default the folder of the view file. The
bundled demo scans are always allowed, and so is an input outside the data folder
whose content (SHA-256) is the one the view was saved from (a downloaded view sits in
the Downloads folder, never beside the data): it opens with a note, and the data
folder, what a browser may read, stays as it was. An input given on the command line
(``serve INPUT --view VIEW.json``) is the operator's choice and opens as usual; the
view's hash then says whether it is the same file.
"""

from __future__ import annotations

import os
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any, ClassVar

import numpy as np
import viser

from rough_viewer.app.features.map import check_view_for_app
from rough_viewer.app.host import Host, parts
from rough_viewer.app.settings import MapSettings
from rough_viewer.app.worker import Job, Run
from rough_viewer.report.view import (
    Camera,
    InputRef,
    LoadedView,
    View,
    file_sha256,
    load_view,
)
from rough_viewer.vocabulary import InputError


def camera_of(host: Host, client: viser.ClientHandle | None) -> Camera | None:
    """The camera of one browser (or the server's initial camera when None), in the
    file frame (metres)."""
    origin = host.session.shown.loaded.origin
    try:  # a browser's camera is known once it has sent one
        cam = client.camera if client is not None else None
        if cam is not None:
            position, look_at, up = cam.position, cam.look_at, cam.up_direction
            fov = float(cam.fov)
    except (AssertionError, AttributeError):
        cam = None
    if cam is None:
        init = host.scene.initial_camera
        position, look_at = init.position, init.look_at
        up = init.up if init.up is not None else np.array([0.0, 0.0, 1.0])
        fov = float(init.fov)

    def vec(v: Any, shift: np.ndarray | None) -> tuple[float, float, float]:
        a = np.asarray(v, dtype=np.float64).reshape(3)
        if shift is not None:
            a = a + shift
        return float(a[0]), float(a[1]), float(a[2])

    p, t, u = vec(position, origin), vec(look_at, origin), vec(up, None)
    if p == t or not np.all(np.isfinite([*p, *t, *u])) or u == (0.0, 0.0, 0.0):
        return None
    fov_deg = float(np.degrees(fov))
    return Camera(position=p, look_at=t, up=u,
                  fov_deg=fov_deg if 0.0 < fov_deg <= 180.0 else 50.0)


#: Fields of a view that are not any feature's part.
_OWN = ("input", "camera")


def view_of(host: Host, ref: InputRef, *, camera: Camera | None) -> View:
    """The view of what the app shows now, for the input ``ref``: each feature's part
    (:meth:`~rough_viewer.app.host.SavedViewPart.snapshot`), over the view the session
    was opened with for fields no mounted feature fills."""
    base = host.session.view
    values: dict[str, Any] = {}
    if base is not None:
        values = {f.name: getattr(base, f.name) for f in fields(View) if f.name not in _OWN}
    for part in parts(host):
        values.update(part.snapshot())
    return View(input=ref, camera=camera, **values)


def apply_view(host: Host, view: View, *, source: str = "(in memory)", notice: str = "") -> int:
    """Queue putting ``view`` back on a built app (:class:`RestoreViewJob`); ``notice``
    (the input moved or changed) is pinned above the tabs and sent to each browser.

    Raises InputError (naming ``source``) when the app's controls cannot take the
    view's map settings; the app is then unchanged.
    """
    check_view_for_app(view, source)
    return host.submit(RestoreViewJob(view, notice))


@dataclass(frozen=True)
class RestoreViewJob(Job[Host]):
    """Ask every feature for the job that restores its part of ``view``, in mount
    order (a part with a lower ``restore_order`` first: the crop, whose points the
    others run on), and queue them; a part that does not fit is named and left out."""

    view: View = field(compare=False)
    notice: str = ""
    lane: ClassVar[str] = "restore"

    @property
    def title(self) -> str:
        return "restoring the saved view"

    def stages(self, ctx: Host, run: Run) -> Iterator[str]:
        ctx.session.view = self.view
        if self.notice:
            ctx.pin(self.notice)
        failed = []
        # a part may come first (the crop: the others run on the points it keeps)
        for part in sorted(parts(ctx), key=lambda p: getattr(p, "restore_order", 0)):
            try:
                job = part.restore(self.view)
            except InputError as exc:
                failed.append(str(exc))
                continue
            if job is not None:
                ctx.submit(job)
        if failed:
            ctx.show_error(f"saved view: {'; '.join(failed)}",
                           kept="The rest of the view is shown.")
        yield "restore"


# ----------------------------------------------------------------------------- serve --view


@dataclass(frozen=True)
class OpenedView:
    """A view file read for ``serve --view``, its input found and allowed."""

    loaded: LoadedView
    input_path: Path
    """The file to open."""
    data_dir: Path | None
    """The data folder the view implies (None: the one ``serve`` chooses, for an input
    given on the command line)."""
    settings: MapSettings
    notice: str
    """One line when the input moved or changed ("" when it is the same file)."""

    @property
    def view(self) -> View:
        return self.loaded.view


def _is_bundled_demo(path: Path) -> bool:
    try:
        from rough_viewer.synthetic.demos import DEMO_DIR
    except ImportError:
        return False
    try:
        return path.resolve().is_relative_to(Path(DEMO_DIR).resolve())
    except (OSError, RuntimeError):
        return False


def open_view(view_file: str | os.PathLike[str], *, inputs: Sequence[Path] = (),
              data_dir: str | os.PathLike[str] | None = None) -> OpenedView:
    """Read a view file for ``serve --view`` and decide what to open.

    Parameters
    ----------
    view_file
        The view (untrusted: validated by :func:`rough_viewer.report.view.load_view`).
    inputs
        Input files given on the command line (at most one); they replace the view's
        recorded input, whose hash then tells whether they are the same file.
    data_dir
        ``--data-dir``; default the view file's folder. The view's own input must lie
        in it (or be a bundled demo).

    Raises
    ------
    InputError
        One line: the file is not a valid view, its input is missing or outside the
        data folder, or its settings do not fit the app's controls.
    """
    vf = Path(view_file)
    if len(inputs) > 1:
        raise InputError("--view opens one input file; give at most one INPUT with it")
    folder = Path(data_dir) if data_dir is not None else vf.resolve().parent
    loaded = load_view(vf, check=not inputs, data_folder=folder)
    view = loaded.view
    settings = check_view_for_app(view, str(vf))
    if inputs:
        path = Path(inputs[0])
        if not path.is_file():
            raise InputError(f"input file not found: {path}")
        same = path.stat().st_size == view.input.size_bytes and \
            file_sha256(path) == view.input.sha256
        notice = "" if same else (f"{path} is not the file the view was saved from "
                                  f"({view.input.path}: another content); the view's "
                                  "numbers may not match")
        return OpenedView(loaded, path, None, settings, notice)
    check = loaded.input_check
    if check.path is None or check.status == "missing":
        raise InputError(f"view file {vf}: {check.message}")
    if not folder.is_dir():
        raise InputError(f"--data-dir is not a folder: {folder}")
    path = check.path.resolve()
    notice = "" if check.status == "unchanged" else check.message
    if not path.is_relative_to(folder.resolve()) and not _is_bundled_demo(path):
        if check.status not in ("unchanged", "moved"):  # its content is not the view's
            raise InputError(f"view file {vf}: its input {path} lies outside the data folder "
                             f"{folder} and is not the file the view was saved from; pass "
                             "--data-dir with a folder that holds it, or give the input "
                             "file as INPUT")
        # a browser download never sits beside the data: the input the view names opens
        # when its content is the view's (SHA-256), and the data folder stays the view's
        # own, so browsers still read nothing else outside it
        notice = "; ".join(t for t in (notice, (
            f"the view's input {path} lies outside the data folder {folder}: opened because "
            "its content is the view's; files a browser loads stay in the data folder "
            "(--data-dir)")) if t)
    return OpenedView(loaded, path, folder, settings, notice)
