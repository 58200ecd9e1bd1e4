// The workstation's polychromatic output: the material spectra of the study, prepared in the
// background by the MaterialsController (per gridding correction the views' kernels need), then
// rendered by the views with the X-ray panel's tube, detector and noise.
#include <set>

#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/materials_controller.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

int MainWindow::polyKey(core::Kernel kernel) const {
    return MaterialsController::keyFor(m_study->settingsFor(kernel).deapodizeFor);
}

void MainWindow::connectMaterials() {
    connect(m_materials.get(), &MaterialsController::ready, this, [this] {
        if (m_materials->volume() != m_study->volume()) return applyPolychromatic();
        m_xray->setMaterialMemory(tr("%1 spectra, %2 MB")
                                      .arg(m_materials->spectrumCount())
                                      .arg(m_materials->spectraMiB(), 0, 'f', 0));
        m_polyRewindow = true;
        applyPolychromatic();
    });
    // Cancelled for another study, or that study came while it ran: the new study's materials.
    connect(m_materials.get(), &MaterialsController::discarded, this,
            &MainWindow::applyPolychromatic);
    connect(m_materials.get(), &MaterialsController::failed, this, [this](const QString& error) {
        message(tr("The material spectra failed: %1").arg(error), true);
        m_xray->setMaterialMemory(tr("failed"));
    });
}

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
    if (m_materials->setVolume(vol)) m_polySources.clear(); // a new study: its own materials
    std::set<int> missing;
    for (std::size_t i = 0; i < m_views.size(); ++i)
        if (!m_materials->has(polyKey(m_viewSettings[i].kernel)))
            missing.insert(polyKey(m_viewSettings[i].kernel));
    pushPolychromatic(); // the views with their materials render, the others wait
    if (missing.empty() || m_materials->busy()) return;
    m_materials->prepare(missing, m_study->spectrumSettings());
    message(tr("Preparing the material spectra (air, soft tissue, bone)…"));
    m_xray->setMaterialMemory(tr("preparing…"));
}

void MainWindow::pushPolychromatic() {
    const XrayPanel::Values& x = m_model->xray();
    if (!isPolychromatic(x.output) || m_materials->volume() != m_study->volume()) return;
    const bool newQuantity = m_polyValues && m_polyValues->show != x.show;
    if (!m_polyValues || *m_polyValues != x) { // a new response: new sources
        m_polySources.clear();
        m_polyValues = x;
    }
    static const auto waiting = std::make_shared<const PolychromaticSource>(); // no spectra yet
    for (std::size_t i = 0; i < m_views.size(); ++i) {
        const int key = polyKey(m_viewSettings[i].kernel);
        const auto spectra = m_materials->spectra().find(key);
        if (spectra == m_materials->spectra().end()) {
            m_views[i]->setPolychromatic(waiting);
            continue;
        }
        auto& source = m_polySources[key];
        if (!source) {
            auto s = std::make_shared<PolychromaticSource>();
            s->spectra = spectra->second;
            try {
                const core::DetectorModel detector{x.detector == 1
                                                       ? core::DetectorKind::PhotonCounting
                                                       : core::DetectorKind::EnergyIntegrating,
                                                   x.csiUm};
                s->response = std::make_shared<const core::SpectralResponse>(
                    core::tubeSpectrum(x.kvp, x.filtrationAlMm, x.filtrationCuMm), detector,
                    core::defaultMaterials());
            } catch (const std::exception& e) {
                message(tr("Polychromatic output: %1").arg(QString::fromUtf8(e.what())), true);
                return;
            }
            // Quantum noise is the detected intensity's: it goes on -ln(I/I0), and a material's
            // mass thickness (the decomposition's truth, no measurement) has none.
            s->noise.mAs = x.show < 0 ? x.noiseMas : 0.0;
            s->show = x.show;
            s->kvp = x.kvp;
            s->filtrationAlMm = x.filtrationAlMm;
            s->filtrationCuMm = x.filtrationCuMm;
            source = s;
        }
        m_views[i]->setPolychromatic(source);
    }
    if (m_polyRewindow || newQuantity) { // -ln(I/I0) and g/cm^2 need their own window
        m_polyRewindow = false;
        applyPreset(WindowPreset::Auto);
    }
}

} // namespace fvr::ui
