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
from brdflab.io.xmlio import to_text
from brdflab.gui.gl_views import LobeView, ObjectView
from brdflab.gui.auto_ladder import AutoLadderPanel
from brdflab.gui.auto_lighting import chosen, choose_job
from brdflab.gui.background import AutoFitProcess, FitProcess, LatestOnly
from brdflab.gui.charts import ChartsPanel
from brdflab.gui.commands import ReplaceMaterial
from brdflab.gui.document import ShownDocument
from brdflab.gui.documents import DocumentFiles
from brdflab.gui.fit_control import FitControl
from brdflab.gui.window_actions import WindowActions
from brdflab.gui.fields import FieldGuard
from brdflab.gui.window_layout import ColumnKeeper
from brdflab.gui.panels import (AUTO_LEVEL_TOLERANCE, PENDING_STYLE, SHOWN, WARNING_STYLE, FittingPanel, LobeControls,
                                MaterialEditor, ObjectControls, PlotsPanel, XmlView, auto_level_job, energy_summaries,
                                refine_job, scrolling)
from brdflab.fitting.diagnosis import bound_warnings, energy_words
from brdflab.gui.panels import sh_table_request

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
        self._candidate = None
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
        self._fit_history: list[tuple[int, float]] = []  # (iteration, error) of the running or last fit

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
        self._fits_energy_job = LatestOnly(energy_summaries, self)
        self._fits_energy_job.done.connect(self._fits_energy_known)
        self._auto_level_for = None  # what the auto subdivision was last computed for
        self._auto_level_job = LatestOnly(auto_level_job, self)
        self._auto_level_job.done.connect(self._auto_level_known)
        self._auto_level_job.failed.connect(lambda m: self.lobe_controls.auto_level_note.setText(f"failed: {m}"))
        self._refine_for: tuple | None = None  # (key, sources) the refined lobe surface was last asked for
        self._refine_job = LatestOnly(refine_job, self)
        self._refine_job.done.connect(self._refined_known)
        self._refine_job.failed.connect(self.show_error)
        self._auto_lighting_for: tuple | None = None  # (source, map, tolerance) the last choice was asked for
        self._auto_lighting_token = 0  # numbers the requests: an answer to an older one is dropped
        self._auto_choice = None  # the lighting.auto.LightingChoice the object view draws with
        self._auto_lighting_job = LatestOnly(choose_job, self)
        self._auto_lighting_job.done.connect(self._auto_lighting_known)
        self._auto_lighting_job.failed.connect(
            lambda m: self.object_controls.show_auto_note(f"auto: the choice failed: {m}", style=WARNING_STYLE))

        self._xml_timer = QTimer(self, singleShot=True, interval=150)
        self._xml_timer.timeout.connect(self._refresh_xml)
        self._xml_stale = False
        self._docks["XML"].visibilityChanged.connect(self._xml_dock_shown)
        self._plot_timer = QTimer(self, singleShot=True, interval=250)
        self._plot_timer.timeout.connect(self._refresh_plots)
        # a running fit reaches the object view twice a second, not at every report (each
        # restarted its image before it had more than a sample: 60–330 ms of GL per restart)
        self._fit_view_timer = QTimer(self, singleShot=True, interval=500)
        self._fit_view_timer.timeout.connect(self._show_fit_progress_on_object)
        self._build_menus()
        self._connect()
        self.plots.follow(self.document)
        self.document.switched.connect(self._forget_closed_document)
        self.document.material_changed.connect(self.material_changed)
        self.document.fittings_changed.connect(self.fittings_changed)
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
        self._object_settings_changed()
        self.set_workspace(self.workspace)
        self.load_model_folders()

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
        self.lobe_controls.changed.connect(self._lobe_settings_changed)
        self.lobe_view.incident_changed.connect(self._drag_incident)
        self.object_controls.changed.connect(self._object_settings_changed)
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
        f.fit_requested.connect(self.start_fit)
        f.auto_requested.connect(self.start_auto)
        f.ladder_requested.connect(self.show_ladder)
        f.stop_requested.connect(self.stop_fit)
        f.fit_selected.connect(self._select_fit)
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
        self._push_object_source()

    # --- workspace ------------------------------------------------------------------------------
    def _binning_note(self) -> None:
        """Rings around a measured highlight are the data's θh bins: said over the views."""
        source = self.workspace.original()
        step = source.theta_h_step if isinstance(source, MeasuredTable) else 1.0
        self.set_warning("bins", None if step < RING_STEP else
                         f"{source.name}: the rings around its highlight are MERL's θh bins in the data (up to "
                         f"{step:.1f}× from one bin to the next), not the renderer")

    def material_changed(self) -> None:
        ws = self.workspace
        if ws.analytic is None and ws.guess is None and ws.source is not None:
            self._new_guess()
        self.editor.show_material(ws.editable())
        self.editor.setToolTip("" if ws.analytic is not None else
                               "Measured material: you are editing the initial guess of the next fit")
        self._push_lobe_sources()
        self._push_object_source()
        self._refresh_text()
        self._check_bounds()

    def fittings_changed(self) -> None:
        ws = self.workspace
        self.fitting.show_fits(ws.document.fittings, ws.shown_fit)
        self._fits_energy_job.request([f.material for f in ws.document.fittings])
        self._check_bounds()
        self._push_lobe_sources()
        self._push_object_source()
        self._refresh_text()

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
        fittings = self.workspace.document.fittings
        if len(summaries) != len(fittings):
            return  # an answer about fits that have changed since: a newer request is on its way
        self.fitting.show_fits(fittings, self.workspace.shown_fit, summaries)
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

    def _refresh_text(self) -> None:
        self._update_title()
        self._xml_timer.start()  # coalesced: rapid edits rewrite the XML text once
        self._plot_timer.start()

    def _refresh_xml(self) -> None:
        """The XML text, only while someone can see it (it costs a serialisation)."""
        self._xml_stale = not (self._docks["XML"].isVisible() or self.xml.toPlainText() == "")
        if not self._xml_stale:
            self.xml.setPlainText(to_text(self.workspace.document))

    @Slot(bool)
    def _xml_dock_shown(self, shown: bool) -> None:
        if shown and self._xml_stale:
            self._refresh_xml()

    def _refresh_plots(self) -> None:
        try:
            self.plots.show_sources(self.workspace.original(), self._candidate or self.workspace.fitted(),
                                    self.lobe_view.viewer.settings.theta_i if self.lobe_view.ctx else 30.0,
                                    self._fit_history)
        except BRDFLabError as e:
            self.show_error(str(e))

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
            ws.guess = material_from_lobes(lobes, self.fitting.strategy.currentText(), ws.source.n_channels)
        except BRDFLabError as e:
            self.show_error(str(e))

    def _guess_lobes_changed(self) -> None:
        if self.workspace.analytic is None:
            self._new_guess()
            self.editor.show_material(self.workspace.editable())
            self._push_lobe_sources()

    def _shown_fit_or_guess(self):
        ws = self.workspace
        if self._candidate is not None:
            return self._candidate
        if ws.analytic is None and (ws.shown_fit is None or self.fitting.fits.currentRow() < 0):
            return ws.guess  # the initial guess, drawn over the measured original
        return ws.fitted()

    def _lobe_labels(self, original, fitted) -> list[str]:
        """What the lobe viewer's legend calls the original and the material drawn over it:
        the stored fit by its number in the Fitting panel's list, a running fit, or the next
        fit's initial guess."""
        ws = self.workspace
        name = getattr(original, "name", "")
        first = f"original: {name}" if name else "original"
        if fitted is None:
            return [first, ""]
        lobes = "+".join(fitted.lobe_models())  # as the list names a fit
        if fitted is self._candidate:
            return [first, f"fit running: {lobes}"]
        if fitted is ws.guess and ws.analytic is None:
            return [first, f"initial guess: {lobes}"]
        return [first, f"fit {ws.shown_fit}: {lobes}"]

    def _push_lobe_sources(self) -> None:
        original, fitted = self.workspace.original(), self._shown_fit_or_guess()
        labels = self._lobe_labels(original, fitted)

        def apply():
            v = self.lobe_view.viewer
            v.labels = labels
            if original is not None and isinstance(original, ws_ops.AnalyticMaterial):
                v.update_material(0, original)
            else:
                v.set_original(original)
            if fitted is not None:
                v.update_material(1, fitted)
            else:
                v.set_fitted(None)

        self.lobe_view.when_ready(apply)
        self._request_auto_level()
        self._request_refined_surface()

    def _push_object_source(self) -> None:
        shown = self.workspace.original()
        choice = self.object_controls.shown.currentText()
        fit = self._candidate or self.workspace.fitted()
        if choice == "fitted":
            shown = fit or shown
        self.object_view.compare = SHOWN[choice] if fit is not None and shown is not None else "off"
        self.object_view.compare_source = fit
        if self.object_view.ctx is None:
            return
        self.object_view.blank = shown is None or (isinstance(shown, ws_ops.AnalyticMaterial) and not shown.lobes)
        if self.object_view.blank:  # an empty material is valid: nothing to shade
            self.object_view.update()
            self._request_auto_lighting()
            return

        def apply():
            try:
                self.object_view.renderer.set_source(shown)
            except BRDFLabError as e:
                self.show_error(str(e))

        self.object_view.when_ready(apply)
        self.object_view.restart()
        self._request_auto_lighting()

    def _lobe_settings_changed(self) -> None:
        self.lobe_controls.apply(self.lobe_view.viewer.settings)
        self.lobe_view.update()
        self._plot_timer.start()
        self._request_auto_level()
        self._request_refined_surface()

    def _request_refined_surface(self) -> None:
        """The lobe viewer's surface refined near the analytic lobes' peaks, in a worker process
        (the newest request wins); the uniform hemisphere is drawn meanwhile."""
        def ask() -> None:
            viewer = self.lobe_view.viewer
            key, sources = viewer.surface_key(), viewer.analytic_sources()
            if sources and (self._refine_for is None or key != self._refine_for[0]):
                self._refine_for = (key, sources)  # held: the ids in the key stay theirs
                self._refine_job.request((key, sources, viewer.settings.shape, viewer.settings.level))

        self.lobe_view.when_ready(ask)

    def _refined_known(self, result: tuple) -> None:
        self.lobe_view.when_ready(lambda: self.lobe_view.viewer.set_refined(*result))

    def _request_auto_level(self) -> None:
        """Auto subdivision: recompute the level when what is drawn changes (not when the
        level itself does), in a worker process; the newest request wins."""
        if not self.lobe_controls.auto_level.isChecked():
            self._auto_level_for = None
            return
        sources = (self.workspace.original(), self._shown_fit_or_guess())
        shape = self.lobe_view.viewer.settings.shape
        key = (tuple(id(s) for s in sources), shape)
        if key != self._auto_level_for:
            self._auto_level_for = key
            self.lobe_controls.auto_level_note.setText("checking…")
            self._auto_level_job.request((sources, shape, AUTO_LEVEL_TOLERANCE))

    def _auto_level_known(self, result: tuple[int, float]) -> None:
        level, error = result
        if self.lobe_controls.auto_level.isChecked():
            self.lobe_controls.auto_level_note.setText(f"level {level}: {error:.1%} of the peak")
            self.lobe_controls.level.setValue(level)

    def _drag_incident(self, theta: float, phi: float) -> None:
        self.lobe_controls.theta.set_value(theta)
        self.lobe_controls.phi.set_value(phi)
        self._lobe_settings_changed()

    def _object_settings_changed(self) -> None:
        self._apply_object_settings()
        self._push_object_source()

    def _apply_object_settings(self) -> None:
        """The controls into the object view's settings; with auto, the mode is the choice's
        (until the first choice arrives, the view keeps the mode it had)."""
        c, v = self.object_controls, self.object_view
        s = v.settings
        if not c.auto:
            s.mode = c.mode.currentText()
        elif self._auto_choice is not None:
            s.mode = self._auto_choice.mode
        s.samples = c.samples.value()
        s.env_rotation = c.rotation.spin.value()
        s.light = c.light()
        v.exposure = c.exposure.spin.value()
        v.gamma = c.gamma.value()
        order, shadows, variant = c.sh_order.value(), c.sh_shadows.isChecked(), c.sh_variant.currentText()
        table = sh_table_request(c.sh_table.currentText())

        def apply_sh():
            v.renderer.set_sh_order(order)
            v.renderer.set_sh_table(table)
            v.renderer.sh_shadows = shadows
            v.renderer.sh_variant = variant

        v.when_ready(apply_sh)
        v.reinhard = c.reinhard.isChecked()

    def _request_auto_lighting(self) -> None:
        """Auto lighting: choose again (in a worker process; the newest request wins) when the
        drawn source, the map or the tolerance changed — not when the choice itself did."""
        c, v = self.object_controls, self.object_view
        if not c.auto:
            self._auto_lighting_for = self._auto_choice = None
            self.set_warning("auto", None)
            return
        r = getattr(v, "renderer", None)  # none before OpenGL starts: the default scene asks again
        unable = None
        if r is None or v.blank or r.source is None:
            unable = ("auto: nothing to light", PENDING_STYLE)
        elif r.environment is None:
            unable = ("auto: no environment map to light with", WARNING_STYLE)
        if unable is not None:
            self._auto_lighting_for = None
            self.set_warning("auto", None)
            c.show_auto_note(unable[0], style=unable[1])
            return
        key = (r.source, r.environment, c.tolerance.value())
        old = self._auto_lighting_for
        if old is not None and old[0] is key[0] and old[1] is key[1] and old[2] == key[2]:
            return
        self._auto_lighting_for = key
        self._auto_lighting_token += 1
        c.show_auto_note("auto: choosing the lighting for this material and map… (the view keeps its last "
                         "setting meanwhile)", style=PENDING_STYLE)
        # the renderer's own proxy lobes for a measured source, as the command line passes them
        self._auto_lighting_job.request((self._auto_lighting_token, r.source, r.environment, key[2] / 100, r.material))

    def _auto_lighting_known(self, result: tuple) -> None:
        token, choice = result
        c, v = self.object_controls, self.object_view
        if token != self._auto_lighting_token or not c.auto:
            return
        self._auto_choice = choice
        c.show_auto_choice(choice)
        self.set_warning("auto", None if choice.within else
                         f"Auto lighting: nothing is predicted within {100 * choice.tolerance:g} %; drawing the best "
                         f"predicted, {chosen(choice).label} ({100 * choice.predicted_error:.1f} %)")
        before = self._lighting_drawn()
        self._apply_object_settings()
        if self._lighting_drawn() != before:  # the same setting keeps its accumulated samples
            v.restart()

    def _lighting_drawn(self) -> tuple:
        """The object view's lighting: mode, samples and (SH) the renderer's order."""
        s, r = self.object_view.settings, self.object_view.renderer
        return s.mode, s.samples, r.sh_order if s.mode == "sh" else None

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
        self._fits_energy_job.shutdown()
        self._auto_level_job.shutdown()
        self._refine_job.shutdown()
        self._auto_lighting_job.shutdown()
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
        renderer = getattr(self.object_view, "renderer", None)  # none before OpenGL starts
        scene = {"environment": renderer.environment if renderer is not None else None}
        scene["material" if isinstance(shown, AnalyticMaterial) else "source"] = shown
        return scene

    def show_error(self, message: str) -> None:
        self.statusBar().showMessage(message, 20000)
        box = QMessageBox(QMessageBox.Warning, "BRDFLab", message, QMessageBox.Ok, self)
        box.setAttribute(Qt.WA_DeleteOnClose)
        box.open()  # not modal-blocking: the program keeps running
