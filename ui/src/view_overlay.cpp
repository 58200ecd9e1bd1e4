#include <fvr/ui/view_overlay.h>

#include <QFontMetrics>
#include <QLinearGradient>
#include <QPainter>

#include <algorithm>
#include <cmath>

#include <fvr/core/xray/patient_views.h>

namespace fvr::ui {

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

const QColor kOverlayGreen(140, 240, 140);
} // namespace

QStringList ViewOverlay::orientationLabels(const core::Volume& volume,
                                           const core::ViewFrame& view) {
    // A file without orientation: the labels follow the assumed one and say so.
    const QString assumed = volume.orientationStated ? QString() : tr(" (assumed)");
    auto lbl = [&](const core::Vec3& v) {
        return QString::fromStdString(core::patientDirectionLabel(volume, v)) + assumed;
    };
    return {lbl(-view.r), lbl(view.r), lbl(view.u), lbl(-view.u)};
}

QString ViewOverlay::polychromaticQuantity(int show) {
    // The materials of core::defaultMaterials(), in the X-ray panel's words.
    static const char* const kMaterials[] = {QT_TR_NOOP("air"), QT_TR_NOOP("soft tissue"),
                                             QT_TR_NOOP("bone")};
    if (show < 0) return QStringLiteral("−ln(I/I0)");
    const QString name = show < 3 ? tr(kMaterials[show]) : tr("material %1").arg(show);
    return tr("%1 mass thickness (g/cm²)").arg(name);
}

QString ViewOverlay::polychromaticBeam(double kvp, double filtrationAlMm, double filtrationCuMm) {
    QString beam = tr("%1 kVp, %2 mm Al").arg(kvp, 0, 'g', 4).arg(filtrationAlMm, 0, 'g', 3);
    if (filtrationCuMm > 0) beam += tr(", %1 mm Cu").arg(filtrationCuMm, 0, 'g', 3);
    return beam;
}

QString ViewOverlay::polychromaticLine(const PolychromaticSource* source) {
    if (!source) return {};
    if (source->spectra.empty())
        return tr("polychromatic: preparing the material spectra (line integrals meanwhile)");
    QString line =
        tr("polychromatic %1: %2")
            .arg(polychromaticBeam(source->kvp, source->filtrationAlMm, source->filtrationCuMm),
                 polychromaticQuantity(source->show));
    if (source->show < 0 && source->noise.active())
        line += tr("  noise %1 mAs").arg(source->noise.mAs, 0, 'g', 3);
    return line;
}

QFont ViewOverlay::font(bool bold) const {
    QFont f = m_s.font;
    f.setPointSizeF(std::max(8.0, f.pointSizeF()));
    f.setBold(bold);
    return f;
}

QString ViewOverlay::text() const {
    QStringList lines;
    if (!m_s.title.isEmpty()) lines << m_s.title;
    if (m_s.performance) lines << performanceLines();
    if (m_s.differenceTo) lines << tr("difference to %1").arg(*m_s.differenceTo);
    return lines.join('\n');
}

QRect ViewOverlay::box() const { return box(text()); }

QRect ViewOverlay::box(const QString& text) const {
    if (text.isEmpty() || !m_s.hasImage) return {};
    const QRect box = QFontMetrics(font()).boundingRect(
        QRect(8, 6, m_s.widget.width() - 16, m_s.widget.height() - 12),
        Qt::AlignLeft | Qt::AlignTop, text);
    return box.adjusted(-4, -2, 4, 2);
}

QList<QRect> ViewOverlay::labelRects() const { return labelRects(box()); }

QList<QRect> ViewOverlay::labelRects(const QRect& avoid) const {
    if (m_s.labels.size() != 4) return {}; // left, right, top, bottom
    const QFontMetrics fm(font(true));
    const QRect r =
        m_s.image.intersected(QRectF(QPointF(0, 0), QSizeF(m_s.widget))).toAlignedRect();
    const int pad = 6;
    const QRect inner = r.adjusted(pad, pad, -pad, -pad);
    const int flags[4] = {Qt::AlignLeft | Qt::AlignVCenter, Qt::AlignRight | Qt::AlignVCenter,
                          Qt::AlignHCenter | Qt::AlignTop, Qt::AlignHCenter | Qt::AlignBottom};
    QList<QRect> rects;
    for (int i = 0; i < 4; ++i) {
        QRect b = fm.boundingRect(inner, flags[i], m_s.labels[i]);
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

QString ViewOverlay::speed() const {
    // While dragging the frame rate the user sees; at rest the last frame's time.
    // Without a time on screen (the frame was made for an export, a preset or a difference, or
    // is not on screen yet): the renderer's own time, named so.
    const FrameStats& s = m_s.stats;
    if (s.wallMs <= 0 && s.totalMs > 0) return tr("render %1 ms").arg(s.totalMs, 0, 'f', 1);
    if (s.wallMs <= 0) return QStringLiteral("–");
    if (m_s.interacting)
        return QStringLiteral("%1 fps").arg(1000.0 / std::max(1.0, s.wallMs), 0, 'f', 0);
    return tr("frame %1 ms").arg(s.wallMs, 0, 'f', 0);
}

QString ViewOverlay::stageLine() const {
    const FrameStats& s = m_s.stats;
    if (s.fused && s.displayFused)
        return QStringLiteral("slice+inverse+display %1 ms (fused)").arg(s.inverseMs, 0, 'f', 2);
    if (s.fused)
        return QStringLiteral("slice+inverse %1 ms  display %2 ms")
            .arg(s.inverseMs, 0, 'f', 2)
            .arg(s.displayMs, 0, 'f', 2);
    if (m_s.gpu)
        return QStringLiteral("slice %1  inverse %2  display %3 ms")
            .arg(s.sliceMs, 0, 'f', 2)
            .arg(s.inverseMs, 0, 'f', 2)
            .arg(s.displayMs, 0, 'f', 2);
    // The CPU renderer's stages (the display is the upload, in the frame time).
    return QStringLiteral("slice %1  inverse %2 ms")
        .arg(s.sliceMs, 0, 'f', 2)
        .arg(s.inverseMs, 0, 'f', 2);
}

QStringList ViewOverlay::performanceLines() const {
    QStringList lines;
    if (!m_s.coneGeometry.isEmpty()) {
        // The cone beam is ray cast on the CPU: no kernel, no spectrum's effects.
        lines << tr("%1  cone beam  %2×%2  %3  %4 ray casting")
                     .arg(speed())
                     .arg(m_s.shown.size)
                     .arg(m_s.gpu ? QStringLiteral("GPU") : QStringLiteral("CPU"))
                     .arg(QString::fromUtf8(core::rayModelName(m_s.rayModel)));
        lines << m_s.coneGeometry;
        if (!m_s.output.isEmpty()) lines << m_s.output;
        if (m_s.progressive && m_s.level > 0)
            lines << tr("interactive level %1/%2 (target %3 fps)")
                         .arg(m_s.level)
                         .arg(m_s.lastLevel)
                         .arg(m_s.targetFps, 0, 'f', 0);
        if (m_s.window.transmission.active())
            lines << tr("Beer-Lambert μw %1/mm ×%2")
                         .arg(m_s.window.transmission.muWaterPerMm, 0, 'f', 4)
                         .arg(m_s.window.transmission.exposure, 0, 'g', 3);
        lines << tr("ray casting %1 ms").arg(m_s.stats.totalMs, 0, 'f', 1);
        lines << QStringLiteral("W %1  L %2")
                     .arg(m_s.window.high - m_s.window.low, 0, 'g', 4)
                     .arg((m_s.window.high + m_s.window.low) / 2, 0, 'g', 4);
        return lines;
    }
    lines << QStringLiteral("%1  %2  %3×%3  %4  %5 voxels%6")
                 .arg(speed())
                 .arg(QString::fromUtf8(core::kernelName(m_s.shown.kernel)))
                 .arg(m_s.shown.size)
                 .arg(m_s.gpu ? QStringLiteral("GPU") : QStringLiteral("CPU"))
                 .arg(QString::fromUtf8(core::voxelModelLabel(m_s.voxelModel)))
                 .arg(m_s.effects.pixelAperture ? tr(", area pixels") : QString());
    if (!m_s.spectrum.isEmpty()) lines << m_s.spectrum;
    if (!m_s.progressive && !m_s.progressiveOff.isEmpty())
        lines << tr("progressive refinement off %1").arg(m_s.progressiveOff);
    if (m_s.progressive)
        lines << (m_s.level == 0
                      ? tr("full quality (interactive target %1 fps)").arg(m_s.targetFps, 0, 'f', 0)
                      : tr("interactive level %1/%2 (target %3 fps)")
                            .arg(m_s.level)
                            .arg(m_s.lastLevel)
                            .arg(m_s.targetFps, 0, 'f', 0));
    if (!m_s.output.isEmpty()) lines << m_s.output;
    if (m_s.level == 0 && m_s.sliceSize > 0 && m_s.shown.size > m_s.sliceSize) {
        const double r = double(m_s.shown.size) / m_s.sliceSize;
        lines << tr("zoom %1×: rendered %2×%2 for the screen (%3× the pixels of %4×%4)")
                     .arg(m_s.zoom, 0, 'f', 1)
                     .arg(m_s.shown.size)
                     .arg(r * r, 0, 'f', 0)
                     .arg(m_s.sliceSize);
    }
    const QStringList fx = effectsSummary();
    if (!fx.isEmpty()) lines << fx.join(QStringLiteral("  "));
    lines << stageLine();
    lines << QStringLiteral("W %1  L %2")
                 .arg(m_s.window.high - m_s.window.low, 0, 'g', 4)
                 .arg((m_s.window.high + m_s.window.low) / 2, 0, 'g', 4);
    return lines;
}

QStringList ViewOverlay::effectsSummary() const {
    const FrameEffects& e = m_s.effects;
    QStringList fx;
    if (e.depthCue > 0) fx << tr("depth cue %1 %").arg(e.depthCue * 100, 0, 'f', 0);
    if (e.filter.sharpenAmount > 0)
        fx << tr("edges ×%1 (σ %2 mm)")
                  .arg(e.filter.sharpenAmount, 0, 'g', 3)
                  .arg(e.filter.sharpenSigmaMm, 0, 'g', 3);
    if (e.filter.bandLimitLpMm > 0)
        fx << tr("band limit %1 lp/mm").arg(e.filter.bandLimitLpMm, 0, 'g', 3);
    if (m_s.window.transmission.active())
        fx << tr("Beer-Lambert μw %1/mm ×%2")
                  .arg(m_s.window.transmission.muWaterPerMm, 0, 'f', 4)
                  .arg(m_s.window.transmission.exposure, 0, 'g', 3);
    return fx;
}

void ViewOverlay::paint(QPainter& p) const {
    p.setRenderHint(QPainter::TextAntialiasing);
    p.setFont(font());
    if (!m_s.hasImage) {
        paintNoImage(p);
        return;
    }
    // The overlay's text, its box and the labels that keep clear of it: once per frame.
    const QString text = this->text();
    const QRect box = this->box(text);
    const QList<QRect> rects = labelRects(box);
    p.setFont(font(true));
    for (int i = 0; i < int(rects.size()); ++i)
        drawHaloText(p, rects[i], Qt::AlignLeft | Qt::AlignTop, m_s.labels[i],
                     QColor(255, 210, 80));
    p.setFont(font());
    if (!text.isEmpty()) {
        p.fillRect(box, QColor(0, 0, 0, 150));
        p.setPen(kOverlayGreen);
        p.drawText(box.adjusted(4, 2, -4, -2), Qt::AlignLeft | Qt::AlignTop, text);
    }
    paintColourBar(p);
    paintNotice(p);
}

QRect ViewOverlay::colourBarRect() const {
    if (m_s.differenceUnits.isEmpty() || !m_s.hasImage) return {};
    // At the image's right edge (inside the view), half the image's height, centred.
    const QRect r =
        m_s.image.intersected(QRectF(QPointF(0, 0), QSizeF(m_s.widget))).toAlignedRect();
    const int h = std::max(40, r.height() / 2);
    // Left of the right-hand orientation label, which it must not hide.
    int right = r.right() - 8;
    const QList<QRect> labels = labelRects();
    if (labels.size() == 4) right = std::min(right, labels[1].left() - 6);
    return QRect(right - 12, r.center().y() - h / 2, 12, h);
}

QStringList ViewOverlay::colourBarLabels() const {
    if (colourBarRect().isNull()) return {};
    const double hi = m_s.window.high, lo = m_s.window.low;
    auto value = [&](double v) {
        return (v > 0   ? QStringLiteral("+")
                : v < 0 ? QStringLiteral("−")
                        : QString()) +
               QString::number(std::abs(v), 'g', 3) + QStringLiteral(" ") + m_s.differenceUnits;
    };
    return {value(hi), value((hi + lo) / 2), value(lo)};
}

void ViewOverlay::paintColourBar(QPainter& p) const {
    // The display maps the window's low end to black and its high end to white (inverted when
    // the window says so): the bar shows that ramp, its ends and middle labelled with units.
    const QRect bar = colourBarRect();
    if (bar.isNull()) return;
    QLinearGradient g(bar.topLeft(), bar.bottomLeft());
    const QColor top = m_s.window.invert ? Qt::black : Qt::white;
    const QColor bottom = m_s.window.invert ? Qt::white : Qt::black;
    g.setColorAt(0, top);
    g.setColorAt(1, bottom);
    p.fillRect(bar, g);
    p.setPen(kOverlayGreen);
    p.drawRect(bar);
    const QStringList labels = colourBarLabels();
    const QFontMetrics fm(font());
    const int ys[3] = {bar.top(), bar.center().y(), bar.bottom()};
    for (int i = 0; i < 3; ++i) {
        const int w = fm.horizontalAdvance(labels[i]);
        const QRect r(bar.left() - 6 - w, ys[i] - fm.height() / 2, w, fm.height());
        drawHaloText(p, r, Qt::AlignRight | Qt::AlignVCenter, labels[i], kOverlayGreen);
    }
}

void ViewOverlay::paintNoImage(QPainter& p) const {
    const QRect all(QPoint(0, 0), m_s.widget);
    p.setPen(QColor(180, 180, 180));
    p.drawText(all.adjusted(12, 12, -12, -12), Qt::AlignCenter | Qt::TextWordWrap,
               m_s.pending.isEmpty()
                   ? tr("No study loaded\nFile ▸ Open, or drop a DICOM folder or volume file here")
                   : m_s.pending);
    if (!m_s.title.isEmpty())
        drawHaloText(p, all.adjusted(8, 6, -8, -6), Qt::AlignLeft | Qt::AlignTop, m_s.title,
                     kOverlayGreen);
}

void ViewOverlay::paintNotice(QPainter& p) const {
    const QString notice = m_s.notice.trimmed();
    if (notice.isEmpty()) return;
    const QRect area(8, 6, m_s.widget.width() - 16, m_s.widget.height() - 12);
    const int flags = Qt::AlignLeft | Qt::AlignBottom | Qt::TextWordWrap;
    const QRect noticeBox = p.fontMetrics().boundingRect(area, flags, notice);
    p.fillRect(noticeBox.adjusted(-4, -2, 4, 2), QColor(0, 0, 0, 170));
    p.setPen(QColor(255, 130, 110));
    p.drawText(noticeBox, flags, notice);
}

} // namespace fvr::ui
