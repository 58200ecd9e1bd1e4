#pragma once
/** The workstation's main window: the projection (or 2/4 synchronised views to compare
 *  kernels), dock panels for the study, rendering, display and messages, menus, toolbar, status
 *  bar with progress and Cancel. */
#include <QMainWindow>
#include <QPointer>

#include <atomic>
#include <thread>

#include <fvr/core/xray/patient_views.h>
#include <fvr/ui/projection_view.h>
#include <fvr/ui/study.h>

class QComboBox;
class QCheckBox;
class QDoubleSpinBox;
class QSpinBox;
class QLabel;
class QPlainTextEdit;
class QProgressBar;
class QPushButton;
class QGridLayout;
class QMenu;

namespace fvr::ui {

class MainWindow : public QMainWindow {
    Q_OBJECT
public:
    explicit MainWindow(QWidget* parent = nullptr);
    ~MainWindow() override;

    StudyController& study() { return *m_study; }
    /** The views on screen (1, 2 or 4); view 0 is the main one. */
    const std::vector<ProjectionView*>& views() const { return m_views; }
    /** Opens a study as the menus do (phantom, file or DICOM folder). */
    void openStudy(const StudySource& source);
    /** Number of views side by side: 1, 2 or 4. */
    void setCompareCount(int n);
    void setDifferenceMode(bool on);
    void showPatientView(core::PatientView v);
    /** Exports; return false and report in the message panel on failure. */
    bool exportScreenshot(const QString& path);
    bool exportProjection(const QString& path); ///< .npy (float), .png (16-bit), .pfm
    bool exportSweep(const QString& folder, int frames, const core::Vec3& axis);
    /** Accuracy readout: view 1's projection against the spatial (ray-casting) projector of the
     *  same voxels and view, computed on a worker thread; the result (PSNR, relative RMSE) goes to
     *  the Messages panel and accuracyMeasured(). */
    void measureAccuracy();

signals:
    void accuracyMeasured(double psnr, double relRmse);

public:
    /** Panel controls (tests drive them like a user). */
    QComboBox* kernelCombo() const { return m_kernel; }
    QComboBox* sizeCombo() const { return m_size; }
    QComboBox* transformCombo() const { return m_transform; }
    QComboBox* oversamplingCombo() const { return m_oversampling; }
    QComboBox* valuesCombo() const { return m_values; }
    QCheckBox* deapodizeCheck() const { return m_deapodize; }
    QCheckBox* invertCheck() const { return m_invert; }
    QDoubleSpinBox* windowWidthSpin() const { return m_width; }
    QDoubleSpinBox* windowLevelSpin() const { return m_level; }
    QPlainTextEdit* messages() const { return m_messages; }
    QComboBox* outputCombo() const { return m_output; }
    QDoubleSpinBox* energySpin() const { return m_energy; }
    QDoubleSpinBox* exposureSpin() const { return m_exposure; }
    QSpinBox* depthCueSpin() const { return m_depthCue; }
    QDoubleSpinBox* sharpenSpin() const { return m_sharpen; }
    QDoubleSpinBox* sharpenRadiusSpin() const { return m_sharpenRadius; }
    QDoubleSpinBox* bandLimitSpin() const { return m_bandLimit; }
    QSpinBox* targetFpsSpin() const { return m_targetFps; }
    QCheckBox* clipCheck() const { return m_clip; }
    QComboBox* voxelModelCombo() const { return m_voxelModel; }
    QComboBox* compareSlotCombo() const { return m_compareSlot; }
    QCheckBox* pixelApertureCheck() const { return m_pixelAperture; }
    QCheckBox* nonNegativeCheck() const { return m_nonNegative; }
    /** The transmission the X-ray panel asks for (inactive for line integrals). */
    core::Transmission currentTransmission() const;
    FrameEffects currentEffects() const;
    QProgressBar* progressBar() const { return m_progress; }

protected:
    void closeEvent(QCloseEvent* e) override;
    void dragEnterEvent(QDragEnterEvent* e) override;
    void dropEvent(QDropEvent* e) override;
    void keyPressEvent(QKeyEvent* e) override;

private:
    void buildViews();
    void buildDocks();
    void buildMenus();
    void applyRenderSettings();
    /** The voxel model combo: changes only the voxel model of the views it applies to. */
    void applyVoxelModel();
    void saveVoxelModelSetting();
    /** "View 2: linear 512×512": a compare view's title. */
    QString viewTitle(int index, const ViewSettings& s) const;
    void applySpectrumSettings();
    void applyWindowFromPanel();
    void syncWindowToPanel(const core::DisplayWindow& w);
    void onStudyLoaded(const QString& name);
    void onSpectrumReady();
    void updateStudyInfo();
    void message(const QString& text, bool error = false);
    void addRecent(const QString& path);
    void rebuildRecentMenu();
    void openFileDialog();
    void openFolderDialog();
    void exportScreenshotDialog();
    void exportProjectionDialog();
    void exportSweepDialog();
    void copyToClipboard();
    void applyPreset(const QString& name);
    void applyEffects();
    void applyOutput(bool resetWindow);

    std::unique_ptr<StudyController> m_study;
    std::vector<ProjectionView*> m_views;
    std::vector<ViewSettings> m_viewSettings; // per compare slot
    QWidget* m_viewHost = nullptr;
    QGridLayout* m_viewGrid = nullptr;
    int m_compareCount = 1;
    bool m_difference = false;
    bool m_syncing = false;
    bool m_rewindow = false; ///< auto window once the next spectrum is ready (values changed)

    QComboBox* m_kernel = nullptr;
    QComboBox* m_size = nullptr;
    QComboBox* m_transform = nullptr;
    QComboBox* m_oversampling = nullptr;
    QComboBox* m_values = nullptr;
    QCheckBox* m_deapodize = nullptr;
    QComboBox* m_compareSlot = nullptr;
    QLabel* m_memory = nullptr;
    QDoubleSpinBox* m_width = nullptr;
    QDoubleSpinBox* m_level = nullptr;
    QCheckBox* m_invert = nullptr;
    QComboBox* m_output = nullptr;
    QDoubleSpinBox* m_energy = nullptr;
    QDoubleSpinBox* m_exposure = nullptr;
    QLabel* m_muWater = nullptr;
    QSpinBox* m_depthCue = nullptr;
    QDoubleSpinBox* m_sharpen = nullptr;
    QDoubleSpinBox* m_sharpenRadius = nullptr;
    QDoubleSpinBox* m_bandLimit = nullptr;
    QSpinBox* m_targetFps = nullptr;
    QCheckBox* m_clip = nullptr;
    QComboBox* m_voxelModel = nullptr;
    QCheckBox* m_pixelAperture = nullptr;
    QCheckBox* m_nonNegative = nullptr;
    QComboBox* m_preset = nullptr;
    QLabel* m_studyInfo = nullptr;
    QPlainTextEdit* m_messages = nullptr;
    QProgressBar* m_progress = nullptr;
    QPushButton* m_cancel = nullptr;
    QLabel* m_backend = nullptr;
    QMenu* m_recentMenu = nullptr;
    QAction* m_overlayAction = nullptr;
    std::thread m_accuracyWorker;
    std::atomic<bool> m_accuracyDone{true};
};

} // namespace fvr::ui
