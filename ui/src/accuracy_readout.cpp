#include <fvr/ui/accuracy_readout.h>

#include <fvr/core/render/image_metrics.h>
#include <fvr/core/render/spatial_projector.h>
#include <fvr/ui/projection_view.h>
#include <fvr/ui/study.h>

namespace fvr::ui {

AccuracyReadout::AccuracyReadout(QObject* parent) : QObject(parent) {}

AccuracyReadout::~AccuracyReadout() = default; // m_jobs waits for a running measurement

void AccuracyReadout::measure(ProjectionView& view, const StudyController& study) {
    if (!study.volume() || !study.spectrum()) return;
    if (m_jobs.running()) {
        emit message(tr("The accuracy measurement is still running"), false);
        return;
    }
    if (view.effects().filter.active()) {
        emit message(tr("The accuracy readout compares with ray casting, which has no slice "
                        "filters: turn edge "
                        "enhancement and the band limit off to measure."),
                     true);
        return;
    }
    if (view.polychromatic() && !view.polychromatic()->spectra.empty()) {
        // -ln(I/I0) against mu ray casting compared two different quantities (19 dB where the
        // same view's line integrals give 45 dB): no figure rather than a misleading one.
        emit message(tr("The accuracy readout compares line integrals with ray casting of the "
                        "same voxels; the polychromatic output shows %1, a non-linear function "
                        "of three material integrals that the ray caster does not make. Set "
                        "X-ray ▸ Output to Line integrals to measure the renderer (the spectral "
                        "response is then applied to those integrals per pixel).")
                         .arg(ViewOverlay::polychromaticQuantity(view.polychromatic()->show)),
                     true);
        return;
    }
    auto fvr = view.projection();
    if (!fvr) return;
    const auto volume = study.volume();
    // The ray caster with the same voxel model, depth weighting and pixel sampling as the frame.
    const core::RenderParams rendered = view.renderParams(fvr->width, view.settings().kernel);
    const core::SpatialProjectorOptions options =
        core::matchingProjectorOptions(rendered, study.spectrum()->mapping);
    const QString reference =
        QString::fromStdString(core::describeProjector(options, rendered.voxelModel));
    const core::ViewFrame frame = fvr->view;
    const core::ImageGeometry geom = fvr->geometry();
    emit message(tr("Measuring accuracy: %1 of the same view, in the background…").arg(reference),
                 false);
    m_jobs.run(
        [volume, options, frame, geom, fvr = *fvr](core::CancelToken&) {
            core::SpatialProjector sp(*volume, options);
            return core::compareImages(fvr.pixels, sp.project(frame, geom).pixels);
        },
        [this, reference](const core::ImageComparison& c) {
            emit message(tr("Accuracy of view 1 against %1: PSNR %2 dB, relative RMSE %3 %")
                             .arg(reference)
                             .arg(c.psnr, 0, 'f', 2)
                             .arg(c.relRmse * 100.0, 0, 'f', 2),
                         false);
            emit measured(c.psnr, c.relRmse);
        },
        [this](const JobError& e) {
            emit message(tr("Accuracy measurement failed: %1").arg(e.message), true);
        });
}

} // namespace fvr::ui
