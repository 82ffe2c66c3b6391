"""The main window's documents: open (off the GUI thread), save, switch, recent files, drops;
meshes and environment maps opened the same way."""

from __future__ import annotations

from pathlib import Path

from PySide6.QtCore import QTimer
from PySide6.QtWidgets import QFileDialog, QMessageBox

from brdflab import workspace as ws_ops
from brdflab.errors import BRDFLabError
from brdflab.gui.probe_open import MAP_FILTER, ask_back_half, front_and_back
from brdflab.io.mesh import FORMATS as MESH_FORMATS
from brdflab.io.mesh import load_mesh
from brdflab.lighting.envmap import load_environment
from brdflab.models.files.library import MissingModelFile
from brdflab.sources.measured import MeasuredTable
from brdflab.sources.proxy import measured_sampler, proxy_lobes
from brdflab.workspace import OPEN_FILTER, Workspace

MAX_RECENT = 8


class DocumentFiles:
    """Opening, saving and switching documents for MainWindow (a mixin)."""

    def set_workspace(self, workspace: Workspace) -> None:
        if self._thread is not None and workspace is not self._fit_owner:
            self._thread.cancel.set()  # the running fit belongs to the document being closed
            self.fitting.status.setText("stopping the run of the closed document…")
        self.locate_button.setVisible(workspace.data_missing)
        self._unsaved_at_clean = workspace.dirty
        self.undo_stack.clear()
        self.document.show(workspace)  # `switched`: nothing of the closed document stays drawn
        self._show_own_ladder()
        self._binning_note()
        for message in workspace.messages:
            self.statusBar().showMessage(message, 10000)

    def _forget_closed_document(self, workspace: Workspace) -> None:
        """Another document is shown: the closed one's last run is no longer said (the
        document drops its progress, the views follow `switched` themselves)."""
        if self._thread is None:
            self.fitting.status.setText("")

    def maybe_save(self) -> bool:
        """True when it is fine to discard the current document."""
        if not self.workspace.dirty:
            return True
        answer = QMessageBox.question(self, "BRDFLab", f"Save changes to {self.workspace.title.rstrip(' *')}?",
                                      QMessageBox.Save | QMessageBox.Discard | QMessageBox.Cancel)
        if answer == QMessageBox.Save:
            return self.save()
        return answer == QMessageBox.Discard

    def new_material(self) -> None:
        if self.maybe_save():
            self.set_workspace(Workspace.new())

    def show_simulation(self) -> None:
        """The Simulation dock (brdflab.gui.simulated), on the open simulated material if any."""
        from brdflab.gui.simulated import show_simulation_dock

        show_simulation_dock(self)

    # loading happens in a worker thread; `loading` is true until the result is applied
    @property
    def loading(self) -> bool:
        return bool(self._loads)

    def _load(self, what: str, path: Path, work, apply) -> None:
        """Run work(path) off the GUI thread, then apply(result) here (errors: a dialog)."""
        future = self._loader.submit(work, Path(path))
        self._loads.append(future)
        self.statusBar().showMessage(f"opening {what} {path}…")
        self.load_progress.setVisible(True)

        def poll():
            if not future.done():
                QTimer.singleShot(30, poll)
                return
            self._loads.remove(future)
            self.load_progress.setVisible(bool(self._loads))
            try:
                result = future.result()
            except MissingModelFile as e:
                self.locate_model(Path(path), e)
                return
            except BRDFLabError as e:
                self.show_error(str(e))
                return
            except Exception as e:  # a file that breaks a reader must not break the window
                self.show_error(f"{path}: cannot open: {type(e).__name__}: {e}")
                return
            apply(result)

        QTimer.singleShot(0, poll)

    def open_path(self, path: Path) -> None:
        def apply(workspace: Workspace) -> None:
            self._remember(Path(path))
            self.set_workspace(workspace)
            if not workspace.messages:  # never hide what set_workspace just reported
                self.statusBar().showMessage(f"opened {path}", 5000)

        self._load("material", path, _open_with_proxy, apply)

    def _ask_and_open(self, title: str, kind: str, file_filter: str, opener) -> None:
        """A file dialog that starts in (and remembers) the last folder of its kind."""
        name, _ = QFileDialog.getOpenFileName(self, title, self._folder(kind), file_filter)
        if name:
            self.settings.setValue(f"folders/{kind}", str(Path(name).parent))
            opener(Path(name))

    def locate_data_dialog(self) -> None:
        ref = self.workspace.document.material
        name, _ = QFileDialog.getOpenFileName(self, f"Locate {Path(getattr(ref, 'name', '')).name}",
                                              self._folder("open"), OPEN_FILTER)
        if name:
            self.locate_data(Path(name))

    def locate_data(self, path: Path) -> None:
        """Give a measured material whose data file is missing the file found at `path`."""
        try:
            self.workspace.locate_data(path)
        except BRDFLabError as e:
            self.show_error(str(e))
            return
        self.undo_stack.resetClean()  # the document now differs from its file
        self.set_workspace_keeping_history()

    def set_workspace_keeping_history(self) -> None:
        ws = self.workspace
        self._unsaved_at_clean = True
        self.locate_button.setVisible(ws.data_missing)
        ws.guess = None
        self.document.show(ws)  # the same document read again: every view refreshes
        self._binning_note()
        for message in ws.messages:
            self.statusBar().showMessage(message, 10000)

    def open_dialog(self) -> None:
        if self.maybe_save():
            self._ask_and_open("Open", "open", OPEN_FILTER, self.open_path)

    def open_mesh(self, path: Path) -> None:
        def apply(mesh) -> None:
            self.object_view.when_ready(lambda: self.object_view.renderer.set_mesh(mesh))
            self.object_view.restart()
            self.statusBar().showMessage(f"mesh {path}: {mesh.n_vertices:,} vertices", 5000)

        self._load("mesh", path, load_mesh, apply)

    def open_mesh_dialog(self) -> None:
        self._ask_and_open("Open mesh", "mesh", "Meshes (" + " ".join(f"*{e}" for e in MESH_FORMATS) + ")", self.open_mesh)

    def open_environment(self, path: Path, back: Path | None = None) -> None:
        """Open a map in the object view's map layout (a pair: `path` the front, `back` the back half)."""
        layout = "dual-paraboloid" if back is not None else self.object_controls.env_layout.currentText()

        def apply(env) -> None:
            self._env_files = (Path(path), back)
            self.object_view.when_ready(lambda: self.object_view.renderer.set_environment(env))
            self.object_view.restart()
            self.object_feed.request_auto_lighting()
            self._map_note(env)
            self.statusBar().showMessage(f"environment {env.path} ({env.layout})", 5000)

        def read(p):
            env = load_environment(p, layout, back)
            env.mips  # noqa: B018  (computed here, in the loading thread: 80 ms of a probe held the GUI thread)
            return env

        self._load("environment", path, read, apply)

    def open_environment_dialog(self) -> None:
        """One map, or both halves of a dual-paraboloid pair (multiple selection)."""
        names, _ = QFileDialog.getOpenFileNames(self, "Open environment (a pair: select both halves)",
                                                self._folder("env"), MAP_FILTER)
        if not names:
            return
        self.settings.setValue("folders/env", str(Path(names[0]).parent))
        try:
            path, back = front_and_back(names)
        except BRDFLabError as e:
            self.show_error(str(e))
            return
        if back is not None:
            self.object_controls.env_layout.setCurrentText("dual-paraboloid")
        elif self.object_controls.env_layout.currentText() == "dual-paraboloid":
            back = ask_back_half(self, path)
        self.open_environment(path, back)

    def _reopen_environment(self) -> None:
        """The map shown, read again in the layout just chosen."""
        path, back = self._env_files
        if self.object_controls.env_layout.currentText() != "dual-paraboloid":
            back = None
        elif back is None:
            back = ask_back_half(self, path)
        self.open_environment(path, back)

    def save(self) -> bool:
        if self.workspace.path is None:
            return self.save_as()
        return self._save_to(self.workspace.path)

    def save_as(self) -> bool:
        name, _ = QFileDialog.getSaveFileName(self, "Save material", self._folder("save"), "BRDFLab materials (*.xml)")
        if not name:
            return False
        path = Path(name if name.lower().endswith(".xml") else name + ".xml")
        self.settings.setValue("folders/save", str(path.parent))
        return self._save_to(path)

    def _save_to(self, path: Path) -> bool:
        try:
            self.document.save(path)
        except BRDFLabError as e:
            self.show_error(str(e))
            return False
        self._unsaved_at_clean = False
        self.undo_stack.setClean()
        self._remember(path)
        self._update_title()
        self.statusBar().showMessage(f"saved {path}", 5000)
        return True

    def _folder(self, kind: str) -> str:
        return str(self.settings.value(f"folders/{kind}", str(Path.home())))

    def _remember(self, path: Path) -> None:
        recent = [p for p in (self.settings.value("recent") or []) if p != str(path)]
        self.settings.setValue("recent", [str(path)] + recent[: MAX_RECENT - 1])
        self._update_recent()

    def _update_recent(self) -> None:
        if self.recent_menu is None:
            return
        self.recent_menu.clear()
        for p in self.settings.value("recent") or []:
            action = self.recent_menu.addAction(p)
            action.triggered.connect(lambda _=False, p=p: self.maybe_save() and self.open_path(Path(p)))

    def dragEnterEvent(self, event) -> None:
        if event.mimeData().hasUrls():
            event.acceptProposedAction()

    def dropEvent(self, event) -> None:
        for url in event.mimeData().urls():
            path = Path(url.toLocalFile())
            ext = path.suffix.lower()
            if ext in MESH_FORMATS:
                self.open_mesh(path)
            elif ext in (".hdr", ".exr"):
                self.open_environment(path)
            elif self.maybe_save():
                self.open_path(path)


def _open_with_proxy(path: Path) -> Workspace:
    """Open a file in the loader thread, and fit a measured source's proxy and build its
    sampling tables there too: the object view fitting it when first drawing the source held
    the GUI thread 0.25–0.44 s (the tables take another 0.3 s)."""
    workspace = Workspace.open(path)
    if workspace.source is not None and not isinstance(workspace.source, ws_ops.AnalyticMaterial):
        proxy_lobes(workspace.source)
        measured_sampler(workspace.source).ensure_all()
    if isinstance(workspace.source, MeasuredTable):
        workspace.source.theta_h_step  # noqa: B018  (cached here, off the GUI thread)
    return workspace
