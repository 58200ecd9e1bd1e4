#include <fvr/ui/panels/xray_panel.h>

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QLabel>
#include <QSettings>
#include <QSpinBox>

#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

XrayPanel::XrayPanel(QWidget* parent) : QWidget(parent) {
    auto* form = new QFormLayout(this);
    addOutputRows(form);
    addEffectRows(form);
    updateBeam();
    connectControls();
}

void XrayPanel::addOutputRows(QFormLayout* xf) {
    m_output = new QComboBox(this);
    m_output->addItem(tr("Line integrals"), int(XrayOutput::LineIntegrals));
    m_output->addItem(tr("Transmitted intensity (Beer-Lambert)"), int(XrayOutput::Transmission));
    m_output->setToolTip(
        tr("Transmitted intensity = exposure × exp(−μ_water × line integral of μ/μ_water): what a "
           "detector records. Needs attenuation values (μ or bone-enhanced μ)."));
    xf->addRow(tr("Output"), m_output);
    m_energy = new QDoubleSpinBox(this);
    m_energy->setRange(20.0, 150.0);
    m_energy->setDecimals(0);
    m_energy->setSuffix(tr(" keV"));
    m_energy->setKeyboardTracking(false);
    m_energy->setToolTip(tr("Effective photon energy: sets μ_water (NIST XCOM, water)"));
    xf->addRow(tr("Energy"), m_energy);
    m_muWater = new QLabel(this);
    xf->addRow(tr("μ water"), m_muWater);
    m_exposure = new QDoubleSpinBox(this);
    m_exposure->setRange(0.05, 50.0);
    m_exposure->setDecimals(2);
    m_exposure->setSingleStep(0.1);
    m_exposure->setKeyboardTracking(false);
    m_exposure->setToolTip(
        tr("Relative exposure (mAs): the unattenuated beam reaches this fraction of full scale"));
    xf->addRow(tr("Exposure"), m_exposure);
}

void XrayPanel::addEffectRows(QFormLayout* xf) {
    m_depthCue = new QSpinBox(this);
    m_depthCue->setRange(0, 100);
    m_depthCue->setSuffix(tr(" %"));
    m_depthCue->setSpecialValueText(tr("off"));
    m_depthCue->setToolTip(
        tr("Depth cueing in the frequency domain (Totsuka & Levoy): structures at the back of the "
           "volume weigh up to this much less than those in front. Needs linear interpolation or "
           "better."));
    xf->addRow(tr("Depth cueing"), m_depthCue);
    m_sharpen = new QDoubleSpinBox(this);
    m_sharpen->setRange(0.0, 10.0);
    m_sharpen->setSingleStep(0.25);
    m_sharpen->setSpecialValueText(tr("off"));
    m_sharpen->setKeyboardTracking(false);
    m_sharpen->setToolTip(
        tr("Edge enhancement (unsharp mask): image + amount × (image − Gaussian blur), applied to "
           "the 2D slice before the inverse transform (free per frame)"));
    xf->addRow(tr("Edge enhancement"), m_sharpen);
    m_sharpenRadius = new QDoubleSpinBox(this);
    m_sharpenRadius->setRange(0.1, 50.0);
    m_sharpenRadius->setSuffix(tr(" mm"));
    m_sharpenRadius->setSingleStep(0.5);
    m_sharpenRadius->setKeyboardTracking(false);
    xf->addRow(tr("Edge radius (σ)"), m_sharpenRadius);
    m_bandLimit = new QDoubleSpinBox(this);
    m_bandLimit->setRange(0.0, 20.0);
    m_bandLimit->setDecimals(2);
    m_bandLimit->setSingleStep(0.05);
    m_bandLimit->setSuffix(tr(" lp/mm"));
    m_bandLimit->setSpecialValueText(tr("off"));
    m_bandLimit->setKeyboardTracking(false);
    m_bandLimit->setToolTip(
        tr("Band limit: order-8 Butterworth low-pass on the slice, −3 dB at this frequency"));
    xf->addRow(tr("Band limit"), m_bandLimit);
}

void XrayPanel::connectControls() {
    // What changed is the settings model's to say (SettingsModel::setXray).
    auto edited = [this] {
        updateBeam();
        emit changed();
    };
    connect(m_output, &QComboBox::currentIndexChanged, this, edited);
    for (auto* sb : {m_energy, m_exposure, m_sharpen, m_sharpenRadius, m_bandLimit})
        connect(sb, &QDoubleSpinBox::valueChanged, this, edited);
    connect(m_depthCue, &QSpinBox::valueChanged, this, edited);
}

void XrayPanel::updateBeam() {
    const bool transmission = isTransmission(output());
    m_muWater->setText(tr("%1 /mm").arg(core::waterAttenuationPerMm(m_energy->value()), 0, 'f', 4));
    m_energy->setEnabled(transmission);
    m_exposure->setEnabled(transmission);
}

XrayPanel::Values XrayPanel::values() const {
    Values v;
    v.output = output();
    v.energyKeV = m_energy->value();
    v.exposure = m_exposure->value();
    v.depthCuePercent = m_depthCue->value();
    v.sharpen = m_sharpen->value();
    v.sharpenRadius = m_sharpenRadius->value();
    v.bandLimit = m_bandLimit->value();
    return v;
}

void XrayPanel::setValues(const Values& v) {
    const QSignalBlocker b1(m_output), b2(m_energy), b3(m_exposure), b4(m_depthCue), b5(m_sharpen),
        b6(m_sharpenRadius), b7(m_bandLimit);
    m_output->setCurrentIndex(m_output->findData(int(v.output)));
    m_energy->setValue(v.energyKeV);
    m_exposure->setValue(v.exposure);
    m_depthCue->setValue(v.depthCuePercent);
    m_sharpen->setValue(v.sharpen);
    m_sharpenRadius->setValue(v.sharpenRadius);
    m_bandLimit->setValue(v.bandLimit);
    updateBeam();
}

XrayPanel::Values XrayPanel::load(const QSettings& s) { return load(s, Values()); }

XrayPanel::Values XrayPanel::load(const QSettings& s, Values v) {
    v.output = s.value(keys::kXrayOutput, int(v.output)).toInt() == int(XrayOutput::Transmission)
                   ? XrayOutput::Transmission
                   : XrayOutput::LineIntegrals;
    v.energyKeV = s.value(keys::kXrayEnergyKeV, v.energyKeV).toDouble();
    v.exposure = s.value(keys::kXrayExposure, v.exposure).toDouble();
    v.depthCuePercent = s.value(keys::kXrayDepthCue, v.depthCuePercent).toInt();
    v.sharpen = s.value(keys::kXraySharpen, v.sharpen).toDouble();
    v.sharpenRadius = s.value(keys::kXraySharpenRadius, v.sharpenRadius).toDouble();
    v.bandLimit = s.value(keys::kXrayBandLimit, v.bandLimit).toDouble();
    return v;
}

void XrayPanel::save(QSettings& s, const Values& v) {
    s.setValue(keys::kXrayOutput, int(v.output));
    s.setValue(keys::kXrayEnergyKeV, v.energyKeV);
    s.setValue(keys::kXrayExposure, v.exposure);
    s.setValue(keys::kXrayDepthCue, v.depthCuePercent);
    s.setValue(keys::kXraySharpen, v.sharpen);
    s.setValue(keys::kXraySharpenRadius, v.sharpenRadius);
    s.setValue(keys::kXrayBandLimit, v.bandLimit);
}

XrayOutput XrayPanel::output() const { return XrayOutput(m_output->currentData().toInt()); }

void XrayPanel::setOutput(XrayOutput o) {
    const QSignalBlocker b(m_output);
    m_output->setCurrentIndex(m_output->findData(int(o)));
    updateBeam();
}

core::Transmission XrayPanel::transmission() const {
    if (!isTransmission(output())) return {};
    return {core::waterAttenuationPerMm(m_energy->value()), m_exposure->value()};
}

core::SliceFilter XrayPanel::sliceFilter() const {
    return {m_sharpen->value(), m_sharpenRadius->value(), m_bandLimit->value()};
}

double XrayPanel::depthCue() const { return m_depthCue->value() / 100.0; }

} // namespace fvr::ui
