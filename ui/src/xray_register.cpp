// Register to X-ray…: the canvas, the dialog's controls, the manual pose and its DRR
// (xray_register.h; the registration run, Accept, Revert and Save are in xray_register_run.cpp).
#include <fvr/ui/xray_register.h>

#include <QApplication>
#include <QCheckBox>
#include <QDoubleSpinBox>
#include <QFileInfo>
#include <QGridLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QMouseEvent>
#include <QPainter>
#include <QProgressBar>
#include <QPushButton>
#include <QVBoxLayout>
#include <QWheelEvent>

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>

#include <fvr/core/dicom/xray_geometry.h>
#include <fvr/ui/background_job.h>
#include <fvr/ui/xray_match.h>

namespace fvr::ui {

namespace {

/** Degrees per screen pixel of a rotating drag, mm per wheel notch. */
constexpr double kDegPerPixel = 0.25;
constexpr double kMmPerNotch = 2.0;

/** The unit beam direction of a camera: the detector's normal, pointing away from the source. */
glm::dvec3 beamAxis(const core::ConeCamera& cam) {
    glm::dvec3 n = glm::normalize(glm::cross(cam.u, cam.v));
    if (glm::dot(n, cam.detectorCentre - cam.source) < 0.0) n = -n;
    return n;
}

/** A rotation by `deg` about `axis` through `pivot`, as a 4x4. */
glm::dmat4 rotationAbout(const glm::dvec3& pivot, const glm::dvec3& axis, double deg) {
    glm::dmat4 m = glm::translate(glm::dmat4(1.0), pivot);
    m = glm::rotate(m, glm::radians(deg), axis);
    return glm::translate(m, -pivot);
}

} // namespace

PoseCanvas::PoseCanvas(const QString& caption, QWidget* parent)
    : QWidget(parent), m_caption(caption) {
    setMinimumSize(360, 300);
    setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
}

void PoseCanvas::setImages(QImage xray, QImage drr) {
    m_xray = std::move(xray);
    m_drr = std::move(drr);
    update();
}

void PoseCanvas::setCaption(const QString& caption) {
    m_caption = caption;
    update();
}

void PoseCanvas::setCheckerboard(bool on) {
    m_checker = on;
    update();
}

void PoseCanvas::setCheckerSize(int pixels) {
    m_checkerSize = std::max(1, pixels);
    update();
}

QImage PoseCanvas::composed() const {
    if (m_xray.isNull() || m_drr.isNull() || m_xray.size() != m_drr.size()) return {};
    const int W = m_xray.width(), H = m_xray.height();
    QImage out(W, H, QImage::Format_RGB32);
    for (int row = 0; row < H; ++row) {
        const uchar* x = m_xray.constScanLine(row);
        const uchar* d = m_drr.constScanLine(row);
        auto* o = reinterpret_cast<QRgb*>(out.scanLine(row));
        for (int col = 0; col < W; ++col) {
            if (m_checker) {
                const int g = ((col / m_checkerSize + row / m_checkerSize) % 2) ? d[col] : x[col];
                o[col] = qRgb(g, g, g);
            } else { // X-ray green, DRR magenta: grey where they agree
                o[col] = qRgb(d[col], x[col], d[col]);
            }
        }
    }
    return out;
}

QRect PoseCanvas::imageRect() const {
    if (m_xray.isNull()) return {};
    const QSize s = m_xray.size().scaled(size(), Qt::KeepAspectRatio);
    return {QPoint((width() - s.width()) / 2, (height() - s.height()) / 2), s};
}

void PoseCanvas::paintEvent(QPaintEvent*) {
    QPainter p(this);
    p.fillRect(rect(), Qt::black);
    const QImage img = composed();
    p.setPen(QColor(140, 230, 140));
    if (!img.isNull()) {
        p.setRenderHint(QPainter::SmoothPixmapTransform);
        p.drawImage(imageRect(), img);
    }
    p.drawText(rect().adjusted(6, 4, -6, -4), Qt::AlignLeft | Qt::AlignTop, m_caption);
}

void PoseCanvas::mousePressEvent(QMouseEvent* e) {
    if (!m_interactive || e->button() != Qt::LeftButton) return;
    m_dragging = true;
    m_last = e->position();
}

void PoseCanvas::mouseMoveEvent(QMouseEvent* e) {
    if (!m_dragging || !m_interactive) return;
    const QRect r = imageRect();
    if (r.isEmpty()) return;
    const double scale = double(m_xray.width()) / r.width(); // detector pixels per screen pixel
    const QPointF d = (e->position() - m_last) * scale;
    m_last = e->position();
    if (!d.isNull()) emit poseDragged(d, e->modifiers());
}

void PoseCanvas::mouseReleaseEvent(QMouseEvent*) { m_dragging = false; }

void PoseCanvas::wheelEvent(QWheelEvent* e) {
    if (!m_interactive) return;
    const double steps = e->angleDelta().y() / 120.0;
    if (steps != 0.0) emit poseWheeled(steps);
    e->accept();
}

XrayRegisterDialog::XrayRegisterDialog(QWidget* parent) : QDialog(parent) {
    setWindowTitle(tr("Register to X-ray"));
    auto* layout = new QVBoxLayout(this);
    auto* pictures = new QHBoxLayout;
    m_beforeCanvas = new PoseCanvas(QString(), this);
    m_beforeCanvas->hide();
    m_canvas = new PoseCanvas(QString(), this);
    m_canvas->setInteractive(true);
    pictures->addWidget(m_beforeCanvas, 1);
    pictures->addWidget(m_canvas, 1);
    layout->addLayout(pictures, 1);
    m_info = new QLabel(this);
    m_info->setWordWrap(true);
    m_info->setTextInteractionFlags(Qt::TextSelectableByMouse);
    layout->addWidget(m_info);
    auto* help = new QLabel(tr("Drag: translate in the detector plane · Shift+drag: rotate about "
                               "the beam · Ctrl+drag: rotate about the image's vertical and "
                               "horizontal axes · Wheel: translate along the beam"),
                            this);
    help->setWordWrap(true);
    layout->addWidget(help);
    buildPoseControls(layout);
    buildRunControls(layout);
    m_options.globalSamples = 0;
    m_jobs = std::make_unique<BackgroundJobs>(this);
    connectControls();
    setBusy(false);
    resize(1100, 720);
}

XrayRegisterDialog::~XrayRegisterDialog() {
    // The registration sees this flag (not the jobs' token) at its next evaluation: set it
    // before the jobs are destroyed, which waits for them.
    if (m_cancelFlag) m_cancelFlag->store(true);
}

void XrayRegisterDialog::buildPoseControls(QBoxLayout* layout) {
    auto* grid = new QGridLayout;
    const char* names[6] = {"rx", "ry", "rz", "tx", "ty", "tz"};
    for (int i = 0; i < 6; ++i) {
        const bool rotation = i < 3;
        auto* s = new QDoubleSpinBox(this);
        s->setRange(rotation ? -180.0 : -500.0, rotation ? 180.0 : 500.0);
        s->setDecimals(rotation ? 2 : 1);
        s->setSingleStep(rotation ? 0.5 : 1.0);
        s->setSuffix(rotation ? QStringLiteral(" °") : QStringLiteral(" mm"));
        s->setKeyboardTracking(false);
        s->setToolTip(rotation ? tr("Rotation about the LPS %1 axis through the centre (degrees; "
                                    "x first, then y, then z)")
                                     .arg(QChar('x' + i))
                               : tr("Translation along LPS %1 (mm)").arg(QChar('x' + i - 3)));
        m_spins[std::size_t(i)] = s;
        grid->addWidget(new QLabel(QString::fromLatin1(names[i]), this), i / 3, 2 * (i % 3));
        grid->addWidget(s, i / 3, 2 * (i % 3) + 1);
    }
    m_reset = new QPushButton(tr("Geometry as recorded"), this);
    m_reset->setToolTip(tr("The identity pose: the X-ray's geometry as its file records it"));
    grid->addWidget(m_reset, 0, 6);
    layout->addLayout(grid);
}

void XrayRegisterDialog::buildRunControls(QBoxLayout* layout) {
    auto* row = new QHBoxLayout;
    m_register = new QPushButton(tr("Register"), this);
    m_cancel = new QPushButton(tr("Cancel"), this);
    m_accept = new QPushButton(tr("Accept"), this);
    m_revert = new QPushButton(tr("Revert"), this);
    m_save = new QPushButton(tr("Save pose…"), this);
    m_checker = new QCheckBox(tr("Checkerboard"), this);
    m_register->setToolTip(tr("Find the pose whose DRR best matches the X-ray, from this one"));
    m_accept->setToolTip(tr("Keep the registered pose"));
    m_revert->setToolTip(tr("Back to the pose before Register"));
    m_save->setToolTip(tr("Write the pose as JSON (4x4 and angles about the isocentre)"));
    for (QWidget* w : {static_cast<QWidget*>(m_register), static_cast<QWidget*>(m_cancel),
                       static_cast<QWidget*>(m_accept), static_cast<QWidget*>(m_revert),
                       static_cast<QWidget*>(m_save), static_cast<QWidget*>(m_checker)})
        row->addWidget(w);
    m_progress = new QProgressBar(this);
    m_progress->setRange(0, 1);
    m_progress->setValue(0);
    row->addWidget(m_progress, 1);
    layout->addLayout(row);
    m_progressText = new QLabel(this);
    layout->addWidget(m_progressText);
    m_resultText = new QLabel(this);
    m_resultText->setWordWrap(true);
    m_resultText->setTextInteractionFlags(Qt::TextSelectableByMouse);
    layout->addWidget(m_resultText);
}

void XrayRegisterDialog::connectControls() {
    for (QDoubleSpinBox* s : m_spins)
        connect(s, &QDoubleSpinBox::valueChanged, this, [this] { poseFromSpins(); });
    connect(m_reset, &QPushButton::clicked, this, [this] { setPose({}); });
    connect(m_canvas, &PoseCanvas::poseDragged, this, &XrayRegisterDialog::dragPose);
    connect(m_canvas, &PoseCanvas::poseWheeled, this, &XrayRegisterDialog::wheelPose);
    connect(m_register, &QPushButton::clicked, this, &XrayRegisterDialog::startRegistration);
    connect(m_cancel, &QPushButton::clicked, this, &XrayRegisterDialog::cancelRegistration);
    connect(m_accept, &QPushButton::clicked, this, &XrayRegisterDialog::acceptPose);
    connect(m_revert, &QPushButton::clicked, this, &XrayRegisterDialog::revert);
    connect(m_save, &QPushButton::clicked, this, &XrayRegisterDialog::savePoseDialog);
    connect(m_checker, &QCheckBox::toggled, this, [this](bool on) {
        m_canvas->setCheckerboard(on);
        m_beforeCanvas->setCheckerboard(on);
        showCaptions();
    });
}

void XrayRegisterDialog::setStudy(std::shared_ptr<const core::Volume> volume,
                                  core::ValueMapping mapping) {
    if (volume != m_volume || mapping != m_mapping) m_caster.reset();
    m_volume = std::move(volume);
    m_mapping = mapping;
}

bool XrayRegisterDialog::openXray(const QString& path, int frame) {
    m_error.clear();
    if (m_running) {
        m_error = tr("A registration is running: cancel it first.");
        return false;
    }
    if (!m_volume) {
        m_error = tr("Open a study first: the DRR is rendered from it.");
        m_info->setText(m_error);
        return false;
    }
    try {
        // The centre: the isocentre the file states, else the study's centre (which is also
        // where readXrayInput puts the isocentre of a file that states none).
        const glm::dvec3 volumeCentre = core::volumeCentre(*m_volume);
        const core::XrayGeometry g = core::readXrayGeometry(path.toStdString(), false);
        m_centre = volumeCentre;
        if (g.isocentreStated && frame < int(g.frames.size()))
            m_centre = g.frames[std::size_t(frame)].isocentre;
        else if (g.isocentreStated && frame < int(g.beams.size()))
            m_centre = g.beams[std::size_t(frame)].isocentre;
        m_input =
            core::readXrayInput(path.toStdString(), volumeCentre, core::XrayValues::Auto, frame);
    } catch (const std::exception& e) {
        m_input.reset();
        m_drr.reset();
        m_error = QString::fromUtf8(e.what());
        m_info->setText(m_error);
        m_canvas->setImages({}, {});
        m_beforeCanvas->hide();
        m_pending = false;
        setBusy(false);
        return false;
    }
    const core::RegistrationView& v = m_input->view;
    m_xrayImage = grayImage(v.image.data(), v.camera.width, v.camera.height, false);
    m_result.reset();
    m_before = {};
    m_pending = false;
    m_beforeCanvas->hide();
    m_resultText->clear();
    setWindowTitle(tr("Register to X-ray — %1").arg(QFileInfo(path).fileName()));
    setPose({});
    setBusy(false);
    return m_drr.has_value();
}

glm::dmat4 XrayRegisterDialog::poseMatrix() const { return core::poseMatrix(m_pose, m_centre); }

void XrayRegisterDialog::setPose(const core::Pose& pose) {
    m_pose = pose;
    showPoseInSpins();
    renderDrr();
}

void XrayRegisterDialog::poseFromSpins() {
    core::Pose p;
    for (int i = 0; i < 3; ++i) {
        p.rotationDeg[i] = m_spins[std::size_t(i)]->value();
        p.translationMm[i] = m_spins[std::size_t(i + 3)]->value();
    }
    m_pose = p;
    renderDrr();
}

void XrayRegisterDialog::showPoseInSpins() {
    for (int i = 0; i < 3; ++i) {
        const QSignalBlocker a(m_spins[std::size_t(i)]), b(m_spins[std::size_t(i + 3)]);
        m_spins[std::size_t(i)]->setValue(m_pose.rotationDeg[i]);
        m_spins[std::size_t(i + 3)]->setValue(m_pose.translationMm[i]);
    }
}

void XrayRegisterDialog::applyStep(const glm::dmat4& step) {
    try {
        m_pose = core::poseFromMatrix(step * poseMatrix(), m_centre);
    } catch (const std::exception& e) {
        emit message(tr("Pose step refused: %1").arg(QString::fromUtf8(e.what())), true);
        return;
    }
    showPoseInSpins();
    renderDrr();
}

void XrayRegisterDialog::dragPose(QPointF d, Qt::KeyboardModifiers modifiers) {
    if (!m_input || m_running) return;
    const core::ConeCamera& cam = m_input->view.camera;
    const glm::dvec3 n = beamAxis(cam);
    // The pivot: the CT's centre where the pose puts it, so that the anatomy turns in place.
    const glm::dvec3 pivot = glm::dvec3(poseMatrix() * glm::dvec4(m_centre, 1.0));
    if (modifiers & Qt::ShiftModifier) { // about the beam: a horizontal drag turns the image
        applyStep(rotationAbout(pivot, n, d.x() * kDegPerPixel));
    } else if (modifiers & Qt::ControlModifier) { // about the image's vertical, then horizontal
        const glm::dmat4 a = rotationAbout(pivot, cam.v, d.x() * kDegPerPixel);
        applyStep(rotationAbout(pivot, cam.u, -d.y() * kDegPerPixel) * a);
    } else { // the anatomy follows the mouse: detector pixels at the pivot's magnification
        const double sid = cam.sourceToDetector();
        const double sod = glm::dot(pivot - cam.source, n);
        const double mm = sod / sid;
        const glm::dvec3 t = (d.x() * cam.pitchU * cam.u + d.y() * cam.pitchV * cam.v) * mm;
        applyStep(glm::translate(glm::dmat4(1.0), t));
    }
}

void XrayRegisterDialog::wheelPose(double steps) {
    if (!m_input || m_running) return;
    const glm::dvec3 n = beamAxis(m_input->view.camera);
    applyStep(glm::translate(glm::dmat4(1.0), n * (steps * kMmPerNotch)));
}

core::DetectorImage XrayRegisterDialog::drrAt(const core::Pose& pose) {
    if (!m_caster) {
        core::ConeProjectorOptions o;
        o.mapping = m_mapping;
        m_caster = std::make_unique<core::ConeProjector>(*m_volume, o);
    }
    const core::ConeCamera cam =
        core::posedCamera(m_input->view.camera, core::poseMatrix(pose, m_centre));
    return m_caster->project(cam);
}

void XrayRegisterDialog::renderDrr() {
    if (!m_input || !m_volume) return;
    QApplication::setOverrideCursor(Qt::WaitCursor);
    try {
        m_drr = drrAt(m_pose);
        m_error.clear();
    } catch (const std::exception& e) {
        m_drr.reset();
        m_error = tr("No DRR at this pose: %1").arg(QString::fromUtf8(e.what()));
    }
    QApplication::restoreOverrideCursor();
    updateImages();
}

void XrayRegisterDialog::showCaptions() {
    const QString colours = m_checker->isChecked() ? tr("checkerboard of X-ray and DRR")
                                                   : tr("X-ray green, DRR magenta");
    m_beforeCanvas->setCaption(tr("Before registration (%1)").arg(colours));
    m_canvas->setCaption(m_pending ? tr("After registration (%1)").arg(colours)
                                   : tr("Current pose (%1)").arg(colours));
}

QString XrayRegisterDialog::xrayName() const {
    return m_input ? QString::fromStdString(m_input->file.filename().string()) : QString();
}

void XrayRegisterDialog::updateImages() {
    if (!m_input) return;
    const core::ConeCamera& cam = m_input->view.camera;
    QString text = tr("%1, frame %2: %3×%4, %5. Centre (%6, %7, %8) mm LPS.")
                       .arg(xrayName())
                       .arg(m_input->frame + 1)
                       .arg(cam.width)
                       .arg(cam.height)
                       .arg(QString::fromStdString(m_input->valuesNote))
                       .arg(m_centre.x, 0, 'f', 1)
                       .arg(m_centre.y, 0, 'f', 1)
                       .arg(m_centre.z, 0, 'f', 1);
    if (!m_error.isEmpty()) text += '\n' + m_error;
    m_info->setText(text);
    if (!m_drr) {
        m_canvas->setImages({}, {});
        return;
    }
    m_canvas->setImages(m_xrayImage,
                        grayImage(m_drr->pixels.data(), m_drr->width, m_drr->height, false));
    m_beforeCanvas->setImages(m_xrayImage, m_drrBeforeImage);
}

} // namespace fvr::ui
