"""3D mesh viewer: a pyvistaqt ``QtInteractor`` showing a :class:`SceneMesh`.

Colour modes: the day image (per-vertex colour sampled at the source pixel),
semantic labels, vertex normals, uncertainty, or per-vertex error. Toggles for
the background / foreground sheets, the walls closing depth steps (grey), the grid
faces the post-processing replaced (red) and light emitters. "Input view" puts the camera at the origin looking down +z with the
image's field of view (OpenCV frame: y down), so the mesh lines up with the photo.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pyvista as pv
import shiboken6
from PySide6.QtWidgets import QCheckBox, QComboBox, QHBoxLayout, QPushButton, QVBoxLayout, QWidget
from pyvistaqt import QtInteractor

from npsim_core.labels import cityscapes, light_classes
from npsim_core.mesh.types import MeshPart, SceneMesh

COLOR_MODES = ("image", "labels", "normals", "uncertainty", "error")


def _polydata(parts: list[MeshPart]) -> pv.PolyData | None:
    parts = [p for p in parts if p.n_faces]
    if not parts:
        return None
    offsets = np.cumsum([0] + [p.n_vertices for p in parts[:-1]])
    tri = np.concatenate([p.faces + o for p, o in zip(parts, offsets)])
    # only the vertices the faces use: a face subset (walls, emitters, the removed grid faces) would
    # otherwise carry every vertex of its sheets (the removed faces of a 2048x1024 frame: 55 k faces
    # over 1.9 M vertices, 47 MB held and uploaded for nothing)
    used, tri = np.unique(tri, return_inverse=True)
    tri = tri.reshape(-1, 3)

    def per_vertex(arrays, dtype):
        return np.concatenate(arrays)[used].astype(dtype)
    pts = per_vertex([p.vertices for p in parts], np.float32)
    cells = np.hstack([np.full((len(tri), 1), 3, dtype=np.int64), tri.astype(np.int64)]).ravel()
    pd = pv.PolyData(pts, cells)
    pd.point_data["pixel"] = per_vertex([p.pixel for p in parts], np.float32)
    pd.point_data["label"] = per_vertex([p.label for p in parts], np.uint8)
    pd.point_data["light"] = per_vertex([p.light_id for p in parts], np.int32)
    return pd


def _sample(img: np.ndarray, pixel: np.ndarray) -> np.ndarray:
    h, w = img.shape[:2]
    u = np.clip(np.rint(pixel[:, 0]).astype(np.intp), 0, w - 1)
    v = np.clip(np.rint(pixel[:, 1]).astype(np.intp), 0, h - 1)
    return img[v, u]


@dataclass
class MeshDisplay:
    """VTK-ready geometry of one mesh (built off the GUI thread by :func:`build_display`)."""

    mesh: SceneMesh
    image: np.ndarray
    background: pv.PolyData | None
    foreground: pv.PolyData | None
    walls: pv.PolyData | None
    removed: pv.PolyData | None
    emitters: pv.PolyData | None
    fields: dict[str, np.ndarray]
    fov_deg: float | None


def _emitter_part(part: MeshPart) -> MeshPart:
    return _select(part, part.face_light_id() > 0)


def _select(part: MeshPart, keep: np.ndarray) -> MeshPart:
    return MeshPart(part.name, part.vertices, part.faces[keep], part.uv, part.pixel, part.label,
                    part.light_id, part.foreground)


def build_display(mesh: SceneMesh, image: np.ndarray, *, removed: MeshPart | None = None,
                  fields: dict[str, np.ndarray] | None = None, fy: float | None = None) -> MeshDisplay:
    """Concatenate the sheets into VTK poly data (pure data work: safe in a worker thread).

    The walls that close depth steps (edge-on from the camera) are kept apart so the
    3D view can show them in their own colour or hide them."""
    walls = [q.edge_on_faces() for q in mesh.parts]
    bg = _polydata([_select(q, ~w) for q, w in zip(mesh.parts, walls) if not q.foreground])
    fg = _polydata([_select(q, ~w) for q, w in zip(mesh.parts, walls) if q.foreground])
    wl = _polydata([_select(q, w) for q, w in zip(mesh.parts, walls)])
    rm = _polydata([removed]) if removed is not None and removed.n_faces else None
    em = _polydata([_emitter_part(q) for q in mesh.parts])
    fov = math.degrees(2 * math.atan(mesh.height / 2.0 / fy)) if fy else None
    return MeshDisplay(mesh, image, bg, fg, wl, rm, em, dict(fields or {}), fov)


class MeshViewer(QWidget):
    """Toolbar + pyvista interactor. Call :meth:`set_mesh` whenever the mesh changes."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        bar = QHBoxLayout()
        self.mode = QComboBox()
        self.mode.addItems(COLOR_MODES)
        self.show_bg = QCheckBox("background")
        self.show_fg = QCheckBox("foreground")
        self.show_walls = QCheckBox("walls")
        self.show_walls.setToolTip("Faces closing depth steps inside a sheet: along the camera rays, "
                                   "invisible from the photo's viewpoint (grey)")
        self.show_removed = QCheckBox("removed")
        self.show_removed.setToolTip("Grid faces the post-processing replaced (red)")
        self.show_lights = QCheckBox("emitters")
        for cb in (self.show_bg, self.show_fg, self.show_walls, self.show_removed, self.show_lights):
            cb.setChecked(cb in (self.show_bg, self.show_fg, self.show_walls))
            cb.toggled.connect(self._redraw)
        self.mode.currentTextChanged.connect(self._redraw)
        self.reset_btn = QPushButton("Input view")
        self.reset_btn.setToolTip("Put the camera back at the photo's viewpoint")
        self.reset_btn.clicked.connect(self.reset_camera)
        bar.addWidget(self.mode)
        bar.addStretch(1)
        bar.addWidget(self.reset_btn)
        lay.addLayout(bar)
        for row in ((self.show_bg, self.show_fg, self.show_walls), (self.show_removed, self.show_lights)):
            toggles = QHBoxLayout()  # two more rows keep the dock narrow (small screens)
            for w in row:
                toggles.addWidget(w)
            toggles.addStretch(1)
            lay.addLayout(toggles)
        self.plotter = QtInteractor(self, auto_update=False)
        self.plotter.set_background("#1b1d22")
        lay.addWidget(self.plotter.interactor, 1)
        self.mesh: SceneMesh | None = None
        self.removed: MeshPart | None = None
        self.image: np.ndarray | None = None
        self.vertex_fields: dict[str, np.ndarray] = {}
        self._fov_deg = 40.0
        self._camera_set = False
        self.renders_requested = 0  # repaints asked for (each renders the scene once)

    # ------------------------------------------------------------------ data
    def set_mesh(self, mesh: SceneMesh, image: np.ndarray, *, fy: float | None = None,
                 removed: MeshPart | None = None, fields: dict[str, np.ndarray] | None = None) -> None:
        """Show ``mesh`` coloured from ``image`` (HxWx3 uint8); ``fields`` are HxW maps for
        the 'uncertainty' / 'error' modes (sampled at each vertex's pixel)."""
        self.set_display(build_display(mesh, image, removed=removed, fields=fields, fy=fy))

    def set_display(self, display: "MeshDisplay") -> None:
        """Show a display prepared by :func:`build_display` (which may run in a worker thread)."""
        self.display = display
        self.mesh, self.image = display.mesh, display.image
        self.vertex_fields = display.fields
        if display.fov_deg:
            self._fov_deg = display.fov_deg
        if not self._camera_set:
            self._place_camera()  # before the actors are added: one render shows both
            self._camera_set = True
        self._redraw()

    def clear(self) -> None:
        """Show nothing and let go of the last frame's meshes and image (another frame opens)."""
        self.display = None
        self.mesh, self.image, self.vertex_fields = None, None, {}
        self._redraw()

    def _colors(self, pd: pv.PolyData) -> np.ndarray:
        mode = self.mode.currentText()
        pix = np.asarray(pd.point_data["pixel"])
        if mode == "labels":
            return cityscapes().color_lut()[np.asarray(pd.point_data["label"])]
        if mode == "normals":
            pd2 = pd.compute_normals(cell_normals=False, point_normals=True, auto_orient_normals=False,
                                     consistent_normals=False, split_vertices=False)
            n = np.asarray(pd2.point_data["Normals"])
            return np.clip((n + 1) * 127.5, 0, 255).astype(np.uint8)
        if mode in ("uncertainty", "error") and mode in self.vertex_fields:
            f = _sample(self.vertex_fields[mode].astype(np.float32), pix)
            f = np.nan_to_num(f, nan=0.0)
            t = np.clip(f / max(float(np.percentile(f, 99)), 1e-9), 0, 1)
            return np.stack([255 * t, 60 + 0 * t, 255 * (1 - t)], axis=1).astype(np.uint8)
        if self.image is not None:
            return _sample(self.image, pix)
        return np.full((pd.n_points, 3), 200, np.uint8)

    def _redraw(self) -> None:
        p = self.plotter
        cam = p.camera_position if self._camera_set else None
        p.clear_actors()  # one render at the end: each costs 60-100 ms for 155k faces on llvmpipe
        d = getattr(self, "display", None)
        if d is None:
            self.request_render()
            return
        for pd, show in ((d.background, self.show_bg.isChecked()), (d.foreground, self.show_fg.isChecked())):
            if pd is not None and show:
                pd.point_data["rgb"] = self._colors(pd)
                p.add_mesh(pd, scalars="rgb", rgb=True, show_scalar_bar=False,
                           lighting=self.mode.currentText() != "image", render=False, reset_camera=False)
        if self.show_walls.isChecked() and d.walls is not None:
            p.add_mesh(d.walls, color="#8a8f99", opacity=0.7, render=False, reset_camera=False)
        if self.show_removed.isChecked() and d.removed is not None:
            p.add_mesh(d.removed, color="red", opacity=0.8, render=False, reset_camera=False)
        if self.show_lights.isChecked() and d.emitters is not None:
            lut = np.zeros((32, 3), np.uint8)
            for c in light_classes():
                lut[c.id] = c.color
            p.add_mesh(d.emitters, scalars=lut[np.asarray(d.emitters.point_data["light"]) // 1000], rgb=True,
                       render=False, reset_camera=False)
        if cam is not None:
            p.camera_position = cam
        self.request_render()

    def request_render(self) -> None:
        """Schedule one render (the widget's next paint renders the scene).

        ``plotter.render()`` renders at once *and* makes the widget repaint, which renders again
        (pyvistaqt's paintGL always renders): two full software renders per change, in one event.
        Asking for a repaint renders once, and several changes in one event share that render."""
        self.renders_requested += 1
        self.plotter.interactor.update()

    def _place_camera(self) -> None:
        p = self.plotter
        p.camera_position = [(0.0, 0.0, 0.0), (0.0, 0.0, 10.0), (0.0, -1.0, 0.0)]
        p.camera.view_angle = self._fov_deg
        p.camera.clipping_range = (0.05, 2000.0)

    def reset_camera(self) -> None:
        """Camera at the origin, looking along +z, image 'up' = -y (OpenCV frame)."""
        self._place_camera()
        self.request_render()

    def screenshot(self) -> np.ndarray:
        return self.plotter.screenshot(return_img=True)

    def close_viewer(self) -> None:
        """Close the interactor explicitly (pyvistaqt segfaults at teardown otherwise).

        The interactor keeps a wrapper of its GL context's surface, a ``QSurface``: not a QObject,
        so PySide never learns when Qt deletes it, and a closed window's Python object lives on
        (signal connections to lambdas). Until then the stale wrapper claims its address, and the
        next Qt object allocated there (a dock's toggle action, a timer) came back to Python as a
        ``QSurface`` — a failed test setup in CI. The wrapper is let go here, after the last GL
        teardown that needs it."""
        self.plotter.close()
        interactor = self.plotter.interactor
        surface = getattr(interactor, "_surface", None)
        if surface is not None:
            interactor._surface = None  # pyvistaqt then skips makeCurrent: the window is finalised
            shiboken6.invalidate(surface)
