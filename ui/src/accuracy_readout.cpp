#include <fvr/ui/accuracy_readout.h>

#include <fvr/core/render/image_metrics.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/ui/projection_view.h>
#include <fvr/ui/study.h>

namespace fvr::ui {

AccuracyReadout::AccuracyReadout(QObject* parent) : QObject(parent) {}

AccuracyReadout::~AccuracyReadout() {
    if (m_worker.joinable()) m_worker.join();
}

void AccuracyReadout::measure(ProjectionView& view, const StudyController& study) {
    if (!study.volume() || !study.spectrum()) return;
    if (m_worker.joinable()) {
        if (!m_done.load()) {
            emit message(tr("The accuracy measurement is still running"), false);
            return;
        }
        m_worker.join();
    }
    if (view.effects().filter.active()) {
        emit message(tr("The accuracy readout compares with ray casting, which has no slice "
                        "filters: turn edge "
                        "enhancement and the band limit off to measure."),
                     true);
        return;
    }
    auto fvr = view.projection();
    if (!fvr) return;
    const auto volume = study.volume();
    // The ray caster with the same voxel model, depth weighting and pixel sampling as the frame.
    const core::RenderParams rendered = view.renderParams(fvr->size, view.settings().kernel);
    const core::SpatialProjectorOptions options =
        core::matchingProjectorOptions(rendered, study.spectrum()->mapping);
    const QString reference =
        QString::fromStdString(core::describeProjector(options, rendered.voxelModel));
    const core::ViewFrame frame = fvr->view;
    const core::ImageGeometry geom{fvr->size, fvr->pixelSize};
    emit message(tr("Measuring accuracy: %1 of the same view, in the background…").arg(reference),
                 false);
    m_done.store(false);
    m_worker = std::thread([this, volume, options, reference, frame, geom, fvr = *fvr] {
        double psnr = 0, rel = 0;
        try {
            core::SpatialProjector sp(*volume, options);
            const core::ImageComparison c =
                core::compareImages(fvr.pixels, sp.project(frame, geom).pixels);
            psnr = c.psnr;
            rel = c.relRmse;
        } catch (const std::exception& e) {
            const QString what = QString::fromUtf8(e.what());
            QMetaObject::invokeMethod(
                this,
                [this, what] {
                    emit message(tr("Accuracy measurement failed: %1").arg(what), true);
                },
                Qt::QueuedConnection);
            m_done.store(true);
            return;
        }
        QMetaObject::invokeMethod(
            this,
            [this, psnr, rel, reference] {
                emit message(tr("Accuracy of view 1 against %1: PSNR %2 dB, relative RMSE %3 %")
                                 .arg(reference)
                                 .arg(psnr, 0, 'f', 2)
                                 .arg(rel * 100.0, 0, 'f', 2),
                             false);
                emit measured(psnr, rel);
            },
            Qt::QueuedConnection);
        m_done.store(true);
    });
}

} // namespace fvr::ui
