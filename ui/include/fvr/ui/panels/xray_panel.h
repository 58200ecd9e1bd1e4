#pragma once
/** The X-ray panel: the output (line integrals or Beer-Lambert transmitted intensity) with its
 *  beam (energy, exposure), depth cueing and the slice filters (edge enhancement, band limit). */
#include <QWidget>

#include <fvr/core/render/render_settings.h>
#include <fvr/core/xray/xray.h>

class QComboBox;
class QDoubleSpinBox;
class QFormLayout;
class QLabel;
class QSettings;
class QSpinBox;

namespace fvr::ui {

/** What the projection shows (core::RenderSettings::output): its line integrals, or the
 *  intensity a detector records. The values are the combo's item data; the setting is saved by
 *  name (xrayOutputName). */
using XrayOutput = core::XrayOutput;

/** True for the Beer-Lambert output. */
inline bool isTransmission(XrayOutput o) { return o == XrayOutput::Transmission; }
/** True for the polychromatic output (TASMIP spectrum through air, soft tissue and bone). */
inline bool isPolychromatic(XrayOutput o) { return o == XrayOutput::Polychromatic; }

class XrayPanel : public QWidget {
    Q_OBJECT
public:
    struct Values {
        // The defaults of these are core::RenderSettings' (the one home of them).
        XrayOutput output = core::RenderSettings{}.output;
        double energyKeV = core::RenderSettings{}.energyKeV;
        double exposure = core::RenderSettings{}.exposure;
        int depthCuePercent = int(100 * core::RenderSettings{}.depthCue);
        double sharpen = core::SliceFilter{}.sharpenAmount;
        double sharpenRadius = core::SliceFilter{}.sharpenSigmaMm;
        double bandLimit = core::SliceFilter{}.bandLimitLpMm;
        // Polychromatic output: the tube, the detector, the dose, what is shown.
        double kvp = 80.0;
        double filtrationAlMm = 2.5;
        double filtrationCuMm = 0.0;
        int detector = 0; ///< 0 energy-integrating, 1 photon-counting
        double csiUm = 0.0; ///< 0: ideal detector
        double noiseMas = 0.0; ///< 0: no noise
        int show = -1; ///< -1: -ln(I/I0); m: material m's mass thickness (g/cm^2)
        bool operator==(const Values&) const = default;
    };

    explicit XrayPanel(QWidget* parent = nullptr);

    Values values() const;
    /** Shows `v` (energy and exposure enabled for transmission only); emits nothing. */
    void setValues(const Values& v);
    /** The saved values (settings_keys.h); `v`'s where none is saved. */
    static Values load(const QSettings& s, Values v);
    static Values load(const QSettings& s); ///< over the defaults
    static void save(QSettings& s, const Values& v);

    XrayOutput output() const;
    /** Shows another output (enabling the beam controls to match); emits nothing. */
    void setOutput(XrayOutput o);
    /** The transmission the panel asks for (inactive for line integrals). */
    core::Transmission transmission() const;
    /** Edge enhancement and band limit. */
    core::SliceFilter sliceFilter() const;
    /** Depth cueing, 0..1. */
    double depthCue() const;

    /** The controls (tests drive them like a user). */
    QComboBox* outputCombo() const { return m_output; }
    QDoubleSpinBox* energySpin() const { return m_energy; }
    QDoubleSpinBox* exposureSpin() const { return m_exposure; }
    QSpinBox* depthCueSpin() const { return m_depthCue; }
    QDoubleSpinBox* sharpenSpin() const { return m_sharpen; }
    QDoubleSpinBox* sharpenRadiusSpin() const { return m_sharpenRadius; }
    QDoubleSpinBox* bandLimitSpin() const { return m_bandLimit; }
    QDoubleSpinBox* kvpSpin() const { return m_kvp; }
    QDoubleSpinBox* filtrationAlSpin() const { return m_filtrationAl; }
    QComboBox* detectorCombo() const { return m_detector; }
    QDoubleSpinBox* noiseSpin() const { return m_noise; }
    QComboBox* showCombo() const { return m_show; }
    /** The memory readout of the material spectra ("3 material spectra: 47 MB"). */
    void setMaterialMemory(const QString& text);

signals:
    /** Any control changed by the user (what changed: SettingsModel's signals). */
    void changed();

private:
    void addOutputRows(QFormLayout* form);
    void addEffectRows(QFormLayout* form);
    void addPolychromaticRows(QFormLayout* form);
    void connectControls();
    /** μ water readout and the beam controls' enabling. */
    void updateBeam();

    QComboBox* m_output = nullptr;
    QDoubleSpinBox* m_energy = nullptr;
    QLabel* m_muWater = nullptr;
    QDoubleSpinBox* m_exposure = nullptr;
    QSpinBox* m_depthCue = nullptr;
    QDoubleSpinBox* m_sharpen = nullptr;
    QDoubleSpinBox* m_sharpenRadius = nullptr;
    QDoubleSpinBox* m_bandLimit = nullptr;
    QDoubleSpinBox* m_kvp = nullptr;
    QDoubleSpinBox* m_filtrationAl = nullptr;
    QDoubleSpinBox* m_filtrationCu = nullptr;
    QComboBox* m_detector = nullptr;
    QDoubleSpinBox* m_csi = nullptr;
    QDoubleSpinBox* m_noise = nullptr;
    QComboBox* m_show = nullptr;
    QLabel* m_materialMemory = nullptr;
    QFormLayout* m_form = nullptr;
};

} // namespace fvr::ui
