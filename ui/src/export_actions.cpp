// The main window's exports: screenshot, float or 16-bit projection, rotation sweep, clipboard.
#include <fvr/ui/main_window.h>

#include <QClipboard>
#include <QDir>
#include <QFileDialog>
#include <QFileInfo>
#include <QGuiApplication>
#include <QInputDialog>
#include <QPainter>
#include <QProgressDialog>
#include <QSaveFile>
#include <QSettings>
#include <QStandardPaths>

#include <cmath>
#include <numbers>

#include <fvr/core/dicom/dicom_export.h>
#include <fvr/core/errors.h>
#include <fvr/core/io/image_io.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

bool MainWindow::exportScreenshot(const QString& path) {
    if (m_views.empty()) return false;
    const QImage img = m_compareCount == 1 ? m_views[0]->screenshot() : grabWithViews(m_viewHost);
    QSaveFile f(path);
    if (!f.open(QIODevice::WriteOnly) || !img.save(&f, "PNG") || !f.commit()) {
        message(tr("Could not write %1: %2").arg(path, f.errorString()), true);
        return false;
    }
    message(tr("Saved screenshot %1").arg(path));
    return true;
}

QImage MainWindow::grabWithViews(QWidget* w) const {
    QImage img = w->grab().toImage();
    QPainter p(&img); // logical coordinates, whatever the device pixel ratio
    for (ProjectionView* v : m_views) {
        const QPoint at = v->mapTo(w, QPoint(0, 0));
        p.drawImage(QRectF(QPointF(at), QSizeF(v->size())), v->screenshot());
    }
    return img;
}

bool MainWindow::exportProjection(const QString& path) {
    if (m_views.empty()) return false;
    const auto p = m_views[0]->projection();
    if (!p) {
        message(tr("Nothing to export yet"), true);
        return false;
    }
    // Float exports hold what the display shows before the window: the transmitted intensity in
    // Beer-Lambert mode, else the line integrals. The PNG goes through the display window itself.
    const core::Transmission t = currentTransmission();
    try {
        const QString ext = QFileInfo(path).suffix().toLower();
        const std::string out = path.toStdString();
        std::vector<float> values = p->pixels;
        if (t.active() && ext != "png") core::applyTransmission(values, t);
        if (ext == "npy")
            core::writeNpy(out, values.data(), p->height, p->width);
        else if (ext == "pfm")
            core::writePfm(out, values.data(), p->height, p->width);
        else if (ext == "png")
            core::writePng(out, withAnnotations(*p).data(), p->height, p->width,
                           m_views[0]->window(), 16);
        else if (ext == "dcm")
            writeDicomProjection(out);
        else
            throw core::WriteError(out + ": unknown format (expected .npy, .pfm, .png or .dcm)");
    } catch (const std::exception& e) {
        message(tr("Could not export: %1").arg(QString::fromUtf8(e.what())), true);
        return false;
    }
    message(tr("Exported projection %1 (%2 × %3, pixel %4 mm, %5)")
                .arg(path)
                .arg(p->width)
                .arg(p->height)
                .arg(p->pixelSize, 0, 'g', 4)
                .arg(exportedQuantity()));
    return true;
}

QString MainWindow::exportedQuantity() const {
    if (const core::Transmission t = currentTransmission(); t.active())
        return tr("transmitted intensity, μ_water %1/mm, exposure %2")
            .arg(t.muWaterPerMm, 0, 'f', 4)
            .arg(t.exposure);
    // The polychromatic output of view 1, once its material spectra have come (till then it
    // shows, and exports, its line integrals).
    const auto& poly = m_views.empty() ? nullptr : m_views[0]->polychromatic();
    if (poly && !poly->spectra.empty()) {
        QString q = tr("polychromatic %1, %2")
                        .arg(ViewOverlay::polychromaticQuantity(poly->show),
                             ViewOverlay::polychromaticBeam(poly->kvp, poly->filtrationAlMm,
                                                            poly->filtrationCuMm));
        if (poly->show < 0 && poly->noise.active())
            q += tr(", noise %1 mAs").arg(poly->noise.mAs, 0, 'g', 3);
        return q;
    }
    return core::isAttenuation(m_study->spectrumSettings().mapping)
               ? tr("line integrals, mm (μ/μ_water × mm)")
               : tr("line integrals of the stored values × mm");
}

/** What the DICOM export takes from the display: the user's window in the written values' units
 *  (a window on the log exposure becomes the intensities at its ends: the viewer's linear
 *  window then spans the same intensities), the patient orientation where the volume knows it,
 *  and a series of its own. */
static void addDisplayToExport(core::DicomExportInfo& info, const core::DisplayWindow& w,
                               const core::Volume& volume) {
    double lo = w.low, hi = w.high;
    if (w.transmission.active()) {
        lo = std::pow(10.0, lo);
        hi = std::pow(10.0, hi);
    }
    info.window = core::DisplayWindowValues{0.5 * (lo + hi), hi - lo, w.invert};
    if (volume.orientationStated) info.patientDirection = volume.direction;
    info.seriesNumber = core::newExportSeriesNumber();
}

core::DicomExportInfo MainWindow::dicomExportInfo() const {
    core::DicomExportInfo info = core::exportInfoFor(m_study->series());
    const core::Transmission t = currentTransmission();
    const auto& poly = m_views[0]->polychromatic();
    if (t.active()) {
        info.valueDescription = "transmitted intensity (mu_water " +
                                std::to_string(t.muWaterPerMm) + "/mm, exposure " +
                                std::to_string(t.exposure) + ")";
    } else if (poly && !poly->spectra.empty()) {
        // -ln(I/I0) or g/cm^2 and the tube, in ASCII (the file declares no character set).
        info.valueDescription = exportedQuantity()
                                    .replace(QStringLiteral("−"), QStringLiteral("-"))
                                    .replace(QStringLiteral("²"), QStringLiteral("^2"))
                                    .toStdString();
    } else {
        info.valueDescription = core::isAttenuation(m_study->spectrumSettings().mapping)
                                    ? "line integral, mm (mu/mu_water x mm)"
                                    : "line integral of the stored values x mm";
    }
    addDisplayToExport(info, m_views[0]->window(), *m_study->volume());
    return info;
}

void MainWindow::writeDicomProjection(const std::string& path) const {
    const auto p = m_views.empty() ? std::nullopt : m_views[0]->projection();
    if (!p) throw core::WriteError(path + ": nothing to export yet");
    core::ProjectionImage image = *p;
    if (const core::Transmission t = currentTransmission(); t.active())
        core::applyTransmission(image.pixels, t);
    core::DicomExportInfo info = dicomExportInfo();
    info.overlay = annotationOverlay(image.width, image.height); // view 1's annotations
    core::writeDicomProjection(path, image, info);
}

bool MainWindow::exportSweep(const QString& folder, int frames, const core::Vec3& axis) {
    if (m_views.empty() || !m_study->spectrum() || frames < 1) return false;
    if (!QDir().mkpath(folder)) {
        message(tr("Could not create %1").arg(folder), true);
        return false;
    }
    ProjectionView* v = m_views[0];
    const core::ViewFrame start = v->viewFrame();
    QProgressDialog progress(tr("Exporting rotation sweep…"), tr("Cancel"), 0, frames, this);
    progress.setWindowModality(Qt::WindowModal);
    std::vector<float> stack;
    int M = 0;
    bool ok = true;
    for (int i = 0; i < frames; ++i) {
        progress.setValue(i);
        if (progress.wasCanceled()) {
            ok = false;
            break;
        }
        v->setViewFrame(start.rotated(axis, 2.0 * std::numbers::pi * i / frames));
        const auto p = v->projection();
        if (!p) {
            ok = false;
            break;
        }
        M = p->width; // the views render squares
        if (const core::Transmission t = currentTransmission(); t.active()) {
            std::vector<float> intensity = p->pixels;
            core::applyTransmission(intensity, t);
            stack.insert(stack.end(), intensity.begin(), intensity.end());
        } else {
            stack.insert(stack.end(), p->pixels.begin(), p->pixels.end());
        }
        try {
            core::writePng(QDir(folder)
                               .filePath(QStringLiteral("frame_%1.png").arg(i, 4, 10, QChar('0')))
                               .toStdString(),
                           p->pixels.data(), M, M, v->window(), 8);
        } catch (const std::exception& e) {
            message(tr("Sweep export failed: %1").arg(QString::fromUtf8(e.what())), true);
            ok = false;
            break;
        }
    }
    progress.setValue(frames);
    v->setViewFrame(start);
    if (ok) {
        try {
            core::writeNpy(QDir(folder).filePath("sweep.npy").toStdString(), stack.data(), M, M,
                           frames);
        } catch (const std::exception& e) {
            message(tr("Sweep export failed: %1").arg(QString::fromUtf8(e.what())), true);
            return false;
        }
        message(tr("Exported %1 frames to %2 (PNG frames and sweep.npy: %3)")
                    .arg(frames)
                    .arg(folder, exportedQuantity()));
    } else {
        message(tr("Sweep export stopped"), true);
    }
    return ok;
}

QString MainWindow::exportFolder() {
    const QString last = QSettings().value(keys::kLastExportFolder).toString();
    if (!last.isEmpty() && QFileInfo(last).isDir()) return last;
    const QString pictures = QStandardPaths::writableLocation(QStandardPaths::PicturesLocation);
    if (!pictures.isEmpty() && QFileInfo(pictures).isDir()) return pictures;
    return QDir::homePath();
}

namespace {
void rememberExportFolder(const QString& folder) {
    QSettings().setValue(keys::kLastExportFolder, folder);
}
} // namespace

void MainWindow::exportScreenshotDialog() {
    const QString path = QFileDialog::getSaveFileName(
        this, tr("Export screenshot"), exportFolder() + "/view.png", tr("PNG image (*.png)"));
    if (!path.isEmpty() && exportScreenshot(path))
        rememberExportFolder(QFileInfo(path).absolutePath());
}

void MainWindow::exportProjectionDialog() {
    const QString path = QFileDialog::getSaveFileName(
        this, tr("Export projection"), exportFolder() + "/projection.npy",
        tr("Float values, as shown before the window (*.npy);;16-bit PNG, current window "
           "(*.png);;PFM float (*.pfm);;"
           "DICOM Secondary Capture (*.dcm)"));
    if (!path.isEmpty() && exportProjection(path))
        rememberExportFolder(QFileInfo(path).absolutePath());
}

void MainWindow::exportSweepDialog() {
    bool ok = false;
    const int n = QInputDialog::getInt(this, tr("Rotation sweep"),
                                       tr("Frames around the patient's head-feet axis:"), 36, 1,
                                       3600, 1, &ok);
    if (!ok) return;
    const QString folder =
        QFileDialog::getExistingDirectory(this, tr("Folder for the sweep"), exportFolder());
    if (folder.isEmpty() || !m_study->volume()) return;
    rememberExportFolder(folder);
    // Head-feet axis of the patient in the volume's index frame.
    const auto& d = m_study->volume()->direction;
    exportSweep(folder, n, {d[0][2], d[1][2], d[2][2]});
}

void MainWindow::copyToClipboard() {
    if (m_views.empty()) return;
    QGuiApplication::clipboard()->setImage(m_compareCount == 1 ? m_views[0]->screenshot()
                                                               : m_viewHost->grab().toImage());
    message(tr("Copied the view to the clipboard"));
}

} // namespace fvr::ui
