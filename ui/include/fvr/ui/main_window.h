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

class QLabel;
class QScreen;
class QProgressBar;
class QPushButton;
class QGridLayout;
class QMenu;
class QToolBar;

namespace fvr::ui {

class AccuracyReadout;
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

signals:
    void accuracyMeasured(double psnr, double relRmse);

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
    void buildPacsMenu(QMenu* file); // main_window_pacs.cpp
    void editPacsNodes();
    void sendProjectionDialog();
    /** View 1's projection as DICOM Secondary Capture: the values the float exports hold, the
     *  source's patient and study. Throws (WriteError, or nothing to export). */
    void writeDicomProjection(const std::string& path) const;
    /** What the float exports of view 1 hold, in words for the Messages panel and the DICOM
     *  ImageComments: the transmitted intensity, the polychromatic quantity (with the tube) or
     *  the line integrals. */
    QString exportedQuantity() const;
    void buildViewMenu(QMenu* view, QToolBar* toolbar);
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
    std::unique_ptr<PacsService> m_pacs;
    QPointer<PacsDialog> m_pacsDialog;
};

} // namespace fvr::ui
