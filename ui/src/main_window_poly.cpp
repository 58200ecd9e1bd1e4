// The workstation's polychromatic output (issue 19): the material spectra of the study in the
// background (per gridding correction the views' kernels need), then the views render them with
// the X-ray panel's tube, detector and noise.
#include <QSettings>
#include <QTimer>

#include <set>

#include <fvr/core/errors.h>
#include <fvr/core/xray/polychromatic_render.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

int MainWindow::polyKey(core::Kernel kernel) const {
    const auto d = m_study->settingsFor(kernel).deapodizeFor;
    return d ? int(*d) : -1;
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
    if (vol != m_polyVolume) { // a new study: its own materials
        if (m_polyCancel) m_polyCancel->cancel(); // a running job's are the old study's
        m_polySpectra.clear();
        m_polySources.clear();
        m_polyVolume = vol;
    }
    std::set<int> missing;
    for (std::size_t i = 0; i < m_views.size(); ++i)
        if (!m_polySpectra.count(polyKey(m_viewSettings[i].kernel)))
            missing.insert(polyKey(m_viewSettings[i].kernel));
    pushPolychromatic(); // the views with their materials render, the others wait
    if (missing.empty() || (m_polyTimer && m_polyTimer->isActive())) return;
    m_polyCancel = std::make_shared<core::CancelToken>();
    core::PreprocessOptions po;
    po.transform = m_study->spectrumSettings().transform;
    po.oversampling = m_study->spectrumSettings().oversampling;
    m_polyJob = std::async(std::launch::async, [vol, po, missing, cancel = m_polyCancel] {
        std::map<int, MaterialSpectra> out;
        for (int key : missing) {
            core::PreprocessOptions o = po;
            if (key >= 0) o.deapodizeFor = core::Kernel(key);
            out[key] =
                core::preprocessMaterials(*vol, core::MaterialMapping{}, o, {}, cancel.get());
        }
        return out;
    });
    message(tr("Preparing the material spectra (air, soft tissue, bone)…"));
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
    const bool stale = m_polyCancel->cancelled(); // another study came while it ran
    std::map<int, MaterialSpectra> ready;
    try {
        ready = m_polyJob.get();
    } catch (const core::Cancelled&) {
        return applyPolychromatic(); // the new study's materials
    } catch (const std::exception& e) {
        message(tr("The material spectra failed: %1").arg(QString::fromUtf8(e.what())), true);
        m_xray->setMaterialMemory(tr("failed"));
        return;
    }
    if (stale || m_polyVolume != m_study->volume()) return applyPolychromatic();
    m_polySpectra.insert(ready.begin(), ready.end());
    double bytes = 0.0;
    int count = 0;
    for (const auto& [key, spectra] : m_polySpectra)
        for (const auto& s : spectra) {
            bytes += double(s->bytes());
            ++count;
        }
    m_xray->setMaterialMemory(tr("%1 spectra, %2 MB").arg(count).arg(bytes / (1 << 20), 0, 'f', 0));
    m_polyRewindow = true;
    applyPolychromatic();
}

void MainWindow::pushPolychromatic() {
    const XrayPanel::Values& x = m_model->xray();
    if (!isPolychromatic(x.output) || m_polyVolume != m_study->volume()) return;
    const bool newQuantity = m_polyValues && m_polyValues->show != x.show;
    if (!m_polyValues || *m_polyValues != x) { // a new response: new sources
        m_polySources.clear();
        m_polyValues = x;
    }
    static const auto waiting = std::make_shared<const PolychromaticSource>(); // no spectra yet
    for (std::size_t i = 0; i < m_views.size(); ++i) {
        const int key = polyKey(m_viewSettings[i].kernel);
        const auto spectra = m_polySpectra.find(key);
        if (spectra == m_polySpectra.end()) {
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
            s->noise.mAs = x.noiseMas;
            s->show = x.show;
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
