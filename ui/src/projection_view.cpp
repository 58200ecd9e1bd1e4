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
#include <fvr/gpu/cone_ray_caster.h>
#include <fvr/gpu/gpu_renderer.h>
#include <fvr/ui/measure_layer.h>

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
    m_measure = new MeasureLayer(this);
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
    m_gpuCone.reset();
    m_gpuConeVolume = nullptr;
    if (m_polyConeOnGpu) m_polyCone.reset(); // its casters go next
    m_polyConeGpu.clear();
    m_polyConeOnGpu = false;
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
    if (newVolume) {
        m_cone.reset();
        if (!m_polyConeOnGpu) m_polyCone.reset(); // else at the next cast, context current
        m_polyConeVolume = nullptr;
        // The GPU caster goes with its volume at the next cast (with the context current); its
        // address is no proof of sameness once the old volume is freed.
        m_gpuConeVolume = nullptr;
    }
    if (newVolume) {
        m_windowSet = false;
        m_stats = {}; // the last study's times (a sweep's, say) are not this one's
    }
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
    // At rest the overlay was drawn before its frame was on screen: once more, with this
    // frame's own time (a drag shows the rate of the frames before, as a rate should).
    if (!m_progressive.interacting()) update();
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
    const double z = std::clamp(zoom, 0.1, 40.0);
    if (z == m_zoom) return;
    m_zoom = z;
    update();
    emit panZoomChanged();
}

void ProjectionView::setPan(const QPointF& pan) {
    if (pan == m_pan) return;
    m_pan = pan;
    update();
    emit panZoomChanged();
}

void ProjectionView::resetPanZoom() {
    if (m_zoom == 1.0 && m_pan.isNull()) return;
    m_zoom = 1.0;
    m_pan = {0, 0};
    update();
    emit panZoomChanged();
}

void ProjectionView::setOverlayVisible(bool on) {
    m_overlay = on;
    update();
}

void ProjectionView::setDifferenceReference(ProjectionView* reference) {
    m_reference = reference;
    m_renderDirty = true;
    m_windowSet = false;
    m_diffKey.reset();
    m_diffMaxAbs = 0.0;
    update();
}

void ProjectionView::setProgressiveOffReason(const QString& reason) {
    m_progressiveOff = reason;
    update();
}

QString ProjectionView::valueUnits() const {
    if (m_poly && !m_poly->spectra.empty())
        return m_poly->show >= 0 ? tr("g/cm²") : QStringLiteral("−ln(I/I0)");
    if (!m_spectrum) return {};
    // Line integrals: attenuation relative to water integrates to water-equivalent mm; stored
    // values to value × mm.
    if (m_spectrum->mapping != core::ValueMapping::Raw) return tr("mm");
    return m_spectrum->sourceUnits == core::ValueUnits::HounsfieldUnits ? tr("HU·mm")
                                                                        : tr("value·mm");
}

QString ProjectionView::spectrumText() const {
    if (!m_spectrum || coneBeam()) return {};
    // The oversampling from the padded size (the spectrum keeps no other record of it).
    const double over = m_spectrum->volumeDims[0] > 0
                            ? double(m_spectrum->padded[0]) / double(m_spectrum->volumeDims[0])
                            : 0.0;
    const bool corrected =
        m_spectrum->deapodizedFor && *m_spectrum->deapodizedFor == m_settings.kernel;
    return tr("%1 %2  oversampling %3  %4")
        .arg(QString::fromUtf8(core::valueMappingName(m_spectrum->mapping)),
             QString::fromUtf8(core::transformName(m_spectrum->kind)))
        .arg(over, 0, 'g', 3)
        .arg(corrected ? tr("gridding corrected") : tr("no gridding correction"));
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
    chooseRenderer();
    m_quad = std::make_unique<QOpenGLShaderProgram>();
    m_quad->addShaderFromSourceCode(QOpenGLShader::Vertex, kQuadVertex);
    m_quad->addShaderFromSourceCode(QOpenGLShader::Fragment, kQuadFragment);
    if (!m_quad->link()) m_notice += tr(" (display shader failed: %1)").arg(m_quad->log());
    m_vao = std::make_unique<QOpenGLVertexArrayObject>();
    m_vao->create();
    emit backendChanged(m_gpu != nullptr, backendNotice());
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
            recordStageTimes(t, true);
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
    const int M = image.width; // the views render squares
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

OverlayState ProjectionView::overlayState() const {
    OverlayState s;
    s.widget = size();
    s.image = imageRect();
    s.font = font();
    s.hasImage = m_spectrum != nullptr;
    s.pending = m_pending;
    s.title = m_title;
    s.performance = m_overlay;
    s.sliceSize = m_settings.size;
    s.zoom = m_zoom;
    if (m_reference) {
        s.differenceTo = m_reference->m_title;
        s.differenceUnits = valueUnits();
    }
    if (!m_title.isEmpty()) s.spectrum = spectrumText(); // compare views: each its own
    s.progressiveOff = m_progressiveOff;
    s.labels = orientationLabels();
    s.notice = m_renderError.isEmpty() ? m_notice : m_renderError + '\n' + m_notice;
    s.shown = m_renderedQuality;
    s.gpu = m_gpu != nullptr;
    s.voxelModel = m_settings.voxelModel;
    if (coneBeam() && m_volume) {
        const core::CArmAngles a = core::cArmAngles(*m_volume, m_view);
        s.coneGeometry = QString::fromStdString(core::cArmLabel(a.primaryDeg, a.secondaryDeg)) +
                         tr("  SID %1  SOD %2 mm")
                             .arg(m_settings.cone.sid, 0, 'f', 0)
                             .arg(m_settings.cone.sod, 0, 'f', 0);
        s.rayModel = m_settings.cone.model;
        s.gpu = m_coneOnGpu;
    }
    s.effects = m_effects;
    s.stats = m_stats;
    s.interacting = m_progressive.interacting();
    s.progressive = m_progressive.enabled();
    s.targetFps = m_progressive.targetFps();
    s.level = m_renderedLevel;
    s.lastLevel = int(m_progressive.levels().size()) - 1;
    s.window = m_window;
    s.output = ViewOverlay::polychromaticLine(m_poly.get());
    return s;
}

void ProjectionView::drawOverlay() {
    QPainter p(this);
    m_measure->paint(p); // under the overlay's text
    overlay().paint(p);
}

QStringList ProjectionView::orientationLabels() const {
    if (!m_volume) return {};
    return ViewOverlay::orientationLabels(*m_volume, m_view);
}

QString ProjectionView::overlayText() const { return overlay().text(); }

QStringList ProjectionView::colourBarLabels() const { return overlay().colourBarLabels(); }

QRect ProjectionView::colourBarRect() const { return overlay().colourBarRect(); }

QRect ProjectionView::overlayBox() const { return overlay().box(); }

QList<QRect> ProjectionView::orientationLabelRects() const { return overlay().labelRects(); }

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
        // Half a turn across the view's shorter side.
        const double k = 180.0 / std::max(1, std::min(width(), height()));
        rotateBy(delta.x() * k, delta.y() * k);
    } else if (m_dragButton == Qt::MiddleButton) {
        setPan(m_pan + QPointF(delta));
    }
}

void ProjectionView::rotateBy(double horizontalDeg, double verticalDeg) {
    if (coneBeam()) {
        rotateCArm(horizontalDeg, verticalDeg);
        return;
    }
    const double k = std::numbers::pi / 180.0;
    core::ViewFrame f = m_view;
    if (horizontalDeg != 0.0) f = f.rotated(f.u, horizontalDeg * k);
    if (verticalDeg != 0.0) f = f.rotated(f.r, verticalDeg * k);
    setViewFrame(f);
    emit viewFrameChanged(m_view);
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
