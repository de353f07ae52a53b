"""``--crop``, ``--crop-mode`` and ``--crop-file``: run a command on the points inside
(or outside) an axis-aligned box, shared by ``compute``, ``report`` and ``zones``.

``--crop xmin,ymin,zmin,xmax,ymax,zmax`` is in the input's unit (``--units``, else
the CRS's), in the file's frame; ``--crop-mode keep|remove`` keeps the points inside
(default) or removes them; ``--crop-file VIEW.json`` takes the crop saved in a view
(:mod:`rough_viewer.report.view`, metres). The crop is applied right after reading;
the note it leaves on the cloud's warnings is printed and goes into the outputs
that record warnings (SUMMARY.json, the report).
"""

from __future__ import annotations

import argparse
import sys
from typing import TYPE_CHECKING

from rough_viewer.vocabulary import UNIT_LABELS, UNIT_METRES, InputError

if TYPE_CHECKING:
    from rough_viewer.io.cloud import PointCloud
    from rough_viewer.io.crop import CropBox, Cropped


def add_crop_options(parser: argparse.ArgumentParser) -> None:
    """Add ``--crop``, ``--crop-mode`` and ``--crop-file``."""
    parser.add_argument(
        "--crop", metavar="XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX",
        help="use only the points inside this axis-aligned box (in --units, the file's frame)")
    parser.add_argument(
        "--crop-mode", choices=("keep", "remove"), default=None,
        help="with --crop: keep the points inside the box (default) or remove them")
    parser.add_argument(
        "--crop-file", metavar="VIEW.json",
        help="use the crop saved in a view file (rough-viewer serve's Export folder)")


def adopt_view_units(args: argparse.Namespace) -> None:
    """With ``--crop-file``, read the input in the unit the view was saved in: a view's
    crop is in metres of the cloud as the app read it, so an STL in millimetres saved
    with ``--units mm`` kept no point when read as metres. ``--units`` left out takes
    the view's; one that contradicts it is refused. Checked before any read."""
    view_file = getattr(args, "crop_file", None)
    if not view_file or getattr(args, "crop", None):
        return
    from rough_viewer.report.view import load_view

    saved = load_view(view_file, check=False).view.units
    given = getattr(args, "units", None)
    if given is None:
        args.units = saved
    elif given != saved:
        raise InputError(f"view file {view_file} was saved with the input in {saved}, but "
                         f"--units {given} was given: leave --units out or give --units "
                         f"{saved}")


def crop_from_args(args: argparse.Namespace, unit: str) -> CropBox | None:
    """The crop the options ask for, in metres, or None; checked before any work."""
    from rough_viewer.io.crop import CropBox

    text, view_file = getattr(args, "crop", None), getattr(args, "crop_file", None)
    mode = getattr(args, "crop_mode", None)
    if text and view_file:
        raise InputError("give --crop or --crop-file, not both")
    if mode and not text:
        raise InputError("--crop-mode goes with --crop (a view file's crop has its own mode)")
    if text:
        from rough_viewer.io.crop import parse_box

        lo, hi = parse_box(text)
        try:
            box = CropBox(lo, hi, mode or "keep")
        except InputError as exc:
            raise InputError(f"--crop: {exc}") from None
        return box.scaled(UNIT_METRES[unit])
    if view_file:
        from rough_viewer.report.view import load_view

        view = load_view(view_file, check=False).view
        if view.crop is None:
            raise InputError(f"view file {view_file} holds no crop")
        return view.crop
    return None


def apply_crop(cloud: PointCloud, box: CropBox | None, unit: str) -> tuple[PointCloud, Cropped | None]:
    """The cloud cropped to ``box`` (unchanged when None), a note on stderr and on the
    cloud's warnings, and the crop (for LAS copies of the kept points)."""
    from rough_viewer.io.crop import crop_cloud

    if box is None:
        return cloud, None
    cropped = crop_cloud(cloud, box)
    note = (f"{box.describe(UNIT_METRES[unit], UNIT_LABELS[unit])}: {cropped.kept:,} of "
            f"{cropped.total:,} points kept")
    print(f"rough-viewer: {note}", file=sys.stderr)
    return cropped.cloud.with_warnings(note), cropped


def refuse_with_chunks(args: argparse.Namespace) -> None:
    """A crop needs the points in memory: refuse it with ``--memory`` / ``--scheduler``."""
    if getattr(args, "crop", None) or getattr(args, "crop_file", None):
        raise InputError("--crop and --crop-file need the points in memory; run without "
                         "--memory and --scheduler")
