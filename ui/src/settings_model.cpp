#include <fvr/ui/settings_model.h>

namespace fvr::ui {

ViewSettings SettingsModel::viewSettings() const {
    return {m_rendering.kernel, m_rendering.size, m_rendering.voxelModel};
}

core::RenderSettings SettingsModel::renderSettings() const {
    core::RenderSettings s = m_rendering.toRenderSettings();
    s.depthCue = depthCue();
    s.filter = sliceFilter();
    s.output = m_xray.output;
    s.energyKeV = m_xray.energyKeV;
    s.exposure = m_xray.exposure;
    return s;
}

core::Transmission SettingsModel::transmission() const {
    if (!isTransmission(m_xray.output)) return {};
    return renderSettings().beam();
}

core::SliceFilter SettingsModel::sliceFilter() const {
    return {m_xray.sharpen, m_xray.sharpenRadius, m_xray.bandLimit};
}

void SettingsModel::setRendering(const RenderingPanel::Values& v, Notify notify) {
    const RenderingPanel::Values old = m_rendering;
    m_rendering = v;
    emit renderingShown(v);
    if (notify == Notify::No || v == old) return;
    if (v.kernel != old.kernel || v.size != old.size) emit viewSettingsChanged();
    if (v.voxelModel != old.voxelModel) emit voxelModelChanged();
    if (v.transform != old.transform || v.oversampling != old.oversampling ||
        v.deapodize != old.deapodize)
        emit spectrumSettingsChanged();
    if (v.mapping != old.mapping) emit valueMappingChanged();
    if (v.targetFps != old.targetFps) emit targetFpsChanged(v.targetFps);
    if (v.pixelAperture != old.pixelAperture || v.clip != old.clip ||
        v.nonNegative != old.nonNegative)
        emit frameOptionsChanged();
    if (v.softwareGpu != old.softwareGpu) emit rendererChoiceChanged();
}

void SettingsModel::setXray(const XrayPanel::Values& v, Notify notify) {
    const XrayPanel::Values old = m_xray;
    m_xray = v;
    emit xrayShown(v);
    if (notify == Notify::No || v == old) return;
    if (v.output != old.output) emit outputChanged();
    if (v.energyKeV != old.energyKeV || v.exposure != old.exposure) emit beamChanged();
    if (v.depthCuePercent != old.depthCuePercent || v.sharpen != old.sharpen ||
        v.sharpenRadius != old.sharpenRadius || v.bandLimit != old.bandLimit)
        emit effectsChanged();
    if (v.kvp != old.kvp || v.filtrationAlMm != old.filtrationAlMm ||
        v.filtrationCuMm != old.filtrationCuMm || v.detector != old.detector ||
        v.csiUm != old.csiUm || v.noiseMas != old.noiseMas || v.show != old.show)
        emit polychromaticChanged();
}

} // namespace fvr::ui
