#pragma once
/** File ▸ Open X-ray to match…: an X-ray (XA, RF, DX, CR) beside the DRR of the open study
 *  rendered with the X-ray's own geometry (core::readXrayGeometry: its C-arm per frame, detector
 *  size, pitch and principal point; the isocentre the file's, else the volume's centre), and
 *  the two laid over each other (opacity) or interleaved in a checkerboard. The DRR is the
 *  cone-beam ray caster's line integrals (the study's values), shown through its own window
 *  as a transmission image (exp(-p)) so that it reads as the radiograph does. */
#include <QDialog>
#include <QImage>

#include <memory>
#include <optional>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/core/render/cone_projector.h>
#include <fvr/core/volume.h>

class QCheckBox;
class QComboBox;
class QLabel;
class QPushButton;
class QSlider;
class QSpinBox;

namespace fvr::ui {

/** 8-bit grayscale of W x H values through their own 0.5-99.5 % window (inverted: dense dark). */
QImage grayImage(const float* values, int width, int height, bool invert);

/** The picture area: X-ray and DRR side by side, or one over the other. */
class XrayMatchCanvas : public QWidget {
    Q_OBJECT
public:
    enum class Mode { SideBySide, Overlay, Checkerboard };
    explicit XrayMatchCanvas(QWidget* parent = nullptr);
    void setImages(QImage xray, QImage drr);
    void setMode(Mode m);
    void setOpacity(double drrOpacity); ///< 0: the X-ray only, 1: the DRR only
    void setCheckerSize(int pixels);
    Mode mode() const { return m_mode; }
    /** What the canvas shows, at the X-ray's size (side by side: twice its width). */
    QImage composed() const;

protected:
    void paintEvent(QPaintEvent*) override;

private:
    QImage m_xray, m_drr;
    Mode m_mode = Mode::SideBySide;
    double m_opacity = 0.5;
    int m_checker = 32;
};

class XrayMatchDialog : public QDialog {
    Q_OBJECT
public:
    explicit XrayMatchDialog(QWidget* parent = nullptr);
    ~XrayMatchDialog() override;

    /** The study the DRR is made of, in the values `mapping` gives (the spectrum's). */
    void setStudy(std::shared_ptr<const core::Volume> volume, core::ValueMapping mapping);
    /** Reads the X-ray and renders the DRR of its first frame. False (the reason shown, and
     *  in errorText()) for a file that is no X-ray or has no usable geometry, or without a
     *  study. */
    bool openXray(const QString& path);
    /** Frame k of a multi-frame X-ray (its own C-arm). */
    void showFrame(int frame);

    const std::optional<core::XrayGeometry>& xray() const { return m_xray; }
    /** The camera of the frame shown and the DRR's line integrals (W x H). */
    const std::optional<core::DetectorImage>& drr() const { return m_drr; }
    QString errorText() const { return m_error; }
    QString warningsText() const;
    XrayMatchCanvas* canvas() const { return m_canvas; }
    QComboBox* modeCombo() const { return m_mode; }
    QSlider* opacitySlider() const { return m_opacity; }
    QSpinBox* frameSpin() const { return m_frame; }
    QCheckBox* invertCheck() const { return m_invert; }
    /** Register to X-ray…: asks for registerRequested() with the X-ray and frame shown. */
    QPushButton* registerButton() const { return m_register; }
    /** The frame shown (0-based). */
    int frame() const { return m_shownFrame; }

signals:
    /** The user asks to register the study to this X-ray's frame. */
    void registerRequested(const QString& path, int frame);

private:
    void renderDrr();
    void updateImages();

    std::shared_ptr<const core::Volume> m_volume;
    core::ValueMapping m_mapping = core::ValueMapping::Mu;
    std::unique_ptr<core::ConeProjector> m_caster;
    std::optional<core::XrayGeometry> m_xray;
    std::optional<core::DetectorImage> m_drr;
    int m_shownFrame = 0;
    QString m_error;
    XrayMatchCanvas* m_canvas = nullptr;
    QLabel* m_info = nullptr;
    QComboBox* m_mode = nullptr;
    QSlider* m_opacity = nullptr;
    QSpinBox* m_frame = nullptr;
    QCheckBox* m_invert = nullptr;
    QPushButton* m_register = nullptr;
};

} // namespace fvr::ui
