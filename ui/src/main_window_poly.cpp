// The workstation's polychromatic output (issue 19): the material spectra of the study in the
// background, then the views render them with the X-ray panel's tube, detector and noise.
#include <QSettings>
#include <QTimer>

#include <fvr/core/errors.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

void MainWindow::applyPolychromatic() {
    if (!isPolychromatic(m_model->xray().output)) {
        for (auto* v : m_views) v->setPolychromatic(nullptr);
        return;
    }
    const auto vol = m_study->volume();
    if (!vol) return; // the study's spectrum brings it (onSpectrumReady)
    if (vol->units != core::ValueUnits::HounsfieldUnits) {
        message(tr("The polychromatic output needs Hounsfield units (materials from CT numbers); "
                   "this study holds %1, so the output stays line integrals.")
                    .arg(QString::fromUtf8(core::unitsName(vol->units))),
                true);
        showOutput(XrayOutput::LineIntegrals);
        applyOutput(true);
        return;
    }
    if (vol == m_polyVolume) return pushPolychromatic();
    if (vol == m_polyJobVolume) return; // being prepared
    if (m_polyCancel) m_polyCancel->cancel();
    m_polyJobVolume = vol;
    m_polyCancel = std::make_shared<core::CancelToken>();
    core::PreprocessOptions po; // no deapodization: any kernel renders the material spectra
    po.transform = m_study->spectrumSettings().transform;
    po.oversampling = m_study->spectrumSettings().oversampling;
    m_polyJob = std::async(std::launch::async, [vol, po, cancel = m_polyCancel] {
        return core::preprocessMaterials(*vol, core::MaterialMapping{}, po, {}, cancel.get());
    });
    message(tr("Preparing the material spectra (air, soft tissue, bone)…"));
    const auto waiting = std::make_shared<PolychromaticSource>(); // no spectra yet
    for (auto* v : m_views) v->setPolychromatic(waiting);
    m_xray->setMaterialMemory(tr("preparing…"));
    if (!m_polyTimer) {
        m_polyTimer = new QTimer(this);
        connect(m_polyTimer, &QTimer::timeout, this, &MainWindow::pollPolychromaticJob);
    }
    m_polyTimer->start(50);
}

void MainWindow::pollPolychromaticJob() {
    if (!m_polyJob.valid() ||
        m_polyJob.wait_for(std::chrono::seconds(0)) != std::future_status::ready)
        return;
    m_polyTimer->stop();
    const auto vol = m_polyJobVolume;
    m_polyJobVolume.reset();
    try {
        m_polySpectra = m_polyJob.get();
        m_polyVolume = vol;
    } catch (const core::Cancelled&) {
        return;
    } catch (const std::exception& e) {
        message(tr("The material spectra failed: %1").arg(QString::fromUtf8(e.what())), true);
        m_xray->setMaterialMemory(tr("failed"));
        return;
    }
    double bytes = 0.0;
    for (const auto& s : m_polySpectra) bytes += double(s->bytes());
    m_xray->setMaterialMemory(
        tr("%1 spectra, %2 MB").arg(m_polySpectra.size()).arg(bytes / (1 << 20), 0, 'f', 0));
    m_polyRewindow = true;
    if (vol == m_study->volume()) applyPolychromatic();
}

void MainWindow::pushPolychromatic() {
    const XrayPanel::Values& x = m_model->xray();
    if (!isPolychromatic(x.output) || m_polySpectra.empty() || m_polyVolume != m_study->volume())
        return;
    auto source = std::make_shared<PolychromaticSource>();
    source->spectra = m_polySpectra;
    try {
        const core::TubeSpectrum spectrum =
            core::tubeSpectrum(x.kvp, x.filtrationAlMm, x.filtrationCuMm);
        const core::DetectorModel detector{x.detector == 1 ? core::DetectorKind::PhotonCounting
                                                           : core::DetectorKind::EnergyIntegrating,
                                           x.csiUm};
        source->response = std::make_shared<const core::SpectralResponse>(spectrum, detector,
                                                                          core::defaultMaterials());
    } catch (const std::exception& e) {
        message(tr("Polychromatic output: %1").arg(QString::fromUtf8(e.what())), true);
        return;
    }
    source->noise.mAs = x.noiseMas;
    source->show = x.show;
    const bool newQuantity = !m_views.empty() && m_views[0]->polychromatic() &&
                             !m_views[0]->polychromatic()->spectra.empty() &&
                             m_views[0]->polychromatic()->show != x.show;
    for (auto* v : m_views) v->setPolychromatic(source);
    if (m_polyRewindow || newQuantity) { // -ln(I/I0) and g/cm^2 need their own window
        m_polyRewindow = false;
        applyPreset(WindowPreset::Auto);
    }
}

} // namespace fvr::ui
