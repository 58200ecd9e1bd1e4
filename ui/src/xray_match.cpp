// File ▸ Open X-ray to match…: the X-ray, the DRR of its geometry, and the two laid over each
// other (xray_match.h).
#include <fvr/ui/xray_match.h>

#include <QApplication>
#include <QCheckBox>
#include <QComboBox>
#include <QFileInfo>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QPainter>
#include <QPushButton>
#include <QSlider>
#include <QSpinBox>
#include <QVBoxLayout>

#include <algorithm>
#include <cmath>

#include <fvr/core/errors.h>
#include <fvr/core/xray/display_window.h>

namespace fvr::ui {

QImage grayImage(const float* values, int width, int height, bool invert) {
    const std::vector<float> v(values, values + std::size_t(width) * std::size_t(height));
    core::DisplayWindow w = core::autoWindow(v);
    w.invert = invert;
    QImage img(width, height, QImage::Format_Grayscale8);
    for (int row = 0; row < height; ++row) {
        uchar* line = img.scanLine(row);
        for (int col = 0; col < width; ++col)
            line[col] = uchar(std::lround(w.map(v[std::size_t(row) * width + col]) * 255.0));
    }
    return img;
}

XrayMatchCanvas::XrayMatchCanvas(QWidget* parent) : QWidget(parent) {
    setMinimumSize(480, 320);
    setSizePolicy(QSizePolicy::Expanding, QSizePolicy::Expanding);
}

void XrayMatchCanvas::setImages(QImage xray, QImage drr) {
    m_xray = std::move(xray);
    m_drr = std::move(drr);
    update();
}

void XrayMatchCanvas::setMode(Mode m) {
    m_mode = m;
    update();
}

void XrayMatchCanvas::setOpacity(double drrOpacity) {
    m_opacity = std::clamp(drrOpacity, 0.0, 1.0);
    update();
}

void XrayMatchCanvas::setCheckerSize(int pixels) {
    m_checker = std::max(1, pixels);
    update();
}

QImage XrayMatchCanvas::composed() const {
    if (m_xray.isNull() || m_drr.isNull() || m_xray.size() != m_drr.size()) return {};
    const int W = m_xray.width(), H = m_xray.height();
    if (m_mode == Mode::SideBySide) {
        QImage out(2 * W, H, QImage::Format_Grayscale8);
        QPainter p(&out);
        p.drawImage(0, 0, m_xray);
        p.drawImage(W, 0, m_drr);
        return out;
    }
    QImage out(W, H, QImage::Format_Grayscale8);
    for (int row = 0; row < H; ++row) {
        const uchar* x = m_xray.constScanLine(row);
        const uchar* d = m_drr.constScanLine(row);
        uchar* o = out.scanLine(row);
        for (int col = 0; col < W; ++col) {
            if (m_mode == Mode::Checkerboard)
                o[col] = ((col / m_checker + row / m_checker) % 2) ? d[col] : x[col];
            else
                o[col] = uchar(std::lround((1.0 - m_opacity) * x[col] + m_opacity * d[col]));
        }
    }
    return out;
}

void XrayMatchCanvas::paintEvent(QPaintEvent*) {
    QPainter p(this);
    p.fillRect(rect(), Qt::black);
    const QImage img = composed();
    if (img.isNull()) return;
    const QSize s = img.size().scaled(size(), Qt::KeepAspectRatio);
    const QRect target(QPoint((width() - s.width()) / 2, (height() - s.height()) / 2), s);
    p.setRenderHint(QPainter::SmoothPixmapTransform);
    p.drawImage(target, img);
    p.setPen(QColor(140, 230, 140));
    if (m_mode == Mode::SideBySide) {
        p.drawText(target.adjusted(6, 4, 0, 0), Qt::AlignLeft | Qt::AlignTop, tr("X-ray"));
        p.drawText(target.adjusted(target.width() / 2 + 6, 4, 0, 0), Qt::AlignLeft | Qt::AlignTop,
                   tr("DRR, the X-ray's geometry"));
    }
}

XrayMatchDialog::XrayMatchDialog(QWidget* parent) : QDialog(parent) {
    setWindowTitle(tr("X-ray and DRR"));
    auto* layout = new QVBoxLayout(this);
    m_canvas = new XrayMatchCanvas(this);
    layout->addWidget(m_canvas, 1);
    m_info = new QLabel(this);
    m_info->setWordWrap(true);
    m_info->setTextInteractionFlags(Qt::TextSelectableByMouse);
    layout->addWidget(m_info);
    auto* controls = new QHBoxLayout;
    m_mode = new QComboBox(this);
    m_mode->addItem(tr("Side by side"), int(XrayMatchCanvas::Mode::SideBySide));
    m_mode->addItem(tr("Overlay"), int(XrayMatchCanvas::Mode::Overlay));
    m_mode->addItem(tr("Checkerboard"), int(XrayMatchCanvas::Mode::Checkerboard));
    controls->addWidget(m_mode);
    controls->addWidget(new QLabel(tr("DRR opacity"), this));
    m_opacity = new QSlider(Qt::Horizontal, this);
    m_opacity->setRange(0, 100);
    m_opacity->setValue(50);
    controls->addWidget(m_opacity, 1);
    controls->addWidget(new QLabel(tr("Frame"), this));
    m_frame = new QSpinBox(this);
    m_frame->setRange(1, 1);
    controls->addWidget(m_frame);
    m_invert = new QCheckBox(tr("DRR bone dark"), this);
    m_invert->setToolTip(tr("Show the DRR as fluoroscopy does (dense = dark), e.g. beside an "
                            "angiogram; off: as a film (dense = bright)"));
    controls->addWidget(m_invert);
    m_register = new QPushButton(tr("Register to X-ray…"), this);
    m_register->setToolTip(tr("Find the study's pose in this X-ray's geometry: adjust it by "
                              "hand, then register"));
    controls->addWidget(m_register);
    layout->addLayout(controls);
    resize(1000, 620);

    connect(m_mode, &QComboBox::currentIndexChanged, this,
            [this] { m_canvas->setMode(XrayMatchCanvas::Mode(m_mode->currentData().toInt())); });
    connect(m_opacity, &QSlider::valueChanged, this,
            [this](int v) { m_canvas->setOpacity(v / 100.0); });
    connect(m_frame, &QSpinBox::valueChanged, this, [this](int f) { showFrame(f - 1); });
    connect(m_invert, &QCheckBox::toggled, this, [this] { updateImages(); });
    connect(m_register, &QPushButton::clicked, this, [this] {
        if (m_xray && m_drr)
            emit registerRequested(QString::fromStdString(m_xray->file.string()), m_shownFrame);
    });
}

XrayMatchDialog::~XrayMatchDialog() = default;

void XrayMatchDialog::setStudy(std::shared_ptr<const core::Volume> volume,
                               core::ValueMapping mapping) {
    if (volume != m_volume || mapping != m_mapping) m_caster.reset();
    m_volume = std::move(volume);
    m_mapping = mapping;
    if (m_xray) renderDrr();
}

bool XrayMatchDialog::openXray(const QString& path) {
    m_error.clear();
    if (!m_volume) {
        m_error = tr("Open a study first: the DRR is rendered from it.");
        m_info->setText(m_error);
        return false;
    }
    try {
        m_xray = core::readXrayGeometry(path.toStdString(), true);
    } catch (const std::exception& e) {
        m_xray.reset();
        m_drr.reset();
        m_error = QString::fromUtf8(e.what());
        m_info->setText(m_error);
        m_canvas->setImages({}, {});
        return false;
    }
    m_shownFrame = 0;
    {
        const QSignalBlocker b(m_frame);
        m_frame->setRange(1, std::max(1, int(m_xray->frameCount())));
        m_frame->setValue(1);
    }
    // Fluoroscopy shows dense tissue dark; a radiograph for presentation shows it bright.
    {
        const QSignalBlocker b(m_invert);
        m_invert->setChecked(m_xray->modality == "XA" || m_xray->modality == "RF");
    }
    setWindowTitle(tr("X-ray and DRR — %1").arg(QFileInfo(path).fileName()));
    renderDrr();
    return !m_drr.has_value() ? false : true;
}

void XrayMatchDialog::showFrame(int frame) {
    if (!m_xray || frame < 0 || frame >= int(m_xray->frameCount())) return;
    m_shownFrame = frame;
    renderDrr();
}

void XrayMatchDialog::renderDrr() {
    if (!m_xray || !m_volume) return;
    QApplication::setOverrideCursor(Qt::WaitCursor);
    try {
        if (!m_caster) {
            core::ConeProjectorOptions o;
            o.mapping = m_mapping;
            m_caster = std::make_unique<core::ConeProjector>(*m_volume, o);
        }
        const core::ConeCamera cam =
            m_xray->camera(std::size_t(m_shownFrame), core::volumeCentre(*m_volume));
        m_drr = m_caster->project(cam);
        m_error.clear();
    } catch (const std::exception& e) {
        m_drr.reset();
        m_error = tr("No DRR for this X-ray: %1").arg(QString::fromUtf8(e.what()));
    }
    QApplication::restoreOverrideCursor();
    updateImages();
}

QString XrayMatchDialog::warningsText() const {
    if (!m_xray) return {};
    QStringList lines;
    for (const auto& w : m_xray->warnings) lines << QString::fromStdString(w);
    return lines.join('\n');
}

void XrayMatchDialog::updateImages() {
    if (!m_xray) return;
    QString text = tr("%1 %2×%3, pitch %4 × %5 mm, ")
                       .arg(QString::fromStdString(m_xray->modality))
                       .arg(m_xray->width)
                       .arg(m_xray->height)
                       .arg(m_xray->pitchU, 0, 'g', 4)
                       .arg(m_xray->pitchV, 0, 'g', 4);
    if (!m_xray->beams.empty()) { // an RT Image: its treatment beam (IEC 61217)
        const core::TreatmentBeam& b = m_xray->beams[std::size_t(m_shownFrame)];
        text += tr("gantry %1° couch %2° collimator %3°, SAD %4 mm, SID %5 mm")
                    .arg(b.gantryDeg, 0, 'g', 6)
                    .arg(b.couchDeg, 0, 'g', 6)
                    .arg(b.collimatorDeg, 0, 'g', 6)
                    .arg(b.sad, 0, 'f', 0)
                    .arg(b.sid, 0, 'f', 0);
    } else {
        const core::CArm& arm = m_xray->frames[std::size_t(m_shownFrame)];
        text += tr("%1, SID %2 mm, SOD %3 mm")
                    .arg(QString::fromStdString(core::cArmLabel(arm.primaryDeg, arm.secondaryDeg)))
                    .arg(arm.sid, 0, 'f', 0)
                    .arg(arm.sod, 0, 'f', 0);
    }
    if (!warningsText().isEmpty()) text += '\n' + tr("Assumed: ") + warningsText();
    if (!m_error.isEmpty()) text += '\n' + m_error;
    m_info->setText(text);
    if (!m_drr || m_xray->pixels.empty()) {
        m_canvas->setImages({}, {});
        return;
    }
    const std::size_t n = std::size_t(m_xray->width) * std::size_t(m_xray->height);
    const QImage xray = grayImage(m_xray->pixels.data() + n * std::size_t(m_shownFrame),
                                  m_xray->width, m_xray->height, false);
    const QImage drr =
        grayImage(m_drr->pixels.data(), m_drr->width, m_drr->height, m_invert->isChecked());
    m_canvas->setImages(xray, drr);
}

} // namespace fvr::ui
