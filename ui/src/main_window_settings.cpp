// The settings model (the Rendering and X-ray panels) applied to the views and the study
// controller: restored at startup, saved on each change, the spectrum prepared again when a
// setting needs it, and the X-ray output with what it requires of the values.
#include <fvr/ui/main_window.h>

#include <QSettings>

#include <algorithm>

#include <fvr/core/xray/display_window.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

void MainWindow::restorePanels() {
    const QSettings s;
    m_model->setRendering(RenderingPanel::load(s), SettingsModel::Notify::No);
    m_display->setValues(
        DisplayPanel::load(s, m_display->values())); // the window follows the image
    m_model->setXray(XrayPanel::load(s), SettingsModel::Notify::No);
    for (auto* v : m_views) {
        v->setEffects(currentEffects());
        v->setTargetFps(m_model->rendering().targetFps);
        v->setAllowSoftwareGpu(m_model->rendering().softwareGpu);
    }
    m_viewSettings[0] = m_model->viewSettings();
    restoreGeometryPanel();
    if (!m_views.empty()) m_views[0]->setSettings(m_viewSettings[0]);
    m_study->setSpectrumSettings(spectrumSettingsFromPanel());
}

void MainWindow::connectPanels() {
    connect(m_rendering, &RenderingPanel::changed, m_model,
            [this] { m_model->setRendering(m_rendering->values()); });
    connect(m_xray, &XrayPanel::changed, m_model, [this] { m_model->setXray(m_xray->values()); });
    connect(m_rendering, &RenderingPanel::appliesToChanged, this, [this](int slot) {
        if (slot < 0 || slot > int(m_views.size())) return;
        // What the view is set to (it may still wait for its kernel's spectrum); All views:
        // view 1's.
        showViewSettings(m_viewSettings[std::size_t(std::max(slot, 1) - 1)]);
    });
    connect(m_display, &DisplayPanel::windowChanged, this, &MainWindow::applyWindowFromPanel);
    connect(m_display, &DisplayPanel::presetRequested, this, &MainWindow::applyPreset);
    connectGeometry();
    connectSettings();
    if (isTransmission(m_model->xray().output) || isPolychromatic(m_model->xray().output))
        applyOutput(true);
}

void MainWindow::connectSettings() {
    connect(m_model, &SettingsModel::viewSettingsChanged, this, &MainWindow::applyRenderSettings);
    connect(m_model, &SettingsModel::voxelModelChanged, this, &MainWindow::applyVoxelModel);
    connect(m_model, &SettingsModel::spectrumSettingsChanged, this,
            &MainWindow::applySpectrumSettings);
    connect(m_model, &SettingsModel::valueMappingChanged, this, &MainWindow::applyValueMapping);
    connect(m_model, &SettingsModel::targetFpsChanged, this, [this](int fps) {
        for (auto* v : m_views) {
            v->setTargetFps(m_difference ? 0 : fps);
            v->setProgressiveOffReason(m_difference && fps > 0 ? differenceProgressiveNote()
                                                               : QString());
        }
        saveRenderingSettings();
    });
    connect(m_model, &SettingsModel::frameOptionsChanged, this, &MainWindow::applyEffects);
    connect(m_model, &SettingsModel::rendererChoiceChanged, this, [this] {
        for (auto* v : m_views) v->setAllowSoftwareGpu(m_model->rendering().softwareGpu);
        saveRenderingSettings();
    });
    connect(m_model, &SettingsModel::outputChanged, this, [this] { applyOutput(true); });
    connect(m_model, &SettingsModel::beamChanged, this, [this] { applyOutput(false); });
    connect(m_model, &SettingsModel::effectsChanged, this, &MainWindow::applyEffects);
    connect(m_model, &SettingsModel::polychromaticChanged, this, [this] {
        QSettings st;
        XrayPanel::save(st, m_model->xray());
        pushPolychromatic();
    });
}

void MainWindow::applyVoxelModel() {
    // Only the voxel model of the views "Applies to" names: their kernels and sizes stay (in
    // compare mode each view keeps its own). Same spectrum: nothing is preprocessed again.
    const core::VoxelModel model = m_model->rendering().voxelModel;
    const int slot = m_rendering->appliesTo();
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        ViewSettings s = m_views[i]->settings();
        s.voxelModel = model;
        m_viewSettings[i].voxelModel = model;
        m_views[i]->setSettings(s);
    }
    saveRenderingSettings();
}

void MainWindow::saveRenderingSettings() {
    RenderingPanel::Values v = m_model->rendering();
    // The startup kernel, size and voxel model are view 1's (in compare mode the panel may be
    // showing another view's).
    v.kernel = m_viewSettings[0].kernel;
    v.size = m_viewSettings[0].size;
    if (!m_views.empty()) v.voxelModel = m_views[0]->settings().voxelModel;
    QSettings st;
    RenderingPanel::save(st, v);
}

void MainWindow::applyRenderSettings() {
    const ViewSettings s = m_model->viewSettings();
    const int slot = m_rendering->appliesTo();
    // Only what changed against the view the panel showed (All views: view 1): a new slice
    // resolution leaves each view's own kernel, and a new kernel each view's own size.
    const ViewSettings shown = m_viewSettings[std::size_t(std::max(slot, 1) - 1)];
    for (int i = 0; i < int(m_views.size()); ++i) {
        if (m_compareCount > 1 && slot > 0 && slot - 1 != i) continue;
        // The kernel and size; the view keeps its projection (Geometry panel) and voxel model.
        ViewSettings vs = m_viewSettings[i];
        if (s.kernel != shown.kernel || i == std::max(slot, 1) - 1) vs.kernel = s.kernel;
        if (s.size != shown.size || i == std::max(slot, 1) - 1) vs.size = s.size;
        m_viewSettings[i] = vs;
        if (m_compareCount > 1) m_views[i]->setTitle(viewTitle(i, vs));
    }
    saveRenderingSettings();
    // A spectrum deapodized for another kernel cannot render this one: view 1's kernel is the
    // main spectrum's, the others get their own (assignSpectra switches each view when its
    // spectrum is ready).
    if (m_model->rendering().deapodize)
        applySpectrumSettings(); // also updateCompareKernels()
    else
        updateCompareKernels();
}

SpectrumSettings MainWindow::spectrumSettingsFromPanel() const {
    return RenderingPanel::spectrumSettings(m_model->rendering(), m_viewSettings[0].kernel);
}

void MainWindow::applySpectrumSettings() {
    const SpectrumSettings s = spectrumSettingsFromPanel();
    saveRenderingSettings();
    if (m_study->volume() && !(s == m_study->spectrumSettings()))
        message(tr("Preprocessing again (%1, oversampling %2, %3)…")
                    .arg(QString::fromUtf8(core::transformName(s.transform)))
                    .arg(s.oversampling)
                    .arg(QString::fromUtf8(core::valueMappingName(s.mapping))) +
                (s.deapodizeFor ? tr(", deapodized for %1")
                                      .arg(QString::fromUtf8(core::kernelName(*s.deapodizeFor)))
                                : QString()));
    m_study->setSpectrumSettings(s);
    if (m_prior) m_prior->setSpectrumSettings(s); // like with like
    updateCompareKernels(); // the gridding correction may have changed
    if (m_study->volume() && m_study->targetSettings().mapping != s.mapping) {
        // The study cannot have these values (attenuation of data that are not HU): the panel
        // shows what is in effect; the request stays for the next study.
        RenderingPanel::Values r = m_model->rendering();
        r.mapping = m_study->targetSettings().mapping;
        m_model->setRendering(r, SettingsModel::Notify::No);
        message(tr("This study's values are not Hounsfield units: they stay %1; studies in HU "
                   "open with %2.")
                    .arg(QString::fromUtf8(core::valueMappingName(r.mapping)),
                         QString::fromUtf8(core::valueMappingName(s.mapping))),
                true);
    }
}

void MainWindow::applyValueMapping() {
    if (isTransmission(m_model->xray().output) &&
        m_model->rendering().mapping == core::ValueMapping::Raw) {
        message(tr("Raw values have no transmission: the output is line integrals again."));
        showOutput(XrayOutput::LineIntegrals);
        applyOutput(true);
    }
    m_rewindow = true; // new values, new range: window again when the spectrum is ready
    applySpectrumSettings();
}

void MainWindow::showViewSettings(const ViewSettings& s) {
    RenderingPanel::Values r = m_model->rendering();
    r.kernel = s.kernel;
    r.size = s.size;
    r.voxelModel = s.voxelModel;
    m_model->setRendering(r, SettingsModel::Notify::No);
}

void MainWindow::showOutput(XrayOutput o) {
    XrayPanel::Values x = m_model->xray();
    x.output = o;
    m_model->setXray(x, SettingsModel::Notify::No); // the caller applies it
}

core::Transmission MainWindow::currentTransmission() const { return m_model->transmission(); }

FrameEffects MainWindow::currentEffects() const {
    FrameEffects e;
    const RenderingPanel::Values& r = m_model->rendering();
    e.depthCue = m_model->depthCue();
    e.filter = m_model->sliceFilter();
    e.clip = r.clip;
    e.nonNegative = r.nonNegative;
    e.pixelAperture = r.pixelAperture;
    return e;
}

void MainWindow::applyEffects() {
    const FrameEffects e = currentEffects();
    for (auto* v : m_views) v->setEffects(e);
    {
        QSettings st;
        XrayPanel::save(st, m_model->xray());
    }
    saveRenderingSettings();
    if (e.depthCue > 0 && std::any_of(m_views.begin(), m_views.end(), [](ProjectionView* v) {
            return v->settings().kernel == core::Kernel::Nearest;
        }))
        message(tr("Depth cueing needs the derivative of the interpolation kernel: views with "
                   "nearest neighbour "
                   "are not rendered until you choose linear or better."),
                true);
}

void MainWindow::applyOutput(bool resetWindow) {
    const bool transmission = isTransmission(m_model->xray().output);
    {
        QSettings st;
        XrayPanel::save(st, m_model->xray());
    }
    if (transmission && m_model->rendering().mapping == core::ValueMapping::Raw) {
        // Beer-Lambert needs attenuation: switch the values to mu (preprocesses again).
        const auto vol = m_study->volume();
        if (vol && vol->units != core::ValueUnits::HounsfieldUnits) {
            message(tr("Transmitted intensity needs attenuation values; this study's values are "
                       "not Hounsfield "
                       "units (%1), so the output stays line integrals.")
                        .arg(QString::fromUtf8(core::unitsName(vol->units))),
                    true);
            showOutput(XrayOutput::LineIntegrals);
            return applyOutput(true);
        }
        message(tr("Transmitted intensity needs attenuation values: switching the values to μ."));
        RenderingPanel::Values r = m_model->rendering();
        r.mapping = core::ValueMapping::Mu;
        m_model->setRendering(r, SettingsModel::Notify::No);
        applyValueMapping();
        m_rewindow = true; // the window follows the new spectrum's image (onSpectrumReady)
    }
    // The views get their output first: the window below is taken from what they show now (it
    // was taken from the previous output's image: polychromatic bone in g/cm^2 windowed line
    // integrals up to 243 as a white rectangle).
    applyPolychromatic();
    if (resetWindow) {
        // Film look (bone white) for transmission. The window from the image (log exposure for
        // transmission); before any image, the first three decades of exposure.
        syncWindowToPanel({-3.0, 0.0, transmission, currentTransmission()}, WindowPreset::Custom);
        applyWindowFromPanel();
        applyPreset(WindowPreset::Auto);
    } else {
        applyWindowFromPanel();
    }
}

} // namespace fvr::ui
