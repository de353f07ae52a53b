"""The File tab: load a file from the data folder, or upload one.

"Load file" and an upload each queue a load (:meth:`rough_viewer.app.host.Host.load`;
a newer load replaces a pending one; a control change merges into it). Files are read
in the tab's unit (``auto``: the CRS's unit of a LAS file, else metres), within the
data folder only (:class:`rough_viewer.app.files.DataFolder`), after a memory check
(:func:`rough_viewer.app.files.read_cloud`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import viser

from rough_viewer.app.binding import Binding
from rough_viewer.app.files import UploadedFile, read_cloud, read_mesh
from rough_viewer.app.host import Host
from rough_viewer.app.worker import Run
from rough_viewer.io import PointCloud
from rough_viewer.memory import format_bytes
from rough_viewer.vocabulary import UNITS, Unit

L_PATH = "File path"
L_UNITS = "Units"
L_LOAD = "Load file"
L_UPLOAD = "Upload file"
#: The unit choice: "auto" = the CRS's unit of a LAS file, else metres.
UNIT_OPTIONS: tuple[str, ...] = ("auto", *UNITS)


def unit_of(choice: str) -> Unit | None:
    """The unit of a dropdown entry (None: ``auto``)."""
    return next((u for u in UNITS if u == choice), None)


@dataclass(frozen=True)
class TypedPath:
    """A path as typed in the File tab (resolved in the data folder when read)."""

    typed: str
    units: Unit | None

    @property
    def title(self) -> str:
        return self.typed or "a file"

    def read(self, host: Host, run: Run) -> PointCloud:
        path = host.options.data.resolve(self.typed)
        return read_cloud(path, self.typed.strip(), units=self.units, progress=run.progress(),
                          max_points=host.options.max_points, memory=host.options.memory)

    def release(self) -> None:
        pass


@dataclass(frozen=True)
class Upload:
    """A finished upload (deleted once read, or when the load is dropped)."""

    upload: UploadedFile
    units: Unit | None

    @property
    def title(self) -> str:
        return self.upload.name

    def read(self, host: Host, run: Run) -> PointCloud:
        cloud = read_cloud(self.upload.path, self.upload.name, cache=False, units=self.units,
                           progress=run.progress(), max_points=host.options.max_points,
                           memory=host.options.memory)
        # an STL or PLY mesh keeps its own triangles, as serve FILE.stl does (the
        # file is deleted once read)
        unit = next((u for u in UNITS if u == cloud.source_unit), None)
        mesh = read_mesh(self.upload.path, self.upload.name, units=unit)
        self.upload.delete()
        cloud = replace(cloud, source=self.upload.name)
        host.session.uploaded_mesh = None if mesh is None else (cloud, mesh)
        return cloud

    def release(self) -> None:
        self.upload.delete()


@dataclass(eq=False)
class FileFeature:
    """The File tab's controls."""

    host: Host
    path: viser.GuiTextHandle
    units: viser.GuiDropdownHandle[str]
    load: viser.GuiButtonHandle
    upload: viser.GuiUploadButtonHandle
    binding: Binding

    def load_path(self, typed: str) -> int:
        """Queue loading ``typed`` (a path in the data folder) in the tab's unit."""
        return self.host.load(TypedPath(typed, unit_of(self.units.value)))

    def load_upload(self, upload: UploadedFile) -> int:
        """Queue loading a finished upload in the tab's unit."""
        return self.host.load(Upload(upload, unit_of(self.units.value)))


def mount(host: Host) -> FileFeature:
    """The File tab: a path in the data folder, its unit, "Load file", an upload."""
    gui = host.gui
    shown = host.session.shown
    limit = f", at most {format_bytes(host.options.max_upload_bytes)}"
    with host.tab("File"):
        f = FileFeature(
            host=host,
            path=gui.add_text(L_PATH, shown.loaded.cloud.source,
                              hint="A file in the server's data folder (--data-dir); "
                              "relative paths start there."),
            units=gui.add_dropdown(
                L_UNITS, UNIT_OPTIONS, initial_value=host.options.units or "auto",
                hint="Unit of the file's coordinates: auto = the unit of a LAS file's CRS, "
                "else metres."),
            load=gui.add_button(L_LOAD),
            upload=gui.add_upload_button(
                L_UPLOAD, hint=f"Send a point-cloud file from this computer{limit}."),
            binding=Binding(),
        )
    host.allow(f.path, f.units, f.load)
    f.binding.on_change([f.load], lambda _h: f.load_path(f.path.value))
    host.take_uploads(f.upload, f.load_upload)
    return f
