#include <fvr/ui/projection_view.h>

#include <QMouseEvent>
#include <QOpenGLContext>
#include <QOpenGLExtraFunctions>
#include <QOpenGLShaderProgram>
#include <QOpenGLVertexArrayObject>
#include <QPainter>
#include <QThread>
#include <QWheelEvent>

#include <algorithm>
#include <cmath>
#include <numbers>

#include <fvr/core/xray/display_window.h>
#include <fvr/core/xray/patient_views.h>
#include <fvr/gpu/errors.h>
#include <fvr/gpu/gl_info.h>
#include <fvr/gpu/gpu_renderer.h>

namespace fvr::ui {

namespace {
const char* kQuadVertex = R"(#version 330 core
uniform vec4 uRect; // x0, y0, x1, y1 in NDC (y1 = top)
out vec2 vTex;
void main() {
    vec2 c = vec2(gl_VertexID & 1, (gl_VertexID >> 1) & 1);
    gl_Position = vec4(mix(uRect.x, uRect.z, c.x), mix(uRect.w, uRect.y, c.y), 0.0, 1.0);
    vTex = c; // texel row 0 (the image's top row) at the top of the quad
}
)";
const char* kQuadFragment = R"(#version 330 core
uniform sampler2D uImage;
in vec2 vTex;
out vec4 fragColor;
void main() { fragColor = vec4(texture(uImage, vTex).rgb, 1.0); }
)";
} // namespace

ProjectionView::ProjectionView(QWidget* parent) : QOpenGLWidget(parent) {
    setMinimumSize(160, 160);
    setFocusPolicy(Qt::StrongFocus);
    setMouseTracking(false);
    m_view = core::ViewFrame::fromDirUp({0, 0, 1}, {0, -1, 0});
    connect(this, &QOpenGLWidget::frameSwapped, this, &ProjectionView::framePresented);
}

ProjectionView::~ProjectionView() {
    // ~QOpenGLWidget destroys the context after this body: its aboutToBeDestroyed must not call
    // back into a ProjectionView that is gone (UBSan: member call on a QOpenGLWidget).
    if (context()) disconnect(context(), &QOpenGLContext::aboutToBeDestroyed, this, nullptr);
    if (m_glReady) {
        makeCurrent();
        releaseGl();
        doneCurrent();
    }
}

void ProjectionView::releaseGl() {
    if (!m_glReady) return;
    m_gpu.reset();
    m_polyGpu.clear();
    m_polyGpuSpectra.clear();
    m_polyOnGpu = false;
    m_quad.reset();
    m_vao.reset();
    if (m_cpuTexture) context()->functions()->glDeleteTextures(1, &m_cpuTexture);
    m_cpuTexture = 0;
    m_glReady = false;
    m_spectrumDirty = true;
}

void ProjectionView::setStudy(std::shared_ptr<const core::Volume> volume,
                              std::shared_ptr<const core::Spectrum> spectrum) {
    if (volume == m_volume && spectrum == m_spectrum) return; // nothing new to render
    const bool newVolume = volume != m_volume;
    m_volume = std::move(volume);
    m_spectrum = std::move(spectrum);
    m_spectrumDirty = true;
    m_renderDirty = true;
    m_cpu.reset();
    if (newVolume) m_windowSet = false;
    m_frameRequested = false; // the next frame is timed from here (its upload included)
    requestFrame();
}

void ProjectionView::setPendingText(const QString& text, bool failed) {
    m_pendingFailed = failed;
    if (text == m_pending) return;
    m_pending = text;
    update();
}

void ProjectionView::setSettings(const ViewSettings& s) {
    if (s == m_settings) return;
    m_settings = s;
    m_renderDirty = true;
    update();
}

void ProjectionView::setEffects(const FrameEffects& e) {
    if (e == m_effects) return;
    m_effects = e;
    m_renderDirty = true;
    update();
}

void ProjectionView::setPolychromatic(std::shared_ptr<const PolychromaticSource> source) {
    if (source == m_poly) return;
    if (!source || !m_poly || source->spectra != m_poly->spectra) m_polyRenderer.reset();
    m_poly = std::move(source);
    m_cpuImage.reset();
    m_renderDirty = true;
    update();
}

core::ProjectionImage ProjectionView::renderPolychromatic(const core::RenderParams& params,
                                                          core::StageTimes* times) {
    if (!m_polyRenderer) {
        std::vector<std::unique_ptr<core::Renderer>> renderers;
        for (const auto& s : m_poly->spectra)
            renderers.push_back(std::make_unique<core::CpuFourierRenderer>(s));
        m_polyRenderer =
            std::make_unique<core::PolychromaticRenderer>(std::move(renderers), m_poly->response);
    } else {
        m_polyRenderer->setResponse(m_poly->response);
    }
    core::PolychromaticFrame f = m_polyRenderer->render(
        params, m_poly->noise, times, core::SpectralResponse::Output::NegativeLog);
    if (m_poly->show >= 0 && std::size_t(m_poly->show) < f.massThickness.size())
        return std::move(f.massThickness[std::size_t(m_poly->show)]);
    return std::move(f.transmission); // -ln(I/I0), the quantity shown
}

void ProjectionView::setTargetFps(double fps) {
    m_progressive.setTargetFps(fps);
    m_renderDirty = true;
    update();
}

void ProjectionView::setInteracting(bool on) {
    if (on == m_progressive.interacting()) return;
    if (on) {
        m_progressive.beginInteraction();
    } else {
        m_progressive.endInteraction();
        if (m_renderedLevel != 0) m_renderDirty = true; // the full-quality frame
    }
    requestFrame();
}

void ProjectionView::requestFrame() {
    // Timed from the first change that can render (waiting for a spectrum is not a frame).
    if (!m_frameRequested && m_spectrum && isVisible()) {
        m_requestClock.start();
        m_frameRequested = true;
    }
    update();
}

void ProjectionView::framePresented() {
    if (!m_framePending) return;
    m_framePending = false;
    m_frameRequested = false;
    // What the user sees: from the change to the frame on screen, display and composition of
    // the window (all synchronised views) included; not one stage's timer.
    m_stats.wallMs = double(m_requestClock.nsecsElapsed()) / 1e6;
    if (m_pendingLevel == m_progressive.level()) m_progressive.frameRendered(m_stats.wallMs);
}

void ProjectionView::setViewFrame(const core::ViewFrame& f) {
    m_view = f;
    m_renderDirty = true;
    requestFrame();
}

void ProjectionView::setWindow(const core::DisplayWindow& w) {
    m_window = w;
    m_windowSet = true;
    update();
}

void ProjectionView::autoWindow() {
    if (auto p = projection()) {
        setWindow(core::filmWindow(p->pixels, m_window.transmission, m_window.invert));
        emit windowChanged(m_window, false);
    }
}

void ProjectionView::setZoom(double zoom) {
    m_zoom = std::clamp(zoom, 0.1, 40.0);
    update();
}

void ProjectionView::resetPanZoom() {
    m_zoom = 1.0;
    m_pan = {0, 0};
    update();
}

void ProjectionView::setOverlayVisible(bool on) {
    m_overlay = on;
    update();
}

void ProjectionView::setDifferenceReference(ProjectionView* reference) {
    m_reference = reference;
    m_renderDirty = true;
    m_windowSet = false;
    update();
}

void ProjectionView::setTitle(const QString& title) {
    m_title = title;
    update();
}

void ProjectionView::initializeGL() {
    connect(context(), &QOpenGLContext::aboutToBeDestroyed, this, [this] {
        makeCurrent();
        releaseGl();
        doneCurrent();
    });
    m_glReady = true;
    m_softwareGl = gpu::currentGlInfo().software();
    chooseRenderer();
    m_quad = std::make_unique<QOpenGLShaderProgram>();
    m_quad->addShaderFromSourceCode(QOpenGLShader::Vertex, kQuadVertex);
    m_quad->addShaderFromSourceCode(QOpenGLShader::Fragment, kQuadFragment);
    if (!m_quad->link()) m_notice += tr(" (display shader failed: %1)").arg(m_quad->log());
    m_vao = std::make_unique<QOpenGLVertexArrayObject>();
    m_vao->create();
    emit backendChanged(m_gpu != nullptr, backendNotice());
}

void ProjectionView::chooseRenderer() {
    m_gpu.reset();
    m_polyGpu.clear();
    m_polyGpuSpectra.clear();
    m_polyOnGpu = false;
    m_cpu.reset();
    m_spectrumDirty = true;
    m_renderDirty = true;
    m_notice.clear();
    if (m_softwareGl && !m_allowSoftwareGpu) return; // the CPU renderer: faster here
    try {
        m_gpu = std::make_unique<gpu::GpuFourierRenderer>(context()->shareGroup());
    } catch (const std::exception& e) {
        m_gpu.reset();
        m_notice = tr("GPU renderer unavailable (%1): rendering on the CPU")
                       .arg(QString::fromUtf8(e.what()));
    }
}

void ProjectionView::setAllowSoftwareGpu(bool allow) {
    if (allow == m_allowSoftwareGpu) return;
    m_allowSoftwareGpu = allow;
    if (!m_glReady || !m_softwareGl) return;
    makeCurrent();
    chooseRenderer();
    doneCurrent();
    emit backendChanged(m_gpu != nullptr, backendNotice());
    update();
}

void ProjectionView::resizeGL(int, int) {}

core::Renderer& ProjectionView::floatRenderer() {
    if (m_gpu) return *m_gpu;
    if (!m_cpu) m_cpu = std::make_unique<core::CpuFourierRenderer>(m_spectrum);
    return *m_cpu;
}

void ProjectionView::uploadSpectrumIfNeeded() {
    if (!m_spectrumDirty) return;
    m_spectrumDirty = false;
    m_renderDirty = true;
    if (m_gpu) {
        try {
            m_gpu->setSpectrum(m_spectrum);
        } catch (const std::exception& e) {
            m_gpu.reset();
            m_notice = tr("GPU renderer unavailable (%1): rendering on the CPU")
                           .arg(QString::fromUtf8(e.what()));
            emit backendChanged(false, m_notice);
        }
    }
    if (!m_gpu) m_cpu = std::make_unique<core::CpuFourierRenderer>(m_spectrum);
}

void ProjectionView::renderIfNeeded(bool fullQuality) {
    if (!m_spectrum || !m_volume) return;
    uploadSpectrumIfNeeded();
    m_progressive.setLevels(core::progressiveLevels(m_settings.size, m_settings.kernel,
                                                    m_spectrum->deapodizedFor.has_value(),
                                                    std::min(64, m_settings.size)));
    // Difference views compare full-quality frames (the reference renders full quality too).
    const int level = (fullQuality || m_reference) ? 0 : m_progressive.level();
    if (level != m_renderedLevel) m_renderDirty = true;
    if (!m_renderDirty) return;
    const core::QualityLevel q = m_progressive.levels()[std::size_t(level)];
    renderFrame(renderParams(q.size, q.kernel),
                level); // same field of view at every level: d = diagonal / M
    m_renderedLevel = level;
    m_renderedQuality = q;
    if (m_reference && m_reference != this) subtractReference();
    if (!m_windowSet) windowFromFrame();
    m_renderDirty = false; // only after a frame really exists
    ++m_frames;
    emit rendered();
}

void ProjectionView::renderFrame(const core::RenderParams& params, int level) {
    m_polyOnGpu = m_polySumOnGpu = false;
    if (m_poly && !m_poly->spectra.empty()) {
        if (m_gpu && renderPolychromaticOnGpu(params)) return;
        core::StageTimes t;
        m_cpuImage = renderPolychromatic(params, &t);
        m_stats.sliceMs = t.sliceMs;
        m_stats.inverseMs = t.inverseMs;
        m_stats.totalMs = t.totalMs;
        m_stats.fused = false;
        m_stats.displayFused = false;
        return;
    }
    m_polyGpu.clear(); // the material frames' GPU memory goes with the polychromatic output
    m_polyGpuSpectra.clear();
    if (m_gpu) {
        // With a window already set (and no difference to map), the last pass of the inverse
        // transform also writes the display texture; paintGL's displayTexture() then costs nothing.
        // Stage times are read in paintGL.
        const bool fuseDisplay = m_windowSet && !(m_reference && m_reference != this);
        m_gpu->renderToGpu(params, fuseDisplay ? &m_window : nullptr);
        m_gpuTimesPending = true;
        m_cpuImage.reset();
        return;
    }
    core::StageTimes t;
    m_cpuImage = floatRenderer().render(params, &t);
    m_stats.sliceMs = t.sliceMs;
    m_stats.inverseMs = t.inverseMs;
    m_stats.totalMs = t.totalMs;
    m_stats.fused = false;
    m_stats.displayFused = false;
}

void ProjectionView::subtractReference() {
    auto own = (m_gpu && !m_poly) || m_polyOnGpu
                   ? std::optional<core::ProjectionImage>(shownGpu().readback())
                   : m_cpuImage;
    auto ref = m_reference->projection();
    // The reference made its own context current (and released it): this view's again, or the
    // frame's texture goes to no context and the view stays empty.
    makeCurrent();
    if (!own || !ref || ref->size != own->size) return;
    double maxAbs = 0;
    for (std::size_t i = 0; i < own->pixels.size(); ++i) {
        own->pixels[i] -= ref->pixels[i];
        maxAbs = std::max(maxAbs, double(std::abs(own->pixels[i])));
    }
    m_cpuImage = own;
    if (!m_windowSet) {
        m_window = {-maxAbs, maxAbs > 0 ? maxAbs : 1.0, false};
        m_windowSet = true;
    }
}

void ProjectionView::windowFromFrame() {
    auto img = m_cpuImage ? *m_cpuImage : shownGpu().readback();
    m_window = core::filmWindow(img.pixels, m_window.transmission, m_window.invert);
    m_windowSet = true;
    emit windowChanged(m_window, false);
}

QRectF ProjectionView::imageRect() const {
    const double side = std::min(width(), height()) * m_zoom;
    return {width() / 2.0 - side / 2.0 + m_pan.x(), height() / 2.0 - side / 2.0 + m_pan.y(), side,
            side};
}

GLuint ProjectionView::frameTexture() {
    if (m_gpu && !m_cpuImage) {
        const GLuint tex = shownGpu().displayTexture(m_window);
        const auto t = shownGpu().lastTimes();
        if (m_gpuTimesPending) {
            m_stats.sliceMs = t.sliceMs;
            m_stats.inverseMs = t.inverseMs;
            m_stats.totalMs = t.totalMs;
            m_stats.fused = t.fused;
            m_stats.displayFused = t.displayFused;
            m_stats.displayMs = t.displayMs;
            m_gpuTimesPending = false;
        }
        return tex;
    }
    if (m_cpuImage) {
        uploadCpuTexture(*m_cpuImage);
        return m_cpuTexture;
    }
    return 0;
}

void ProjectionView::uploadCpuTexture(const core::ProjectionImage& image) {
    auto* f = context()->extraFunctions();
    const int M = image.size;
    std::vector<unsigned char> rgba(std::size_t(M) * M * 4);
    for (std::size_t i = 0; i < std::size_t(M) * M; ++i) {
        const auto v =
            static_cast<unsigned char>(std::lround(m_window.map(image.pixels[i]) * 255.0));
        rgba[4 * i] = rgba[4 * i + 1] = rgba[4 * i + 2] = v;
        rgba[4 * i + 3] = 255;
    }
    if (!m_cpuTexture) f->glGenTextures(1, &m_cpuTexture);
    f->glBindTexture(GL_TEXTURE_2D, m_cpuTexture);
    f->glPixelStorei(GL_UNPACK_ALIGNMENT, 4);
    if (m_cpuTextureSize != M) {
        f->glTexImage2D(GL_TEXTURE_2D, 0, GL_RGBA8, M, M, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                        rgba.data());
        f->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_LINEAR);
        f->glTexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
        m_cpuTextureSize = M;
    } else {
        f->glTexSubImage2D(GL_TEXTURE_2D, 0, 0, 0, M, M, GL_RGBA, GL_UNSIGNED_BYTE, rgba.data());
    }
}

void ProjectionView::paintGL() {
    auto* f = context()->extraFunctions();
    f->glClearColor(0.08f, 0.08f, 0.09f, 1.0f);
    f->glClear(GL_COLOR_BUFFER_BIT);
    if (!m_spectrum) {
        drawOverlay();
        return;
    }
    const int framesBefore = m_frames;
    if (!m_frameRequested) m_requestClock.start(); // a repaint nobody timed: from here
    try {
        renderIfNeeded();
        m_renderError.clear();
        if (m_frames != framesBefore) {
            m_framePending = true; // timed when the window's frame is on screen
            m_pendingLevel = m_renderedLevel;
            if (m_simulatedMsAt512 > 0) {
                const double r = m_renderedQuality.size / 512.0;
                QThread::msleep(
                    static_cast<unsigned long>(std::lround(m_simulatedMsAt512 * r * r)));
            }
        } else {
            m_frameRequested = false; // served without a new frame: the clock starts afresh
        }
    } catch (const std::exception& e) {
        m_frameRequested = false; // no frame: the next one is timed afresh
        m_renderError = tr("Not rendered: %1").arg(QString::fromUtf8(e.what()));
        drawOverlay();
        return;
    }
    GLuint tex = 0;
    try {
        tex = frameTexture();
    } catch (const std::exception& e) { // nothing may leave paintGL
        m_renderError = tr("Not displayed: %1").arg(QString::fromUtf8(e.what()));
        tex = 0;
    }
    if (tex) {
        m_displayedLevel = m_renderedLevel;
        m_displayedSize = m_renderedQuality.size;
    }
    if (tex && m_quad && m_quad->isLinked()) {
        const QRectF r = imageRect();
        const double dpr = devicePixelRatioF();
        f->glViewport(0, 0, int(width() * dpr), int(height() * dpr));
        auto ndcX = [&](double x) { return float(2.0 * x / width() - 1.0); };
        auto ndcY = [&](double y) { return float(1.0 - 2.0 * y / height()); };
        m_quad->bind();
        m_quad->setUniformValue(
            "uRect", QVector4D(ndcX(r.left()), ndcY(r.bottom()), ndcX(r.right()), ndcY(r.top())));
        m_quad->setUniformValue("uImage", 0);
        f->glActiveTexture(GL_TEXTURE0);
        f->glBindTexture(GL_TEXTURE_2D, tex);
        m_vao->bind();
        f->glDrawArrays(GL_TRIANGLE_STRIP, 0, 4);
        m_vao->release();
        m_quad->release();
    }
    drawOverlay();
}

namespace {
/** Text with a dark halo stays readable on bright (bone) and dark (air) parts of the image. */
void drawHaloText(QPainter& p, const QRectF& r, int flags, const QString& text,
                  const QColor& color) {
    p.setPen(QColor(0, 0, 0, 200));
    for (const QPointF& o : {QPointF(-1, 0), QPointF(1, 0), QPointF(0, -1), QPointF(0, 1)})
        p.drawText(r.translated(o), flags, text);
    p.setPen(color);
    p.drawText(r, flags, text);
}
} // namespace

void ProjectionView::drawOverlay() {
    QPainter p(this);
    p.setRenderHint(QPainter::TextAntialiasing);
    p.setFont(overlayFont());
    if (!m_spectrum) {
        p.setPen(QColor(180, 180, 180));
        p.drawText(
            rect().adjusted(12, 12, -12, -12), Qt::AlignCenter | Qt::TextWordWrap,
            m_pending.isEmpty()
                ? tr("No study loaded\nFile ▸ Open, or drop a DICOM folder or volume file here")
                : m_pending);
        if (!m_title.isEmpty())
            drawHaloText(p, rect().adjusted(8, 6, -8, -6), Qt::AlignLeft | Qt::AlignTop, m_title,
                         QColor(140, 240, 140));
        return;
    }
    // The overlay's text, its box and the labels that keep clear of it: once per frame.
    const QString text = overlayText();
    const QRect box = overlayBox(text);
    if (m_volume) drawOrientationLabels(p, box);
    if (!text.isEmpty()) {
        p.fillRect(box, QColor(0, 0, 0, 150));
        p.setPen(QColor(140, 240, 140));
        p.drawText(box.adjusted(4, 2, -4, -2), Qt::AlignLeft | Qt::AlignTop, text);
    }
    const QString notice = m_renderError.isEmpty() ? m_notice : m_renderError + '\n' + m_notice;
    if (!notice.trimmed().isEmpty()) {
        const QRect area(8, 6, width() - 16, height() - 12);
        const QRect noticeBox = p.fontMetrics().boundingRect(
            area, Qt::AlignLeft | Qt::AlignBottom | Qt::TextWordWrap, notice.trimmed());
        p.fillRect(noticeBox.adjusted(-4, -2, 4, 2), QColor(0, 0, 0, 170));
        p.setPen(QColor(255, 130, 110));
        p.drawText(noticeBox, Qt::AlignLeft | Qt::AlignBottom | Qt::TextWordWrap, notice.trimmed());
    }
}

QStringList ProjectionView::orientationLabels() const {
    if (!m_volume) return {};
    // A file without orientation: the labels follow the assumed one and say so.
    const QString assumed = m_volume->orientationStated ? QString() : tr(" (assumed)");
    auto lbl = [&](const core::Vec3& v) {
        return QString::fromStdString(core::patientDirectionLabel(*m_volume, v)) + assumed;
    };
    const core::Vec3 neg_r{-m_view.r[0], -m_view.r[1], -m_view.r[2]};
    const core::Vec3 neg_u{-m_view.u[0], -m_view.u[1], -m_view.u[2]};
    return {lbl(neg_r), lbl(m_view.r), lbl(m_view.u), lbl(neg_u)};
}

QFont ProjectionView::overlayFont(bool bold) const {
    QFont f = font();
    f.setPointSizeF(std::max(8.0, f.pointSizeF()));
    f.setBold(bold);
    return f;
}

QString ProjectionView::overlayText() const {
    QStringList lines;
    if (!m_title.isEmpty()) lines << m_title;
    if (m_overlay) lines << overlayLines();
    if (m_reference) lines << tr("difference to %1").arg(m_reference->m_title);
    return lines.join('\n');
}

QRect ProjectionView::overlayBox() const { return overlayBox(overlayText()); }

QRect ProjectionView::overlayBox(const QString& text) const {
    if (text.isEmpty() || !m_spectrum) return {};
    const QRect box = QFontMetrics(overlayFont())
                          .boundingRect(QRect(8, 6, width() - 16, height() - 12),
                                        Qt::AlignLeft | Qt::AlignTop, text);
    return box.adjusted(-4, -2, 4, 2);
}

QList<QRect> ProjectionView::orientationLabelRects() const {
    return orientationLabelRects(orientationLabels(), overlayBox());
}

QList<QRect> ProjectionView::orientationLabelRects(const QStringList& labels,
                                                   const QRect& avoid) const {
    if (labels.size() != 4) return {}; // left, right, top, bottom
    const QFontMetrics fm(overlayFont(true));
    const QRect r = imageRect().intersected(QRectF(rect())).toAlignedRect();
    const int pad = 6;
    const QRect inner = r.adjusted(pad, pad, -pad, -pad);
    const int flags[4] = {Qt::AlignLeft | Qt::AlignVCenter, Qt::AlignRight | Qt::AlignVCenter,
                          Qt::AlignHCenter | Qt::AlignTop, Qt::AlignHCenter | Qt::AlignBottom};
    QList<QRect> rects;
    for (int i = 0; i < 4; ++i) {
        QRect b = fm.boundingRect(inner, flags[i], labels[i]);
        // Never under the overlay box (compare views: their image starts at the top): below it,
        // or right of it where below would leave the image (a small view).
        if (!avoid.isNull() && b.intersects(avoid)) {
            const QRect below = b.translated(0, avoid.bottom() + 3 - b.top());
            if (below.bottom() < inner.bottom() - 2 * b.height())
                b = below;
            else
                b.moveLeft(std::max(b.left(), avoid.right() + 6));
        }
        rects << b;
    }
    return rects;
}

void ProjectionView::drawOrientationLabels(QPainter& p, const QRect& overlay) {
    const QColor label(255, 210, 80);
    const QFont font = p.font();
    const QStringList labels = orientationLabels();
    const QList<QRect> rects = orientationLabelRects(labels, overlay);
    p.setFont(overlayFont(true));
    for (int i = 0; i < int(rects.size()); ++i)
        drawHaloText(p, rects[i], Qt::AlignLeft | Qt::AlignTop, labels[i], label);
    p.setFont(font);
}

QStringList ProjectionView::overlayLines() const {
    QStringList lines;
    const core::QualityLevel shown = m_renderedQuality;
    // While dragging the frame rate the user sees; at rest the last frame's time.
    const QString speed =
        m_stats.wallMs <= 0 ? QStringLiteral("–")
        : m_progressive.interacting()
            ? QStringLiteral("%1 fps").arg(1000.0 / std::max(1.0, m_stats.wallMs), 0, 'f', 0)
            : tr("frame %1 ms").arg(m_stats.wallMs, 0, 'f', 0);
    lines << QStringLiteral("%1  %2  %3×%3  %4  %5 voxels%6")
                 .arg(speed)
                 .arg(QString::fromUtf8(core::kernelName(shown.kernel)))
                 .arg(shown.size)
                 .arg(m_gpu ? QStringLiteral("GPU") : QStringLiteral("CPU"))
                 .arg(QString::fromUtf8(core::voxelModelLabel(m_settings.voxelModel)))
                 .arg(m_effects.pixelAperture ? tr(", area pixels") : QString());
    if (m_progressive.enabled())
        lines << (m_renderedLevel == 0 ? tr("full quality (interactive target %1 fps)")
                                             .arg(m_progressive.targetFps(), 0, 'f', 0)
                                       : tr("interactive level %1/%2 (target %3 fps)")
                                             .arg(m_renderedLevel)
                                             .arg(m_progressive.levels().size() - 1)
                                             .arg(m_progressive.targetFps(), 0, 'f', 0));
    const QStringList fx = effectsSummary();
    if (!fx.isEmpty()) lines << fx.join(QStringLiteral("  "));
    if (m_stats.fused && m_stats.displayFused)
        lines << QStringLiteral("slice+inverse+display %1 ms (fused)")
                     .arg(m_stats.inverseMs, 0, 'f', 2);
    else if (m_stats.fused)
        lines << QStringLiteral("slice+inverse %1 ms  display %2 ms")
                     .arg(m_stats.inverseMs, 0, 'f', 2)
                     .arg(m_stats.displayMs, 0, 'f', 2);
    else if (m_gpu)
        lines << QStringLiteral("slice %1  inverse %2  display %3 ms")
                     .arg(m_stats.sliceMs, 0, 'f', 2)
                     .arg(m_stats.inverseMs, 0, 'f', 2)
                     .arg(m_stats.displayMs, 0, 'f', 2);
    else // the CPU renderer's stages (the display is the upload, in the frame time)
        lines << QStringLiteral("slice %1  inverse %2 ms")
                     .arg(m_stats.sliceMs, 0, 'f', 2)
                     .arg(m_stats.inverseMs, 0, 'f', 2);
    lines << QStringLiteral("W %1  L %2")
                 .arg(m_window.high - m_window.low, 0, 'g', 4)
                 .arg((m_window.high + m_window.low) / 2, 0, 'g', 4);
    return lines;
}

QStringList ProjectionView::effectsSummary() const {
    QStringList fx;
    if (m_effects.depthCue > 0) fx << tr("depth cue %1 %").arg(m_effects.depthCue * 100, 0, 'f', 0);
    if (m_effects.filter.sharpenAmount > 0)
        fx << tr("edges ×%1 (σ %2 mm)")
                  .arg(m_effects.filter.sharpenAmount, 0, 'g', 3)
                  .arg(m_effects.filter.sharpenSigmaMm, 0, 'g', 3);
    if (m_effects.filter.bandLimitLpMm > 0)
        fx << tr("band limit %1 lp/mm").arg(m_effects.filter.bandLimitLpMm, 0, 'g', 3);
    if (m_window.transmission.active())
        fx << tr("Beer-Lambert μw %1/mm ×%2")
                  .arg(m_window.transmission.muWaterPerMm, 0, 'f', 4)
                  .arg(m_window.transmission.exposure, 0, 'g', 3);
    return fx;
}

std::optional<core::ProjectionImage> ProjectionView::projection() {
    if (!m_spectrum || !m_volume) return std::nullopt;
    if (m_glReady) {
        makeCurrent();
        try {
            renderIfNeeded(true); // exports and measurements always get the full-quality frame
        } catch (const std::exception&) {
            doneCurrent();
            return std::nullopt;
        }
        std::optional<core::ProjectionImage> img;
        try {
            if (m_poly && !m_poly->spectra.empty() && m_reference)
                img = renderPolychromatic(renderParams(m_settings.size, m_settings.kernel));
            else if (m_polyOnGpu || (m_gpu && !(m_poly && !m_poly->spectra.empty())))
                img = shownGpu().readback(); // the view's own projection, also in difference mode
            else if (m_reference && m_cpuImage)
                img = floatRenderer().render(renderParams(m_settings.size, m_settings.kernel));
            else
                img = m_cpuImage;
        } catch (const std::exception&) {
            img.reset();
        }
        doneCurrent();
        return img;
    }
    if (m_poly && !m_poly->spectra.empty())
        return renderPolychromatic(renderParams(m_settings.size, m_settings.kernel));
    return floatRenderer().render(renderParams(m_settings.size, m_settings.kernel));
}

core::RenderParams ProjectionView::renderParams(int M, core::Kernel kernel) const {
    core::RenderParams p{
        m_view, {M, core::defaultPixelSize(m_volume->dims, m_volume->spacing, M)}, kernel};
    p.voxelModel = m_settings.voxelModel;
    p.pixelAperture = m_effects.pixelAperture;
    p.depthCue = m_effects.depthCue;
    p.filter = m_effects.filter;
    p.clipToVolume = m_effects.clip;
    p.nonNegative = m_effects.nonNegative;
    return p;
}

QImage ProjectionView::screenshot() { return grabFramebuffer(); }

void ProjectionView::mousePressEvent(QMouseEvent* e) {
    m_dragButton = e->button();
    m_dragMods = e->modifiers();
    m_lastPos = e->position().toPoint();
    if (m_dragButton == Qt::LeftButton && !(m_dragMods & Qt::ControlModifier)) { // rotation drag
        setInteracting(true);
        emit interactionChanged(true);
    }
}

void ProjectionView::mouseMoveEvent(QMouseEvent* e) {
    if (m_dragButton == Qt::NoButton) return;
    if (!(e->buttons() & m_dragButton)) { // the release went elsewhere (a grab, a focus change)
        endDrag();
        return;
    }
    const QPoint pos = e->position().toPoint();
    const QPoint delta = pos - m_lastPos;
    m_lastPos = pos;
    const bool windowing = m_dragButton == Qt::RightButton ||
                           (m_dragButton == Qt::LeftButton && (m_dragMods & Qt::ControlModifier));
    if (windowing) {
        double w = m_window.high - m_window.low, c = (m_window.high + m_window.low) / 2;
        w = std::max(1e-9, w * std::exp(delta.x() * 0.005));
        c -= delta.y() * w * 0.003;
        m_window.low = c - w / 2;
        m_window.high = c + w / 2;
        m_windowSet = true;
        emit windowChanged(m_window, true);
        update();
    } else if (m_dragButton == Qt::LeftButton) {
        // Trackball: horizontal drags turn about the screen's vertical axis, vertical drags about
        // the horizontal one; the object follows the mouse.
        const double k = std::numbers::pi / std::max(1, std::min(width(), height()));
        core::ViewFrame f = m_view;
        if (delta.x()) f = f.rotated(f.u, delta.x() * k);
        if (delta.y()) f = f.rotated(f.r, delta.y() * k);
        setViewFrame(f);
        emit viewFrameChanged(m_view);
    } else if (m_dragButton == Qt::MiddleButton) {
        m_pan += QPointF(delta);
        update();
    }
}

void ProjectionView::mouseReleaseEvent(QMouseEvent* e) {
    if (e->button() == m_dragButton) endDrag();
}

void ProjectionView::focusOutEvent(QFocusEvent* e) {
    endDrag();
    QOpenGLWidget::focusOutEvent(e);
}

void ProjectionView::endDrag() {
    m_dragButton = Qt::NoButton;
    if (m_progressive.interacting()) {
        setInteracting(false);
        emit interactionChanged(false);
    }
}

void ProjectionView::wheelEvent(QWheelEvent* e) {
    const double steps = e->angleDelta().y() / 120.0;
    setZoom(m_zoom * std::pow(1.15, steps));
}

} // namespace fvr::ui
