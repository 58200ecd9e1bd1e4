#pragma once
/** The workstation's render settings in one place: the Rendering and X-ray values. The panels
 *  show what the model holds (they observe it) and write the user's edits into it; the main
 *  window reads the model and acts on its change signals, never on widget values. Per-view
 *  settings in compare mode are the main window's (MainWindow::m_viewSettings); the display
 *  window follows each image (the views hold it). */
#include <QObject>

#include <fvr/core/xray/xray.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/xray_panel.h>

namespace fvr::ui {

class SettingsModel : public QObject {
    Q_OBJECT
public:
    explicit SettingsModel(QObject* parent = nullptr) : QObject(parent) {}

    const RenderingPanel::Values& rendering() const { return m_rendering; }
    const XrayPanel::Values& xray() const { return m_xray; }
    /** The kernel, size and voxel model of the Rendering values (the view "Applies to"
     *  names). */
    ViewSettings viewSettings() const;
    /** Every rendering choice the panels hold (view 1's kernel, size and voxel model: the
     *  Rendering values), as the CLI and the Python module take them. */
    core::RenderSettings renderSettings() const;
    /** The transmission the X-ray values ask for (inactive for line integrals). */
    core::Transmission transmission() const;
    core::SliceFilter sliceFilter() const;
    double depthCue() const { return m_xray.depthCuePercent / 100.0; }

    enum class Notify { Yes, No };
    /** New values: the panels show them. With Notify::Yes the change signals below say what
     *  changed (a user's edit: the main window applies it); Notify::No only shows a state
     *  already in effect (the values a study could not have, a cancelled change). */
    void setRendering(const RenderingPanel::Values& v, Notify notify = Notify::Yes);
    void setXray(const XrayPanel::Values& v, Notify notify = Notify::Yes);

signals:
    /** For the observers (the panels): always, with the new values. */
    void renderingShown(const fvr::ui::RenderingPanel::Values& v);
    void xrayShown(const fvr::ui::XrayPanel::Values& v);
    // What changed (Notify::Yes), in the order they are emitted.
    void viewSettingsChanged(); ///< kernel or slice resolution
    void voxelModelChanged();
    void spectrumSettingsChanged(); ///< transform, oversampling or gridding correction
    void valueMappingChanged();
    void targetFpsChanged(int fps);
    void frameOptionsChanged(); ///< pixel aperture, clip or non-negative
    void rendererChoiceChanged(); ///< a software GPU used or not
    void outputChanged(); ///< line integrals or transmission
    void beamChanged(); ///< energy or exposure
    void effectsChanged(); ///< depth cueing or a slice filter
    /** kVp, filtration, detector, noise or what the polychromatic output shows: a new spectral
     *  response, no preprocessing. */
    void polychromaticChanged();

private:
    RenderingPanel::Values m_rendering;
    XrayPanel::Values m_xray;
};

} // namespace fvr::ui
