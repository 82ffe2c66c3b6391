"""The main window: one Workspace, shown by dock panels and two OpenGL views."""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from PySide6.QtCore import QSettings, Qt, QTimer, Slot
from PySide6.QtGui import QGuiApplication, QUndoStack
from PySide6.QtWidgets import (QApplication, QDockWidget, QFileDialog, QLabel, QMainWindow, QMessageBox,
                               QProgressBar, QPushButton, QSplitter, QVBoxLayout, QWidget)

from brdflab import workspace as ws_ops
from brdflab.lighting.envmap import load_environment
from brdflab.errors import BRDFLabError
from brdflab.fitting.auto import Ladder
from brdflab.fitting.lm import material_from_lobes
from brdflab.io.mesh import default_mesh
from brdflab.io.resources import data_dir
from brdflab.sources.measured import MeasuredTable
from brdflab.workspace import Workspace

MODEL_FILTER = "Model files (*.brdf *.xml);;BRDF Explorer (*.brdf);;BRDFLab model descriptors (*.xml);;All files (*)"
from brdflab.gui.gl_views import LobeView, ObjectView
from brdflab.gui.auto_ladder import AutoLadderPanel
from brdflab.gui.background import AutoFitProcess, FitProcess
from brdflab.gui.charts import ChartsPanel
from brdflab.gui.commands import ReplaceMaterial
from brdflab.gui.document import ShownDocument
from brdflab.gui.documents import DocumentFiles
from brdflab.gui.fit_control import FitControl
from brdflab.gui.lobe_feed import LobeViewFeed
from brdflab.gui.object_feed import ObjectViewFeed
from brdflab.gui.window_actions import WindowActions
from brdflab.gui.fields import FieldGuard
from brdflab.gui.window_layout import ColumnKeeper
from brdflab.gui.panels import (FittingPanel, LobeControls, MaterialEditor, ObjectControls, PlotsPanel, XmlView,
                                scrolling)
from brdflab.fitting.diagnosis import bound_warnings, energy_words

LAYOUT_VERSION = 5  # 2: the lobe viewer became the central view; 3: the Charts dock; 4: the Auto ladder dock;
# 5: the left column the window's full height
DEFAULT_MESH = "meshes/spot.obj"
DEFAULT_ENV = "envmaps/venice_sunset_1k.hdr"
RING_STEP = 2.0  # a measured table whose neighbouring θh bins differ this much shows them as rings


class _ViewsArea(QWidget):
    """The two views, with the warnings banner laid over their top edge: a banner that comes
    and goes never resizes the views (nor restarts their rendering)."""

    def __init__(self, views: QWidget) -> None:
        super().__init__()
        column = QVBoxLayout(self)
        column.setContentsMargins(0, 0, 0, 0)
        column.addWidget(views)
        self.banner = QLabel(self, wordWrap=True, textFormat=Qt.RichText, visible=False)
        self.banner.setObjectName("warnings")
        self.banner.setStyleSheet("QLabel#warnings { background: rgba(90, 66, 16, 225); color: #ffe9b0; padding: 4px; }")

    def show_banner(self, html: str) -> None:
        self.banner.setText(html)
        self.banner.setVisible(bool(html))
        self._place_banner()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._place_banner()

    def _place_banner(self) -> None:  # over the views' top edge, as tall as its text
        width = self.width()
        self.banner.setGeometry(0, 0, width, self.banner.heightForWidth(width))
        self.banner.raise_()


class MainWindow(DocumentFiles, FitControl, WindowActions, QMainWindow):
    def __init__(self, settings: QSettings | None = None) -> None:
        super().__init__()
        self._field_guard = FieldGuard(self._shortcut_texts, self)  # first: it sees every field polished
        QApplication.instance().installEventFilter(self._field_guard)
        self.settings = settings or QSettings()
        self.resize(1500, 950)
        # the width the panels need side by side is the window's least (an 800-px minimum let the
        # Fitting and Plots panels overlap below 1,042 px); the height a 1366 × 768 laptop allows
        self.setMinimumHeight(560)
        self.setAcceptDrops(True)
        self.undo_stack = QUndoStack(self)
        self.undo_stack.cleanChanged.connect(self._clean_changed)
        self.undo_stack.indexChanged.connect(self._index_changed)
        self._unsaved_at_clean = False  # a new document (e.g. opened data) that no file holds yet
        self.document = ShownDocument(Workspace.new(), self)  # evented: views subscribe to it
        self._thread: FitProcess | AutoFitProcess | None = None  # the running fit
        self._auto_ladder: tuple[Workspace, Ladder] | None = None  # the last Auto run and its document
        self._loader = ThreadPoolExecutor(max_workers=1)
        self._loads: list = []
        self._env_files: tuple[Path, Path | None] = (data_dir("resources") / DEFAULT_ENV, None)  # reopened in a new layout
        self.load_progress = QProgressBar(maximumWidth=160)
        self.load_progress.setRange(0, 0)
        self.load_progress.setVisible(False)
        self.statusBar().addPermanentWidget(self.load_progress)
        self.locate_button = QPushButton("Locate data file…")
        self.locate_button.setToolTip("The measured data file this material names is missing: find it")
        self.locate_button.setVisible(False)
        self.locate_button.clicked.connect(self.locate_data_dialog)
        self.statusBar().addPermanentWidget(self.locate_button)
        self._fit_owner: Workspace | None = None  # the document a running fit belongs to

        self.lobe_view = LobeView()
        self.object_view = ObjectView()
        self.editor = MaterialEditor()
        self.lobe_controls = LobeControls()
        self.object_controls = ObjectControls()
        self.fitting = FittingPanel()
        self.plots = PlotsPanel()
        self.xml = XmlView()
        self.charts = ChartsPanel(self._study_scene)
        self.ladder = AutoLadderPanel()
        # the lobe viewer is the central, largest view (as in BRDFLab), the object view beside it
        self.views = QSplitter(Qt.Horizontal)
        self.views.setObjectName("views")
        self.views.addWidget(self.lobe_view)
        self.views.addWidget(self.object_view)
        self.views.setChildrenCollapsible(False)
        self.views.setStretchFactor(0, 3)
        self.views.setStretchFactor(1, 2)
        central = self._views_area = _ViewsArea(self.views)
        self.warnings = central.banner
        self.setCentralWidget(central)
        self._docks = {}
        # the left column runs the window's full height: on a 1366 × 768 laptop the Material
        # panel showed 1–2 parameter rows above a full-width bottom row
        self.setCorner(Qt.BottomLeftCorner, Qt.LeftDockWidgetArea)
        for name, widget, area in (
            ("Material", self.editor, Qt.LeftDockWidgetArea),
            ("Lobe options", self.lobe_controls, Qt.LeftDockWidgetArea),
            ("Object view options", self.object_controls, Qt.LeftDockWidgetArea),
            ("Fitting", self.fitting, Qt.BottomDockWidgetArea),
            ("Plots", self.plots, Qt.BottomDockWidgetArea),
            ("XML", self.xml, Qt.BottomDockWidgetArea),
            ("Charts", self.charts, Qt.BottomDockWidgetArea),
            ("Auto ladder", self.ladder, Qt.BottomDockWidgetArea),
        ):
            dock = QDockWidget(name, self)
            dock.setObjectName(name)
            dock.setWidget(scrolling(widget) if name not in ("Fitting", "Plots", "XML", "Charts", "Auto ladder")
                           else widget)  # Fitting scrolls its controls itself, its progress pinned below
            self.addDockWidget(area, dock)
            self._docks[name] = dock
        # left: the material over the view options; bottom: fitting beside the plots (XML a tab)
        self.tabifyDockWidget(self._docks["Lobe options"], self._docks["Object view options"])
        self.splitDockWidget(self._docks["Fitting"], self._docks["Plots"], Qt.Horizontal)
        self.tabifyDockWidget(self._docks["Plots"], self._docks["XML"])
        self.tabifyDockWidget(self._docks["XML"], self._docks["Charts"])
        self.tabifyDockWidget(self._docks["Charts"], self._docks["Auto ladder"])
        self._docks["Lobe options"].raise_()
        self._docks["Plots"].raise_()
        self.resizeDocks([self._docks["Material"]], [340], Qt.Horizontal)
        self.resizeDocks([self._docks["Material"], self._docks["Lobe options"]], [330, 150], Qt.Vertical)
        self.resizeDocks([self._docks["Fitting"], self._docks["Plots"]], [400, 900], Qt.Horizontal)
        self.resizeDocks([self._docks["Plots"]], [250], Qt.Vertical)
        self._default_layout = self.saveState(LAYOUT_VERSION)
        self._left_keeper = ColumnKeeper(self, self._docks["Material"])
        self._warnings: dict[str, str] = {}  # what is wrong, by topic, shown above the views
        self._build_menus()
        self._follow_document()
        self._connect()
        self.lobe_view.when_ready(lambda: None)
        self.object_view.when_ready(self._default_scene)
        geometry = self.settings.value("geometry")
        if geometry is not None:
            self.restoreGeometry(geometry)
            self.restoreState(self.settings.value("state"), LAYOUT_VERSION)
            views = self.settings.value("views")
            if views is not None:
                self.views.restoreState(views)
        else:
            self._fit_screen()
        self._restoring_layout = False  # a layout restored puts its own tabs in front
        for dock in self._docks.values():  # connected after the saved layout is restored
            dock.topLevelChanged.connect(lambda floating, d=dock: self._docked_again(d, floating))
        self._placed = False  # the first show puts the window and its floated panels on screen
        self.set_workspace(self.workspace)
        self.load_model_folders()

    def _follow_document(self) -> None:
        """Every view subscribes to the shown document; the window's own parts (the initial
        guess first, so the views find it, then the banner and the title) do too."""
        d = self.document
        for signal in (d.material_changed, d.fittings_changed, d.drawn_changed, d.saved):
            signal.connect(self._document_changed)
        d.switched.connect(self._forget_closed_document)
        d.switched.connect(lambda _: self._document_changed())
        self.editor.follow(d)
        self.fitting.follow(d)
        self.xml.follow(d)
        self.plots.follow(d, lambda: self.lobe_view.viewer.settings.theta_i if self.lobe_view.ctx else 30.0)
        self.lobe_feed = LobeViewFeed(d, self.lobe_view, self.lobe_controls, self.show_error, self)
        self.lobe_feed.settings_changed.connect(self.plots.refresh_soon)
        self.object_feed = ObjectViewFeed(d, self.object_view, self.object_controls, self.set_warning,
                                          self.show_error, self)

    def _document_changed(self) -> None:
        ws = self.workspace
        if ws.analytic is None and ws.guess is None and ws.source is not None:
            self._new_guess()
        self._check_bounds()
        self._update_title()

    @property
    def workspace(self) -> Workspace:
        """The document shown (self.document's)."""
        return self.document.workspace

    # --- models from files ------------------------------------------------------------------------
    def model_folders(self) -> list[Path]:
        """The folder chosen in the settings, then BRDFLAB_MODELS's."""
        from brdflab.models.files.library import env_folders

        chosen = self.settings.value("models/folder")
        return ([Path(chosen)] if chosen else []) + env_folders()

    def load_model_folders(self) -> None:
        """Read every model file in the model folders (off the GUI thread); a file that cannot
        be used is said in the status bar and the banner, the others are added."""
        from brdflab.models.files.library import load_folders

        folders = [f for f in self.model_folders() if f.is_dir()]
        if not folders:
            return
        problems: list[str] = []

        def work(_path):
            return load_folders(folders, warn=problems.append)

        def apply(models) -> None:
            self.editor.refresh_models()
            self.set_warning("models", "<br>".join(problems[:3]) if problems else None)
            self.statusBar().showMessage(f"{len(models)} model(s) from {', '.join(map(str, folders))}"
                                         + (f"; {len(problems)} file(s) could not be used" if problems else ""), 10000)

        self._load("models from", folders[0], work, apply)

    def model_folder_dialog(self) -> None:
        name = QFileDialog.getExistingDirectory(self, "Model folder", self.settings.value("models/folder") or "")
        if name:
            self.settings.setValue("models/folder", name)
            self.load_model_folders()

    def add_model_file_dialog(self) -> None:
        self._ask_and_open("Add model from file", "models", MODEL_FILTER, self.add_model_file)

    def add_model_file(self, path: Path) -> None:
        """Read a model file (checked off the GUI thread) and add a lobe of it at its defaults."""
        from brdflab.models.files.library import load_model_file

        def apply(model) -> None:
            self.editor.refresh_models(select=model.name)
            self.statusBar().showMessage(f"added the model {model.name} ({model.origin.format} file {path})", 10000)
            for warning in model.warnings:
                self.statusBar().showMessage(warning, 10000)
            if self.workspace.editable() is not None:
                self._edit(ws_ops.with_lobe_added(self.workspace.editable(), model.name), f"Add {model.name} lobe")

        self._load("model", path, load_model_file, apply)

    def locate_model(self, document: Path, missing) -> None:
        """A material names a model file that is not there: ask for it, then open the material
        again (everything else in it is read as before)."""
        box = QMessageBox(QMessageBox.Warning, "BRDFLab", str(missing), QMessageBox.Cancel, self)
        locate = box.addButton("Locate model file…", QMessageBox.AcceptRole)
        box.exec()
        if box.clickedButton() is not locate:
            return
        name, _ = QFileDialog.getOpenFileName(self, f"Locate the model {missing.model_name}", self._folder("models"),
                                              MODEL_FILTER)
        if name:
            self.use_located_model(document, missing.model_name, Path(name))

    def use_located_model(self, document: Path, model_name: str, path: Path) -> None:
        """Read the model file the user found for `model_name`, then open `document` again."""
        from brdflab.models.files.library import load_model_file

        def apply(model) -> None:
            if model.xml_name != model_name:
                self.show_error(f"{path}: defines the model {model.xml_name!r}, not {model_name!r}")
                return
            self.editor.refresh_models()
            self.open_path(document)

        self._load("model", path, load_model_file, apply)

    # --- set-up ------------------------------------------------------------------------------
    def _fit_screen(self) -> None:
        """First start: the default size, shrunk to the screen's free area (a 1366 × 768 laptop)."""
        screen = self.screen().availableGeometry() if self.screen() else None
        if screen is not None:
            self.resize(min(self.width(), screen.width()), min(self.height(), screen.height() - 30))

    def showEvent(self, event) -> None:
        super().showEvent(event)
        if not self._placed:
            self._placed = True
            QTimer.singleShot(0, self._place_on_screen)  # once the window manager has framed it

    def _place_on_screen(self) -> None:
        """The window, then every floated panel, inside the free area of the screen it is on,
        frame included, the panels raised above the window: a layout saved on a larger (or a
        detached) screen came back with the window's bottom off-screen and a floated panel
        behind the window."""
        for widget in (self, *(d for d in self._docks.values() if d.isFloating() and d.isVisible())):
            frame = widget.frameGeometry()
            screen = QGuiApplication.screenAt(frame.center()) or self.screen() or QGuiApplication.primaryScreen()
            free = screen.availableGeometry()
            extra_w, extra_h = frame.width() - widget.width(), frame.height() - widget.height()
            if frame.width() > free.width() or frame.height() > free.height():
                widget.resize(min(widget.width(), free.width() - extra_w), min(widget.height(), free.height() - extra_h))
                frame = widget.frameGeometry()
            x = min(max(frame.x(), free.x()), free.x() + free.width() - frame.width())
            y = min(max(frame.y(), free.y()), free.y() + free.height() - frame.height())
            if (x, y) != (frame.x(), frame.y()):
                widget.move(x, y)
            if widget is not self:
                widget.raise_()

    def reset_layout(self) -> None:
        """Every panel back where it starts, the two views at their first proportions."""
        self._restoring_layout = True
        self.restoreState(self._default_layout, LAYOUT_VERSION)
        for dock in self._docks.values():
            dock.setFloating(False)
        self._restoring_layout = False
        total = sum(self.views.sizes())
        self.views.setSizes([total * 3 // 5, total - total * 3 // 5])

    def _docked_again(self, dock: QDockWidget, floating: bool) -> None:
        """A floating panel docked again (a double-click on its title) comes to the front of
        its tabs: it went back as a hidden tab behind the one in front (Plots behind XML)."""
        if not floating and not self._restoring_layout:
            dock.raise_()

    def _connect(self) -> None:
        e = self.editor
        e.parameter_edited.connect(lambda k, n, v: self._edit(ws_ops.with_parameter(self.workspace.editable(), k, n, v),
                                                              f"Set {n}", (k, n)))
        e.scale_edited.connect(lambda k, c, v: self._edit(ws_ops.with_scale(self.workspace.editable(), k, c, v),
                                                          "Set scale", (k, "scale", c)))
        e.lobe_added.connect(lambda m: self._edit(ws_ops.with_lobe_added(self.workspace.editable(), m), f"Add {m} lobe"))
        e.model_file_requested.connect(self.add_model_file_dialog)
        e.lobe_removed.connect(lambda k: self._edit(ws_ops.with_lobe_removed(self.workspace.editable(), k), "Remove lobe"))
        e.lobe_moved.connect(lambda k, d: self._edit(ws_ops.with_lobe_moved(self.workspace.editable(), k, d), "Move lobe"))
        e.combination_changed.connect(lambda c: self._edit(ws_ops.with_combination(self.workspace.editable(), c), f"{c} combination"))
        e.channels_changed.connect(lambda n: self._edit(ws_ops.with_channels(self.workspace.editable(), n), "Channels"))
        self.object_controls.open_mesh.connect(self.open_mesh_dialog)
        self.object_controls.open_environment.connect(self.open_environment_dialog)
        self.object_controls.env_layout.textActivated.connect(lambda _: self._reopen_environment())
        for view in (self.lobe_view, self.object_view):
            view.failed.connect(self.show_error)
        e.energy_known.connect(self._editable_energy_known)
        self.object_view.ringing.connect(self._sh_ringing)
        self.object_view.table_shown.connect(self.object_controls.sh_table_note.setText)
        self.object_view.busy.connect(lambda text: self.statusBar().showMessage(text, 0 if text else 1))
        f = self.fitting
        f.fits_energy_known.connect(self._fits_energy_known)
        f.fit_requested.connect(self.start_fit)
        f.auto_requested.connect(self.start_auto)
        f.ladder_requested.connect(self.show_ladder)
        f.stop_requested.connect(self.stop_fit)
        f.refit_requested.connect(self._refit)
        f.promote_requested.connect(self._promote)
        f.lobes.currentTextChanged.connect(lambda _: self._guess_lobes_changed())
        f.strategy.currentTextChanged.connect(lambda _: self._guess_lobes_changed())

    def _default_scene(self) -> None:
        try:
            self.object_view.renderer.set_mesh(default_mesh(DEFAULT_MESH))
            self.object_view.renderer.set_environment(load_environment(data_dir("resources") / DEFAULT_ENV))
        except BRDFLabError as e:
            self.show_error(str(e))
        self.object_feed.draw()

    # --- workspace ------------------------------------------------------------------------------
    def _binning_note(self) -> None:
        """Rings around a measured highlight are the data's θh bins: said over the views."""
        source = self.workspace.original()
        step = source.theta_h_step if isinstance(source, MeasuredTable) else 1.0
        self.set_warning("bins", None if step < RING_STEP else
                         f"{source.name}: the rings around its highlight are MERL's θh bins in the data (up to "
                         f"{step:.1f}× from one bin to the next), not the renderer")

    # --- what is wrong, where the user looks ----------------------------------------------------
    def set_warning(self, topic: str, text: str | None) -> None:
        if text:
            self._warnings[topic] = text
        else:
            self._warnings.pop(topic, None)
        self._views_area.show_banner("<br>".join(f"⚠ {t}" for t in self._warnings.values()))

    def _editable_energy_known(self, summary) -> None:
        whose = "This material" if self.workspace.analytic is not None else "The initial guess"
        words = energy_words(*summary)
        self.set_warning("energy", f"{whose}: {words}" if words else None)

    def _fits_energy_known(self, summaries: list) -> None:
        bad = [(k, max(s[1])) for k, s in enumerate(summaries) if s is not None and not s[0]]
        if not bad:
            self.set_warning("fits", None)
            return
        which = ", ".join(str(k) for k, _ in bad)  # one short line however many fits
        self.set_warning("fits", f"Stored fit{'s' if len(bad) > 1 else ''} {which}: "
                                 f"{energy_words(False, [a for _, a in bad])}")

    def _check_bounds(self) -> None:
        ws = self.workspace
        found = []
        if ws.fitted() is not None:
            found += [f"fit {ws.shown_fit}, " + b for b in bound_warnings(ws.fitted())]
        if ws.analytic is not None:
            found += bound_warnings(ws.analytic, at_default=False)
        more = f" and {len(found) - 3} more" if len(found) > 3 else ""
        self.set_warning("bounds", "At a bound: " + "; ".join(found[:3]) + more if found else None)

    @Slot(float)
    def _sh_ringing(self, fraction: float) -> None:
        self.set_warning("sh", None if fraction <= 0 else
                         f"SH ringing: {fraction:.1%} of the object's pixels came out negative and were clamped "
                         "to black (raise the SH order or use the fis mode)")

    def _map_note(self, env) -> None:
        self.set_warning("map", f"Environment {env.name}: {env.note}" if getattr(env, "note", "") else None)

    @Slot(bool)
    def _clean_changed(self, clean: bool) -> None:
        self._update_title()

    @Slot(int)
    def _index_changed(self, index: int) -> None:
        self._update_title()

    def _update_title(self) -> None:
        # dirty follows the undo stack exactly: clean only at the index the file holds
        self.workspace.dirty = self._unsaved_at_clean or not self.undo_stack.isClean()
        self.setWindowTitle(f"{self.workspace.title} — BRDFLab")

    def _edit(self, new_material, text: str, merge_key=None) -> None:
        if self.workspace.editable() is None:
            return
        try:
            new_material.validate()
        except BRDFLabError as e:
            self.show_error(str(e))
            return
        self.undo_stack.push(ReplaceMaterial(self, self.workspace.editable(), new_material, text, merge_key))

    def _new_guess(self) -> None:
        """A fresh initial guess from the Fitting panel's lobes and strategy."""
        ws = self.workspace
        if ws.analytic is not None or ws.source is None:
            return
        lobes = [x.strip() for x in self.fitting.lobes.currentText().split(",") if x.strip()]
        try:
            self.document.replace_guess(material_from_lobes(lobes, self.fitting.strategy.currentText(),
                                                            ws.source.n_channels))
        except BRDFLabError as e:
            self.show_error(str(e))

    def _guess_lobes_changed(self) -> None:
        if self.workspace.analytic is None:
            self._new_guess()

    def closeEvent(self, event) -> None:
        if not self.maybe_save():
            event.ignore()
            return
        self.stop_fit()
        if self._thread is not None:
            self._thread.kill()
        self.editor.shutdown()
        self.plots.shutdown()
        self.charts.shutdown()
        QApplication.instance().removeEventFilter(self._field_guard)
        self.fitting.shutdown()
        self.lobe_feed.shutdown()
        self.object_feed.shutdown()
        self.object_view.shutdown()
        self.settings.setValue("geometry", self.saveGeometry())
        self.settings.setValue("state", self.saveState(LAYOUT_VERSION))
        self.settings.setValue("views", self.views.saveState())
        event.accept()

    def _study_scene(self) -> dict:
        """What the Charts dock measures on: the shown material (the fit when one is shown)
        and the object view's environment map."""
        from brdflab.material.analytic import AnalyticMaterial

        shown = self.workspace.fitted() or self.workspace.original()
        scene = {"environment": self.object_view.environment_map()}
        scene["material" if isinstance(shown, AnalyticMaterial) else "source"] = shown
        return scene

    def show_error(self, message: str) -> None:
        self.statusBar().showMessage(message, 20000)
        box = QMessageBox(QMessageBox.Warning, "BRDFLab", message, QMessageBox.Ok, self)
        box.setAttribute(Qt.WA_DeleteOnClose)
        box.open()  # not modal-blocking: the program keeps running
