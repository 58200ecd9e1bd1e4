#pragma once
/** Register to X-ray…: the pose of the open study (core::Pose, registration/pose.h) in an X-ray's
 *  geometry, adjusted by hand and found by core::registerPose.
 *
 *  - The X-ray (core::readXrayInput: its camera at the identity pose, its values as line
 *    integrals) is shown with the DRR of the study at the current pose laid over it: the X-ray
 *    in green, the DRR in magenta (where they agree the picture is grey), or a checkerboard of
 *    the two. The DRR is the CPU cone-beam ray caster's image for
 *    posedCamera(camera, poseMatrix(pose, centre)), re-rendered whenever the pose changes.
 *  - Manual adjustment in 6 DoF: drag = translate in the detector plane, Shift+drag = rotate
 *    about the beam, Ctrl+drag = rotate about the detector's column and row directions,
 *    wheel = translate along the beam; spin boxes show and set rx, ry, rz (degrees, about the
 *    LPS axes through the centre, x first) and tx, ty, tz (mm, LPS): the offsets from the
 *    geometry the X-ray records.
 *  - Register runs core::registerPose in the background from the current pose (progress by
 *    stage, Cancel: the best pose so far, marked cancelled), then shows the overlays before and
 *    after, the similarity before and after and the time; Accept keeps the registered pose,
 *    Revert goes back to the pose before Register; Save pose… writes it (writePoseJson, about
 *    the centre).
 *  The centre is the X-ray's isocentre when the file states one, else the study's centre. */
#include <QDialog>
#include <QImage>
#include <QPointF>

#include <array>
#include <atomic>
#include <memory>
#include <optional>

#include <fvr/core/registration/registration.h>
#include <fvr/core/registration/registration_io.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/volume.h>

class QBoxLayout;
class QCheckBox;
class QDoubleSpinBox;
class QLabel;
class QProgressBar;
class QPushButton;

namespace fvr::ui {

class BackgroundJobs;

/** An X-ray with a DRR over it (X-ray green, DRR magenta; or a checkerboard of the two), which
 *  turns mouse drags and the wheel into pose steps (in detector pixels). */
class PoseCanvas : public QWidget {
    Q_OBJECT
public:
    explicit PoseCanvas(const QString& caption, QWidget* parent = nullptr);
    void setImages(QImage xray, QImage drr);
    void setCaption(const QString& caption);
    void setCheckerboard(bool on);
    void setCheckerSize(int pixels);
    /** The X-ray's size: the blend, or the checkerboard (X-ray where (col/s + row/s) is even). */
    QImage composed() const;
    /** Whether drags and the wheel are turned into poseDragged / poseWheeled. */
    void setInteractive(bool on) { m_interactive = on; }

signals:
    /** A drag of (dx, dy) detector pixels (x right, y down) with the modifiers held. */
    void poseDragged(QPointF detectorDelta, Qt::KeyboardModifiers modifiers);
    /** Wheel steps (positive: away from the user, one notch = 1). */
    void poseWheeled(double steps);

protected:
    void paintEvent(QPaintEvent*) override;
    void mousePressEvent(QMouseEvent* e) override;
    void mouseMoveEvent(QMouseEvent* e) override;
    void mouseReleaseEvent(QMouseEvent* e) override;
    void wheelEvent(QWheelEvent* e) override;

private:
    /** Where composed() is drawn in the widget. */
    QRect imageRect() const;

    QString m_caption;
    QImage m_xray, m_drr;
    bool m_checker = false;
    int m_checkerSize = 32;
    bool m_interactive = false;
    bool m_dragging = false;
    QPointF m_last;
};

class XrayRegisterDialog : public QDialog {
    Q_OBJECT
public:
    explicit XrayRegisterDialog(QWidget* parent = nullptr);
    ~XrayRegisterDialog() override;

    /** The study registered, in the values `mapping` gives (those its DRRs show). */
    void setStudy(std::shared_ptr<const core::Volume> volume, core::ValueMapping mapping);
    /** Reads frame `frame` of the X-ray (readXrayInput) and shows it at the identity pose. False
     *  (the reason in errorText()) without a study or for a file that cannot be registered to. */
    bool openXray(const QString& path, int frame = 0);

    /** The pose shown (about centre()), and its matrix. */
    core::Pose pose() const { return m_pose; }
    glm::dmat4 poseMatrix() const;
    glm::dvec3 centre() const { return m_centre; }
    /** Sets the pose (the spin boxes follow) and renders its DRR. */
    void setPose(const core::Pose& pose);
    /** One manual step, as the canvas's drag (detector pixels) and wheel give them. */
    void dragPose(QPointF detectorDelta, Qt::KeyboardModifiers modifiers);
    void wheelPose(double steps);

    /** The DRR's line integrals at the current pose (W x H of the X-ray). */
    const std::optional<core::DetectorImage>& drr() const { return m_drr; }
    const std::optional<core::XrayInput>& xray() const { return m_input; }
    QString errorText() const { return m_error; }
    /** The options Register uses (its levels, similarity, global stage); the centre, cancel flag,
     *  progress and mapping are the dialog's own. */
    core::RegistrationOptions& registrationOptions() { return m_options; }
    /** Register pressed: runs in the background. */
    void startRegistration();
    void cancelRegistration();
    bool registering() const { return m_running; }
    /** The last registration's result (cancelled or not). */
    const std::optional<core::RegistrationResult>& result() const { return m_result; }
    /** The pose before the last Register (what Revert restores). */
    core::Pose poseBeforeRegistration() const { return m_before; }
    /** Accept: the registered pose stays (and becomes what a later Revert goes back to). */
    void acceptPose();
    /** Revert: back to the pose before Register. */
    void revert();
    /** Writes the current pose (writePoseJson, about centre()); false (said) on failure. */
    bool savePose(const QString& path);

    /** rx, ry, rz (degrees), tx, ty, tz (mm). */
    QDoubleSpinBox* poseSpin(int parameter) const { return m_spins[std::size_t(parameter)]; }
    QPushButton* registerButton() const { return m_register; }
    QPushButton* cancelButton() const { return m_cancel; }
    QPushButton* acceptButton() const { return m_accept; }
    QPushButton* revertButton() const { return m_revert; }
    QPushButton* saveButton() const { return m_save; }
    QCheckBox* checkerboardCheck() const { return m_checker; }
    QProgressBar* progressBar() const { return m_progress; }
    QLabel* progressLabel() const { return m_progressText; }
    QLabel* resultLabel() const { return m_resultText; }
    PoseCanvas* canvas() const { return m_canvas; }
    PoseCanvas* beforeCanvas() const { return m_beforeCanvas; }

signals:
    /** For the Messages panel: start, finish, cancel, failures, saved files. */
    void message(const QString& text, bool error = false);
    /** A registration has ended (finished, cancelled or failed). */
    void registrationEnded();

private:
    void buildPoseControls(QBoxLayout* layout);
    void buildRunControls(QBoxLayout* layout);
    void connectControls();
    /** The pose from the spin boxes. */
    void poseFromSpins();
    void showPoseInSpins();
    void renderDrr();
    /** DRR line integrals for a pose (throws what the caster throws). */
    core::DetectorImage drrAt(const core::Pose& pose);
    void updateImages();
    void setBusy(bool busy);
    void showProgress(const core::RegistrationProgress& p);
    void finishRegistration(core::RegistrationResult r);
    void failRegistration(const QString& why, bool cancelled);
    /** Applies a rigid step S (in the X-ray's frame) after the pose: T' = S T. */
    void applyStep(const glm::dmat4& step);
    void savePoseDialog();
    QString xrayName() const;
    /** The canvases' captions: "after registration" while a registered pose awaits the user. */
    void showCaptions();

    std::shared_ptr<const core::Volume> m_volume;
    core::ValueMapping m_mapping = core::ValueMapping::Mu;
    std::unique_ptr<core::ConeProjector> m_caster;
    std::optional<core::XrayInput> m_input;
    glm::dvec3 m_centre{0.0};
    core::Pose m_pose, m_before;
    std::optional<core::DetectorImage> m_drr;
    QImage m_xrayImage, m_drrBeforeImage;
    std::optional<core::RegistrationResult> m_result;
    core::RegistrationOptions m_options;
    std::shared_ptr<std::atomic<bool>> m_cancelFlag;
    bool m_running = false;
    bool m_pending = false; ///< a registered pose awaits Accept or Revert
    QString m_error;

    PoseCanvas* m_canvas = nullptr;
    PoseCanvas* m_beforeCanvas = nullptr;
    QLabel* m_info = nullptr;
    std::array<QDoubleSpinBox*, 6> m_spins{};
    QPushButton* m_reset = nullptr;
    QPushButton* m_register = nullptr;
    QPushButton* m_cancel = nullptr;
    QPushButton* m_accept = nullptr;
    QPushButton* m_revert = nullptr;
    QPushButton* m_save = nullptr;
    QCheckBox* m_checker = nullptr;
    QProgressBar* m_progress = nullptr;
    QLabel* m_progressText = nullptr;
    QLabel* m_resultText = nullptr;
    /** Last: its jobs end before the rest of the dialog goes. */
    std::unique_ptr<BackgroundJobs> m_jobs;
};

} // namespace fvr::ui
