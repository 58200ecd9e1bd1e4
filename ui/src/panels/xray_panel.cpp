#include <fvr/ui/panels/xray_panel.h>

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QLabel>
#include <QSettings>
#include <QSpinBox>

#include <algorithm>
#include <initializer_list>

#include <fvr/core/errors.h>
#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

XrayPanel::XrayPanel(QWidget* parent) : QWidget(parent) {
    auto* form = new QFormLayout(this);
    m_form = form;
    addOutputRows(form);
    addPolychromaticRows(form);
    addEffectRows(form);
    updateBeam();
    connectControls();
}

void XrayPanel::addOutputRows(QFormLayout* xf) {
    m_output = new QComboBox(this);
    m_output->addItem(tr("Line integrals"), int(XrayOutput::LineIntegrals));
    m_output->addItem(tr("Transmitted intensity (Beer-Lambert)"), int(XrayOutput::Transmission));
    m_output->addItem(tr("Polychromatic (tube spectrum, materials)"),
                      int(XrayOutput::Polychromatic));
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

namespace {

QDoubleSpinBox* numberSpin(QWidget* parent, double lo, double hi, int decimals, double step,
                           const QString& suffix) {
    auto* sb = new QDoubleSpinBox(parent);
    sb->setRange(lo, hi);
    sb->setDecimals(decimals);
    sb->setSingleStep(step);
    sb->setSuffix(suffix);
    sb->setKeyboardTracking(false);
    return sb;
}

} // namespace

void XrayPanel::addPolychromaticRows(QFormLayout* xf) {
    m_kvp = numberSpin(this, 30.0, 140.0, 0, 5.0, tr(" kV"));
    m_kvp->setToolTip(tr("Tube voltage: TASMIP tungsten spectrum (Boone & Seibert 1997)"));
    xf->addRow(tr("Tube voltage"), m_kvp);
    m_filtrationAl = numberSpin(this, 0.0, 20.0, 1, 0.5, tr(" mm Al"));
    m_filtrationAl->setToolTip(tr("Added aluminium filtration (the TASMIP tube has about 1 mm)"));
    xf->addRow(tr("Filtration"), m_filtrationAl);
    m_filtrationCu = numberSpin(this, 0.0, 2.0, 2, 0.05, tr(" mm Cu"));
    xf->addRow(tr("Copper filter"), m_filtrationCu);
    m_detector = new QComboBox(this);
    m_detector->addItem(tr("Energy-integrating"), 0);
    m_detector->addItem(tr("Photon-counting"), 1);
    xf->addRow(tr("Detector"), m_detector);
    m_csi = numberSpin(this, 0.0, 2000.0, 0, 50.0, tr(" µm CsI"));
    m_csi->setSpecialValueText(tr("ideal"));
    xf->addRow(tr("Absorber"), m_csi);
    m_noise = numberSpin(this, 0.0, 1000.0, 2, 0.5, tr(" mAs"));
    m_noise->setSpecialValueText(tr("off"));
    m_noise->setToolTip(tr("Quantum noise for this exposure at 1 m (Poisson, seeded)"));
    xf->addRow(tr("Noise (dose)"), m_noise);
    m_show = new QComboBox(this);
    m_show->addItem(tr("−ln(I/I0)"), -1);
    m_show->addItem(tr("Air (g/cm²)"), 0);
    m_show->addItem(tr("Soft tissue (g/cm²)"), 1);
    m_show->addItem(tr("Bone (g/cm²)"), 2);
    xf->addRow(tr("Show"), m_show);
    m_materialMemory = new QLabel(this);
    xf->addRow(tr("Materials"), m_materialMemory);
}

void XrayPanel::setMaterialMemory(const QString& text) { m_materialMemory->setText(text); }

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
    for (auto* sb : {m_energy, m_exposure, m_sharpen, m_sharpenRadius, m_bandLimit, m_kvp,
                     m_filtrationAl, m_filtrationCu, m_csi, m_noise})
        connect(sb, &QDoubleSpinBox::valueChanged, this, edited);
    for (auto* cb : {m_detector, m_show})
        connect(cb, &QComboBox::currentIndexChanged, this, edited);
    connect(m_depthCue, &QSpinBox::valueChanged, this, edited);
}

void XrayPanel::updateBeam() {
    const bool transmission = isTransmission(output());
    m_muWater->setText(tr("%1 /mm").arg(core::waterAttenuationPerMm(m_energy->value()), 0, 'f', 4));
    m_energy->setEnabled(transmission);
    m_exposure->setEnabled(transmission);
    // The polychromatic rows show with that output only (the panel keeps its height otherwise);
    // the single energy's rows (energy, μ water, exposure) do not apply there: the tube's
    // spectrum replaces them.
    const bool poly = isPolychromatic(output());
    for (QWidget* w :
         std::initializer_list<QWidget*>{m_kvp, m_filtrationAl, m_filtrationCu, m_detector, m_csi,
                                         m_noise, m_show, m_materialMemory})
        m_form->setRowVisible(w, poly);
    for (QWidget* w : std::initializer_list<QWidget*>{m_energy, m_muWater, m_exposure})
        m_form->setRowVisible(w, !poly);
    // Quantum noise is drawn on the detected intensity (-ln(I/I0)); a material's mass thickness
    // is the decomposition's truth, no measurement: noise does not apply to it.
    const bool material = m_show->currentData().toInt() >= 0;
    m_noise->setEnabled(!material);
    m_noise->setToolTip(
        material ? tr("Quantum noise is on the detected intensity, −ln(I/I0): a material's mass "
                      "thickness is no measurement and has none. Show −ln(I/I0) to add noise.")
                 : tr("Quantum noise for this exposure at 1 m (Poisson, seeded)"));
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
    v.kvp = m_kvp->value();
    v.filtrationAlMm = m_filtrationAl->value();
    v.filtrationCuMm = m_filtrationCu->value();
    v.detector = m_detector->currentData().toInt();
    v.csiUm = m_csi->value();
    v.noiseMas = m_noise->value();
    v.show = m_show->currentData().toInt();
    return v;
}

void XrayPanel::setValues(const Values& v) {
    const QSignalBlocker b1(m_output), b2(m_energy), b3(m_exposure), b4(m_depthCue), b5(m_sharpen),
        b6(m_sharpenRadius), b7(m_bandLimit), b8(m_kvp), b9(m_filtrationAl), b10(m_filtrationCu),
        b11(m_detector), b12(m_csi), b13(m_noise), b14(m_show);
    m_output->setCurrentIndex(m_output->findData(int(v.output)));
    m_energy->setValue(v.energyKeV);
    m_exposure->setValue(v.exposure);
    m_depthCue->setValue(v.depthCuePercent);
    m_sharpen->setValue(v.sharpen);
    m_sharpenRadius->setValue(v.sharpenRadius);
    m_bandLimit->setValue(v.bandLimit);
    m_kvp->setValue(v.kvp);
    m_filtrationAl->setValue(v.filtrationAlMm);
    m_filtrationCu->setValue(v.filtrationCuMm);
    m_detector->setCurrentIndex(m_detector->findData(v.detector));
    m_csi->setValue(v.csiUm);
    m_noise->setValue(v.noiseMas);
    m_show->setCurrentIndex(std::max(0, m_show->findData(v.show)));
    updateBeam();
}

XrayPanel::Values XrayPanel::load(const QSettings& s) { return load(s, Values()); }

XrayPanel::Values XrayPanel::load(const QSettings& s, Values v) {
    // A name; earlier versions saved 0, 1 or 2.
    const QString output = s.value(keys::kXrayOutput).toString();
    if (output == QLatin1String("1"))
        v.output = XrayOutput::Transmission;
    else if (output == QLatin1String("2"))
        v.output = XrayOutput::Polychromatic;
    else if (output == QLatin1String("0"))
        v.output = XrayOutput::LineIntegrals;
    else if (!output.isEmpty()) {
        try {
            v.output = core::parseXrayOutput(output.toStdString());
        } catch (const core::SettingsError&) {
            // a name this version does not know: `v`'s
        }
    }
    v.energyKeV = s.value(keys::kXrayEnergyKeV, v.energyKeV).toDouble();
    v.exposure = s.value(keys::kXrayExposure, v.exposure).toDouble();
    v.depthCuePercent = s.value(keys::kXrayDepthCue, v.depthCuePercent).toInt();
    v.sharpen = s.value(keys::kXraySharpen, v.sharpen).toDouble();
    v.sharpenRadius = s.value(keys::kXraySharpenRadius, v.sharpenRadius).toDouble();
    v.bandLimit = s.value(keys::kXrayBandLimit, v.bandLimit).toDouble();
    v.kvp = s.value(keys::kXrayKvp, v.kvp).toDouble();
    v.filtrationAlMm = s.value(keys::kXrayFiltrationAl, v.filtrationAlMm).toDouble();
    v.filtrationCuMm = s.value(keys::kXrayFiltrationCu, v.filtrationCuMm).toDouble();
    v.detector = s.value(keys::kXrayDetector, v.detector).toInt() == 1 ? 1 : 0;
    v.csiUm = s.value(keys::kXrayCsiUm, v.csiUm).toDouble();
    v.noiseMas = s.value(keys::kXrayNoiseMas, v.noiseMas).toDouble();
    return v;
}

void XrayPanel::save(QSettings& s, const Values& v) {
    s.setValue(keys::kXrayOutput, QString::fromUtf8(core::xrayOutputName(v.output)));
    s.setValue(keys::kXrayEnergyKeV, v.energyKeV);
    s.setValue(keys::kXrayExposure, v.exposure);
    s.setValue(keys::kXrayDepthCue, v.depthCuePercent);
    s.setValue(keys::kXraySharpen, v.sharpen);
    s.setValue(keys::kXraySharpenRadius, v.sharpenRadius);
    s.setValue(keys::kXrayBandLimit, v.bandLimit);
    s.setValue(keys::kXrayKvp, v.kvp);
    s.setValue(keys::kXrayFiltrationAl, v.filtrationAlMm);
    s.setValue(keys::kXrayFiltrationCu, v.filtrationCuMm);
    s.setValue(keys::kXrayDetector, v.detector);
    s.setValue(keys::kXrayCsiUm, v.csiUm);
    s.setValue(keys::kXrayNoiseMas, v.noiseMas);
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
