#pragma once
/** The workstation's main window: the projection (or 2/4 synchronised views to compare
 *  kernels), dock panels for the study, rendering, display, X-ray image and messages, menus,
 *  toolbar, status bar with progress and Cancel. The panels own their controls; the window wires
 *  their values to the views and the study controller. */
#include <QMainWindow>
#include <QPointer>
#include <map>
#include <optional>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/pacs/pacs.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/ui/measure_layer.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/projection_view.h>
#include <fvr/ui/study.h>
#include <fvr/ui/workstation_state.h>

class QLabel;
class QScreen;
class QProgressBar;
class QPushButton;
class QGridLayout;
class QMenu;
class QSettings;
class QTimer;
class QToolBar;
class QUndoStack;

namespace fvr::ui {

class AccuracyReadout;
class CineController;
struct CineSettings;
class DicomTagsDialog;
class MaterialsController;
class PacsDialog;
class PacsService;
class DisplayPanel;
class GeometryPanel;
class XrayMatchDialog;
class XrayRegisterDialog;
class MessagesPanel;
class RenderingPanel;
class SettingsModel;
class StudyPanel;
class XrayPanel;
enum class WindowPreset;

class MainWindow : public QMainWindow {
    Q_OBJECT
public:
    explicit MainWindow(QWidget* parent = nullptr);
    ~MainWindow() override;

    StudyController& study() { return *m_study; }
    /** The views on screen (1, 2 or 4); view 0 is the main one. */
    const std::vector<ProjectionView*>& views() const { return m_views; }
    /** The reader's tool the views' left button draws with (Measure menu and toolbar). */
    void setMeasureTool(MeasureTool tool);
    MeasureTool measureTool() const { return m_measureTool; }
    /** The status bar's value under the cursor (image pixel, value, units). */
    QString cursorReadout() const;
    /** Turns or mirrors the image of every view (the views turn together). */
    void turnImage(measure::Turn t);
    /** Opens a study as the menus do (phantom, file or DICOM folder). */
    void openStudy(const StudySource& source);
    /** Whether a folder of several series asks which one (off: the default series opens,
     *  as in fvr-render; scripted runs). */
    /** The window's size without saved geometry: 1400 x 900 or 95% of `screen`'s free area,
     *  whichever is less. */
    static QSize defaultWindowSize(const QScreen* screen);
    /** Makes the window fit `available` (the screen's free area): the right column's panels and
     *  Messages become tabs of one group where their column is too tall, and the size is bounded
     *  by it. Called for the window's screen when it is made. */
    void fitInto(const QSize& available);
    void setAskForSeries(bool ask) { m_askForSeries = ask; }
    /** Number of views side by side: 1, 2 or 4. */
    void setCompareCount(int n);
    void setDifferenceMode(bool on);
    void showPatientView(core::PatientView v);
    /** Exports (export_actions.cpp); return false and report in the message panel on failure. */
    bool exportScreenshot(const QString& path);
    /** `w` (the window, or the view area) as on screen. QWidget::grab() alone loses what the
     *  views paint over their image (overlay, orientation labels, titles): each view's own
     *  framebuffer is drawn over it. */
    QImage grabWithViews(QWidget* w) const;
    bool exportProjection(const QString& path); ///< .npy (float), .png (16-bit), .pfm
    bool exportSweep(const QString& folder, int frames, const core::Vec3& axis);
    /** Where export dialogs start: the last export folder, else Pictures, else home; never the
     *  study's own folder (Enter would write into the source data). */
    static QString exportFolder();
    /** Accuracy readout (AccuracyReadout): view 1's projection against the spatial (ray-casting)
     *  projector of the same voxels and view, on a worker thread; the result (PSNR, relative
     *  RMSE) goes to the Messages panel and accuracyMeasured(). */
    void measureAccuracy();
    /** Cine (cine_actions.cpp): the views turn by a step per tick (Cine menu, Space). */
    CineController& cine() { return *m_cine; }
    /** One full turn of the cine from view 1's current frame (360 / step frames, the cine's
     *  axis and frame rate) as an MP4 (H.264) movie of view 1 through its window, with progress
     *  and Cancel. False (and the reason in the messages) on failure or cancel. */
    bool exportMovie(const QString& path);
    /** The same frames as Multi-frame Grayscale Word Secondary Capture: the values the float
     *  exports hold, FrameTime = 1000 / frame rate, the study's patient and study fields. */
    bool exportCineDicom(const QString& path);
    /** Study ▸ DICOM tags…: the tag browser of the open series (made once, shown). */
    DicomTagsDialog* showDicomTags();

    /** PACS (main_window_pacs.cpp): the local store, listener and sends. */
    PacsService& pacs() { return *m_pacs; }
    /** File ▸ PACS…: the dialog, made once and kept (its results survive closing it). */
    PacsDialog* pacsDialog();
    /** File ▸ Send projection to PACS: view 1's projection as the .dcm export writes it
     *  (Secondary Capture, in the source's study when it came from DICOM), sent to `node` on a
     *  worker thread; the outcome goes to the Messages panel and PacsService::sent(). False
     *  when there is nothing to send or the file could not be written. */
    bool sendProjection(const core::pacs::Node& node);

    /** The render settings (the one source of truth the panels show). */
    SettingsModel& settings() { return *m_model; }
    /** View ▸ Use a software GPU (tests). */
    QAction* softwareGpuAction() const { return m_softwareGpuAction; }
    /** View ▸ Performance overlay (tests). */
    QAction* overlayAction() const { return m_overlayAction; }
    /** The panels (tests drive their controls like a user). */
    StudyPanel* studyPanel() const { return m_studyPanel; }
    RenderingPanel* renderingPanel() const { return m_rendering; }
    DisplayPanel* displayPanel() const { return m_display; }
    XrayPanel* xrayPanel() const { return m_xray; }
    GeometryPanel* geometryPanel() const { return m_geometry; }
    /** File ▸ Open X-ray to match…: the X-ray beside the DRR of its geometry (the dialog,
     *  shown; the reason in the messages when the file cannot be matched). */
    XrayMatchDialog* matchXray(const QString& path);
    /** File ▸ Register to X-ray…: the study's pose in the X-ray's geometry, by hand and by
     *  registration (the dialog, shown; its start, end and cancel in the messages). */
    XrayRegisterDialog* registerXray(const QString& path, int frame = 0);
    MessagesPanel* messages() const { return m_messages; }
    QProgressBar* progressBar() const { return m_progress; }
    QPushButton* cancelButton() const { return m_cancel; }
    /** The transmission the X-ray panel asks for (inactive for line integrals). */
    core::Transmission currentTransmission() const;
    /** The per-frame effects of the Rendering and X-ray panels. */
    FrameEffects currentEffects() const;

    /** What is on screen as data (main_window_state.cpp): the settings, each compare slot's,
     *  the orientation, each view's window, zoom and pan. */
    WorkstationState currentState() const;
    /** Shows `state` (undo/redo and sessions): the compare views, the settings (new spectra
     *  are prepared where they need it), the orientation, windows, zoom and pan. */
    void applyState(const WorkstationState& state);
    /** Edit ▸ Undo/Redo: the user's changes to the view, window and settings, a burst of
     *  changes (a drag, the wheel, a spin box held down) as one step. */
    QUndoStack* undoStack() const { return m_undo; }
    void undo();
    void redo();
    /** A change still settling is recorded now (tests, and before an undo). */
    void flushStateChange();
    /** File ▸ Save session: the study, the state and (through savingSession) the annotations,
     *  as an INI file. False, with the reason in the Messages panel, when there is no study or
     *  the file cannot be written. */
    bool saveSession(const QString& path);
    /** File ▸ Open session: opens its study, then shows its state (sessionRestored()). False,
     *  with the file and the reason in the Messages panel, for a file that is not a session. */
    bool openSession(const QString& path);
    /** The keys: every view turns as a drag would (arrows: 5°, PageUp/PageDown: 90°). */
    void rotateViews(double horizontalDeg, double verticalDeg);
    /** The keys + and −: every view's zoom times `factor`. */
    void zoomViews(double factor);
    /** A window preset of the user's: a name, the window, and the quantity it was set on
     *  (main_window_presets.cpp). */
    struct UserPreset {
        QString name;
        double low = 0.0, high = 1.0;
        QString quantity; ///< windowQuantity() when saved: "mm", "−ln(I/I0)", "log exposure"
    };
    QList<UserPreset> userPresets() const;
    /** Display ▸ Save preset…: view 1's window under `name` for the quantity on screen
     *  (replacing one of the same name and quantity). */
    bool saveWindowPreset(const QString& name);
    /** Applies user preset `index`; refused, with the reason in the messages, where the view
     *  shows another quantity than the preset's. */
    bool applyUserPreset(int index);
    void deleteUserPreset(int index);
    /** What the window applies to on view 1: its units, or the log exposure of a transmission
     *  output. */
    QString windowQuantity() const;
    /** File ▸ Open prior…: another study beside this one (main_window_prior.cpp), in view 2
     *  (compare mode), turned with view 1 as the same view of the patient, rendered with view
     *  1's settings and window. Its progress and errors go to the Messages panel; priorReady()
     *  once it shows. */
    void openPrior(const StudySource& source);
    void closePrior();
    /** A prior is loaded and shown in view 2. */
    bool hasPrior() const;
    const StudyController* prior() const { return m_prior.get(); }
    /** Help ▸ About's text: name, version, commit, and that it is not for diagnostic use. */
    static QString aboutText();
    /** Help ▸ Keyboard shortcuts: every menu action with a shortcut ("Undo", "Ctrl+Z") and
     *  the mouse's gestures, as the dialog lists them. */
    QList<QPair<QString, QString>> shortcutList() const;

signals:
    void accuracyMeasured(double psnr, double relRmse);
    /** A session is being written / was read: what else it keeps (the annotations) goes in or
     *  comes out of `s`. */
    void savingSession(QSettings& s);
    void sessionOpened(QSettings& s);
    /** An opened session's study is loaded and its state shown. */
    void sessionRestored();
    /** A prior's spectrum is ready and view 2 shows it. */
    void priorReady();
    /** Something on screen changed (the Edit menu's state follows). */
    void stateChangeNoted();

protected:
    void closeEvent(QCloseEvent* e) override;
    void dragEnterEvent(QDragEnterEvent* e) override;
    void dropEvent(QDropEvent* e) override;

private:
    void buildViews();
    void buildDocks();
    void buildStatusBar();
    void connectStudy();
    void connectPanels();
    /** The model's change signals to the window's actions. */
    void connectSettings();
    void restorePanels();
    void buildMenus(); // main_window_menus.cpp
    // main_window_state.cpp and main_window_reading.cpp
    void buildUndo();
    void buildEditMenu();
    void buildNavigation(QMenu* view);
    void buildPanelsMenu(QMenu* view);
    void buildHelpMenu();
    void showShortcutsDialog();
    /** What a change is about: changes of one kind in a burst are one undo step; a user's
     *  change of another kind ends the step before it (a new output, then a drag: two steps). */
    enum class ChangeKind { View, Window, Settings, Mode };
    /** A change to what is on screen: a user's (an undo step once it settles) or not (an
     *  automatic window: absorbed into the state undo returns to). */
    void noteStateChange(bool byUser, ChangeKind kind);
    void recordState();
    /** After a study loaded: an opened session's state, and an empty undo history. */
    void startStudyHistory();
    void connectUserPresets();
    /** Two views show the same quantity (units), so one window suits both (a prior of other
     *  values keeps its own); a view without a study yet: yes. */
    static bool sameQuantity(const ProjectionView& a, const ProjectionView& b);
    /** View 2 shows the prior, if there is one (assignSpectra). */
    bool assignPrior();
    /** `frame` of view `from` as view `to` shows it: the same patient view in its volume. */
    core::ViewFrame linkedFrame(const ProjectionView* from, const ProjectionView* to,
                                const core::ViewFrame& frame) const;
    void openPriorDialog();
    void storeUserPresets(const QList<UserPreset>& presets);
    void applyPendingSession();
    void saveSessionDialog();
    void openSessionDialog();
    void buildPacsMenu(QMenu* file); // main_window_pacs.cpp
    void editPacsNodes();
    /** Quitting while retrieves wait or run: asks first (a question box named
     *  "confirmQuitRetrieves"); true to quit. */
    bool confirmQuitDuringRetrieves();
    void sendProjectionDialog();
    /** View 1's projection as DICOM Secondary Capture: the values the float exports hold, the
     *  source's patient and study. Throws (WriteError, or nothing to export). */
    void writeDicomProjection(const std::string& path) const;
    /** What view 1's DICOM exports say: the source's patient and study, the exported quantity,
     *  the user's window and a new series (the pixels get currentTransmission() where active). */
    core::DicomExportInfo dicomExportInfo() const;
    /** What the float exports of view 1 hold, in words for the Messages panel and the DICOM
     *  ImageComments: the transmitted intensity, the polychromatic quantity (with the tube) or
     *  the line integrals. */
    QString exportedQuantity() const;
    void buildViewMenu(QMenu* view, QToolBar* toolbar);
    /** The Study and Cine menus and the Cine toolbar (cine_actions.cpp). */
    void buildReaderMenus();
    /** View 1 rendered at every frame of one cine turn (progress, Cancel); view 1 is back at
     *  its frame after. Empty when cancelled or failed (the reason in the messages). */
    std::vector<core::ProjectionImage> renderCineTurn(const QString& what);
    /** The Measure menu and toolbar, the status bar's readout (main_window_measure.cpp). */
    void buildMeasureMenu();
    /** A new view draws with the current tool and reports the value under the cursor. */
    void attachMeasure(ProjectionView* v);
    /** View 1's image values with its annotations burned in at the value the window shows
     *  brightest (the 16-bit PNG export). */
    std::vector<float> withAnnotations(const core::ProjectionImage& image) const;
    /** View 1's annotations as a DICOM overlay plane of its image (empty: none). */
    core::DicomOverlay annotationOverlay(int width, int height) const;
    ProjectionView* addView(int index, int count, const core::ViewFrame& frame);
    void connectView(ProjectionView* v);
    /** The status bar's renderer (GPU, CPU, and why) and a view's backend notice. */
    void showBackend(const ProjectionView& v, bool gpu, const QString& notice);
    /** Tells the study controller the compare views' kernels (`retry`: also those whose
     *  spectrum was not prepared), then assignSpectra(). */
    void updateCompareKernels(bool retry = false);
    /** Each view gets the spectrum that renders its kernel at the settings in effect, or says
     *  why it waits. */
    void assignSpectra();
    /** The Rendering panel's memory readout: all spectra in use. */
    void updateSpectrumMemory();
    void applyRenderSettings();
    /** The voxel model combo: changes only the voxel model of the views it applies to. */
    void applyVoxelModel();
    /** The Geometry panel (main_window_geometry.cpp): its projection, distances and ray model
     *  go to the views the Rendering panel's "Applies to" names (in compare mode a parallel
     *  view can stand beside a cone-beam one); saved at once. */
    void restoreGeometryPanel();
    void connectGeometry();
    void applyGeometry();
    /** The panel's angles: every view turns to that C-arm (they are synchronised). */
    void applyCArmAngles(double primaryDeg, double secondaryDeg);
    /** Shows a view frame's C-arm angles in the panel. */
    void showCArmAngles(const core::ViewFrame& frame);
    /** The Rendering panel's settings, with view 1's voxel model (the startup setting). */
    void saveRenderingSettings();
    /** "View 2: linear 512×512": a compare view's title. */
    QString viewTitle(int index, const ViewSettings& s) const;
    /** Difference mode: every difference view windowed with one symmetric scale, the largest
     *  |difference| of them (errors 7x apart look 7x apart). */
    void applySharedDifferenceScale();
    /** What the overlays say in Difference mode about progressive refinement (it is off). */
    QString differenceProgressiveNote() const;
    /** The spectrum settings the Rendering panel asks for. */
    SpectrumSettings spectrumSettingsFromPanel() const;
    void applySpectrumSettings();
    void applyValueMapping();
    void applyWindowFromPanel();
    void syncWindowToPanel(const core::DisplayWindow& w, WindowPreset from);
    /** The Rendering panel shows the spectrum in use (values, transform, oversampling, and with
     *  `withGridding` the gridding correction) and its memory. */
    void showSpectrumSettingsInEffect(bool withGridding);
    void onStudyLoaded(const QString& name);
    void onSpectrumReady();
    void updateStudyInfo();
    void showProgress(bool on);
    void message(const QString& text, bool error = false);
    void addRecent(const QString& path);
    void rebuildRecentMenu();
    void openFileDialog();
    void openFolderDialog();
    void openXrayMatchDialog();
    /** The X-ray the match dialog shows, else one asked for. */
    void openRegisterDialog();
    void exportScreenshotDialog();
    void exportProjectionDialog();
    void exportSweepDialog();
    void copyToClipboard();
    void applyPreset(WindowPreset preset);
    void applyEffects();
    void applyOutput(bool resetWindow);
    /** The Rendering panel (through the model) shows a view's kernel, size and voxel model. */
    void showViewSettings(const ViewSettings& s);
    /** The X-ray panel shows another output (the caller applies it). */
    void showOutput(XrayOutput o);
    // The polychromatic output (main_window_poly.cpp).
    /** On: the material spectra of the study's volume (m_materials prepares them once per
     *  volume), then pushPolychromatic(); off: the views' own spectra again. */
    void applyPolychromatic();
    /** The views get the material spectra with the response of the X-ray values (no
     *  preprocessing: kVp, filtration, detector, noise, what is shown). */
    void pushPolychromatic();
    /** The materials controller's outcomes to the X-ray panel, the messages and the views. */
    void connectMaterials();

    std::unique_ptr<StudyController> m_study;
    SettingsModel* m_model = nullptr; ///< child of the window
    std::vector<ProjectionView*> m_views;
    std::vector<ViewSettings> m_viewSettings; // per compare slot
    QWidget* m_viewHost = nullptr;
    QGridLayout* m_viewGrid = nullptr;
    int m_compareCount = 1;
    bool m_difference = false;
    bool m_syncing = false;
    bool m_askForSeries = true;
    bool m_rewindow = false; ///< auto window once the next spectrum is ready (values changed)
    /** The material spectra of the study (its job ends before the views go). */
    std::unique_ptr<MaterialsController> m_materials;
    bool m_polyRewindow = false;
    /** The sources the views get (per key), made for the X-ray values m_polyValues. */
    std::map<int, std::shared_ptr<const PolychromaticSource>> m_polySources;
    std::optional<XrayPanel::Values> m_polyValues;
    /** The key of the material spectra a kernel renders from. */
    int polyKey(core::Kernel kernel) const;

    StudyPanel* m_studyPanel = nullptr;
    RenderingPanel* m_rendering = nullptr;
    DisplayPanel* m_display = nullptr;
    XrayPanel* m_xray = nullptr;
    GeometryPanel* m_geometry = nullptr;
    XrayMatchDialog* m_xrayMatch = nullptr; ///< child of the window, made on first use
    XrayRegisterDialog* m_register = nullptr; ///< child of the window, made on first use
    MessagesPanel* m_messages = nullptr;
    QProgressBar* m_progress = nullptr;
    QPushButton* m_cancel = nullptr;
    QLabel* m_backend = nullptr;
    QLabel* m_cursorLabel = nullptr; ///< the value under the cursor
    MeasureTool m_measureTool = MeasureTool::Pointer;
    std::map<MeasureTool, QAction*> m_measureActions;
    QMenu* m_recentMenu = nullptr;
    QAction* m_overlayAction = nullptr;
    QAction* m_softwareGpuAction = nullptr;
    std::unique_ptr<AccuracyReadout> m_accuracy;
    CineController* m_cine = nullptr; ///< child of the window
    QPointer<DicomTagsDialog> m_tags;
    std::unique_ptr<PacsService> m_pacs;
    QAction* m_differenceAction = nullptr;
    QAction* m_undoAction = nullptr;
    QAction* m_redoAction = nullptr;
    QUndoStack* m_undo = nullptr;
    QTimer* m_stateTimer = nullptr;
    WorkstationState m_recorded; ///< the state the next undo step starts from
    bool m_userChange = false;
    ChangeKind m_pendingKind = ChangeKind::View;
    WorkstationState m_lastOfStep; ///< the state after the pending step's last change
    bool m_applyingState = false;
    std::unique_ptr<StudyController> m_prior; ///< a prior beside the study (view 2)
    std::optional<WorkstationState> m_pendingSession; ///< shown once its study is loaded
    QString m_pendingSessionPath;
    QPointer<PacsDialog> m_pacsDialog;
};

} // namespace fvr::ui
