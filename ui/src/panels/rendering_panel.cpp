#include <fvr/ui/panels/rendering_panel.h>

#include <algorithm>

#include <QCheckBox>
#include <QComboBox>
#include <QFormLayout>
#include <QLabel>
#include <QSettings>
#include <QSpinBox>

#include <fvr/core/errors.h>
#include <fvr/core/render/voxel_model.h>
#include <fvr/core/xray/xray.h>
#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

namespace {
const double kOversampling[] = {1.0, 1.25, 1.5, 2.0};

/** A choice saved by name, or by the enum number earlier versions saved (0..count-1); anything
 *  else: `fallback`. */
template <class E, class Parse>
E savedChoice(const QSettings& s, const char* key, E fallback, int count, Parse parse) {
    const QVariant saved = s.value(key);
    if (!saved.isValid()) return fallback;
    const QString text = saved.toString();
    bool isNumber = false;
    const int number = text.toInt(&isNumber);
    if (isNumber) return number >= 0 && number < count ? E(number) : fallback;
    try {
        return parse(text.toStdString());
    } catch (const core::SettingsError&) {
        return fallback; // a name this version does not know
    }
}

/** Selects the item holding `data`; a value the combo does not offer leaves it as it is. */
void selectData(QComboBox* c, const QVariant& data) {
    const int i = c->findData(data);
    if (i >= 0) c->setCurrentIndex(i);
}
} // namespace

RenderingPanel::RenderingPanel(QWidget* parent) : QWidget(parent) {
    auto* form = new QFormLayout(this);
    addViewRows(form);
    addSpectrumRows(form);
    addFrameRows(form);
    connectControls();
}

void RenderingPanel::addViewRows(QFormLayout* rf) {
    m_appliesTo = new QComboBox(this);
    m_appliesTo->addItem(tr("All views"));
    m_appliesTo->setEnabled(false);
    rf->addRow(tr("Applies to"), m_appliesTo);
    m_kernel = new QComboBox(this);
    for (core::Kernel k : core::allKernels())
        m_kernel->addItem(QString::fromUtf8(core::kernelName(k)), int(k));
    rf->addRow(tr("Interpolation"), m_kernel);
    m_size = new QComboBox(this);
    for (int s : core::settingsSizes()) m_size->addItem(QStringLiteral("%1 × %1").arg(s), s);
    rf->addRow(tr("Slice resolution"), m_size);
    m_voxelModel = new QComboBox(this);
    m_voxelModel->addItem(tr("Trilinear (as a DRR ray caster)"), int(core::VoxelModel::Trilinear));
    m_voxelModel->addItem(tr("Cubic B-spline through the voxels"), int(core::VoxelModel::BSpline));
    m_voxelModel->addItem(tr("Band-limited (sharpest, rings)"), int(core::VoxelModel::BandLimited));
    m_voxelModel->setToolTip(
        tr("What lies between the voxels. Trilinear: the projection a trilinear DRR ray caster "
           "computes, no ringing at the scan ends. Band-limited: the plain Fourier image, the "
           "sharpest, but it rings (stripes, negative values) where the scan ends inside the body "
           "and between coarse slices. Same spectrum: changing it costs no preprocessing."));
    rf->addRow(tr("Voxel model"), m_voxelModel);
}

void RenderingPanel::addSpectrumRows(QFormLayout* rf) {
    m_transform = new QComboBox(this);
    m_transform->addItem(tr("FFT (complex half spectrum)"), int(core::TransformKind::Fft));
    m_transform->addItem(tr("FHT (Hartley)"), int(core::TransformKind::Fht));
    rf->addRow(tr("Transform"), m_transform);
    m_oversampling = new QComboBox(this);
    for (double f : kOversampling) m_oversampling->addItem(QStringLiteral("%1×").arg(f), f);
    rf->addRow(tr("Oversampling"), m_oversampling);
    m_values = new QComboBox(this);
    m_values->addItem(tr("Attenuation μ (mm)"), int(core::ValueMapping::Mu));
    m_values->addItem(tr("Bone-enhanced μ (mm)"), int(core::ValueMapping::MuBone));
    m_values->addItem(tr("Raw values (value × mm)"), int(core::ValueMapping::Raw));
    m_values->setToolTip(
        tr("What the projection integrates. μ = μ_water (1 + HU/1000), clipped at 0; bone-enhanced "
           "makes the slope %1× steeper above %2 HU (bone stands out as on a low-kV film). The "
           "transform is linear only in these values: a change preprocesses again in the "
           "background.")
            .arg(core::kBoneGain)
            .arg(core::kBoneThresholdHu));
    rf->addRow(tr("Values"), m_values);
    m_deapodize = new QCheckBox(tr("Gridding correction (deapodize)"), this);
    m_deapodize->setToolTip(
        tr("Divide the volume by the kernel's Fourier transform before the 3D FFT, as "
           "gridding codes do: Kaiser-Bessel with 1.25× oversampling is then more accurate than "
           "ray casting. Every kernel but linear (which does not gain) gets it. The spectrum is "
           "made for one kernel: changing the kernel preprocesses again, and each compare view "
           "gets its kernel's own spectrum."));
    rf->addRow(QString(), m_deapodize);
    m_memory = new QLabel(this);
    rf->addRow(tr("Spectrum memory"), m_memory);
}

void RenderingPanel::addFrameRows(QFormLayout* rf) {
    m_targetFps = new QSpinBox(this);
    m_targetFps->setRange(0, 240);
    m_targetFps->setSuffix(tr(" fps"));
    m_targetFps->setSpecialValueText(tr("off (always full quality)"));
    m_targetFps->setToolTip(
        tr("Progressive refinement: while you rotate, frames render at a lower slice resolution "
           "(or with linear interpolation when the spectrum allows) to hold this frame rate; "
           "the full-quality frame follows when you let go. The overlay shows the level."));
    rf->addRow(tr("Interactive target"), m_targetFps);
    m_pixelAperture = new QCheckBox(tr("Detector pixels integrate over their area"), this);
    m_pixelAperture->setToolTip(
        tr("Off: each pixel samples the projection at its centre, as ray casters do. On: each "
           "pixel averages the projection over its area, as a detector does (less aliasing "
           "when the pixels are coarser than the voxels)."));
    rf->addRow(QString(), m_pixelAperture);
    m_clip = new QCheckBox(tr("Clip to the volume (no ghosts outside it)"), this);
    m_clip->setToolTip(tr(
        "Pixels whose ray misses the volume are exactly 0 in a projection; Fourier rendering puts "
        "the kernel's ghost copies and ringing there. On: those pixels show 0."));
    rf->addRow(QString(), m_clip);
    m_nonNegative = new QCheckBox(tr("No negative line integrals"), this);
    m_nonNegative->setToolTip(
        tr("For values that are never negative (attenuation, or raw data without negative "
           "values) no line integral is: what is left of the interpolation's ringing below 0 "
           "is shown as 0. No effect on raw Hounsfield units."));
    rf->addRow(QString(), m_nonNegative);
}

void RenderingPanel::connectControls() {
    // What changed is the settings model's to say (SettingsModel::setRendering).
    for (QComboBox* c : {m_kernel, m_size, m_voxelModel, m_transform, m_oversampling, m_values})
        connect(c, &QComboBox::currentIndexChanged, this, &RenderingPanel::changed);
    for (QCheckBox* c : {m_deapodize, m_pixelAperture, m_clip, m_nonNegative})
        connect(c, &QCheckBox::toggled, this, &RenderingPanel::changed);
    connect(m_targetFps, &QSpinBox::valueChanged, this, &RenderingPanel::changed);
    connect(m_appliesTo, &QComboBox::currentIndexChanged, this, [this](int slot) {
        emit appliesToChanged(slot);
        emit changed();
    });
}

RenderingPanel::Values RenderingPanel::values() const {
    Values v;
    v.kernel = core::Kernel(m_kernel->currentData().toInt());
    v.size = m_size->currentData().toInt();
    v.voxelModel = core::VoxelModel(m_voxelModel->currentData().toInt());
    v.transform = core::TransformKind(m_transform->currentData().toInt());
    v.oversampling = m_oversampling->currentData().toDouble();
    v.mapping = core::ValueMapping(m_values->currentData().toInt());
    v.deapodize = m_deapodize->isChecked();
    v.targetFps = m_targetFps->value();
    v.pixelAperture = m_pixelAperture->isChecked();
    v.clip = m_clip->isChecked();
    v.nonNegative = m_nonNegative->isChecked();
    v.softwareGpu = m_softwareGpu;
    return v;
}

void RenderingPanel::setValues(const Values& v) {
    const QSignalBlocker b1(m_kernel), b2(m_size), b3(m_voxelModel), b4(m_transform),
        b5(m_oversampling), b6(m_values), b7(m_deapodize), b8(m_targetFps), b9(m_pixelAperture),
        b10(m_clip), b11(m_nonNegative);
    selectData(m_kernel, int(v.kernel));
    selectData(m_size, v.size);
    selectData(m_voxelModel, int(v.voxelModel));
    selectData(m_transform, int(v.transform));
    selectData(m_oversampling, v.oversampling);
    selectData(m_values, int(v.mapping));
    m_deapodize->setChecked(v.deapodize);
    // The box asks for the correction where it helps: for a kernel it does not help (linear),
    // the view it shows renders without it, and the box says so.
    m_deapodize->setText(v.deapodize && !core::griddingCorrectionHelps(v.kernel)
                             ? tr("Gridding correction (deapodize): not applied to %1")
                                   .arg(QString::fromUtf8(core::kernelName(v.kernel)))
                             : tr("Gridding correction (deapodize)"));
    m_targetFps->setValue(v.targetFps);
    m_pixelAperture->setChecked(v.pixelAperture);
    m_clip->setChecked(v.clip);
    m_nonNegative->setChecked(v.nonNegative);
    m_softwareGpu = v.softwareGpu; // the View menu's choice, kept with the others
}

RenderingPanel::Values RenderingPanel::load(const QSettings& s) { return load(s, Values()); }

RenderingPanel::Values RenderingPanel::load(const QSettings& s, Values v) {
    v.kernel = savedChoice(s, keys::kRenderKernel, v.kernel, int(core::allKernels().size()),
                           core::parseKernel);
    const int size = s.value(keys::kRenderSize, v.size).toInt();
    const auto sizes = core::settingsSizes();
    if (std::find(sizes.begin(), sizes.end(), size) != sizes.end()) v.size = size;
    v.transform = savedChoice(s, keys::kRenderTransform, v.transform, 2, core::parseTransform);
    v.oversampling = s.value(keys::kRenderOversampling, v.oversampling).toDouble();
    v.deapodize = s.value(keys::kRenderDeapodize, v.deapodize).toBool();
    v.mapping = savedChoice(s, keys::kRenderValues, v.mapping, 3, core::parseValueMapping);
    v.targetFps = s.value(keys::kRenderTargetFps, v.targetFps).toInt();
    v.clip = s.value(keys::kRenderClip, v.clip).toBool();
    v.nonNegative = s.value(keys::kRenderNonNegative, v.nonNegative).toBool();
    v.pixelAperture = s.value(keys::kRenderPixelAperture, v.pixelAperture).toBool();
    v.softwareGpu = s.value(keys::kRenderSoftwareGpu, v.softwareGpu).toBool();
    try {
        const QString name =
            s.value(keys::kRenderVoxelModel, core::voxelModelName(v.voxelModel)).toString();
        v.voxelModel = core::parseVoxelModel(name.toStdString());
    } catch (const core::SettingsError&) {
        // an unknown saved name: the default
    }
    return v;
}

void RenderingPanel::save(QSettings& s, const Values& v) {
    s.setValue(keys::kRenderKernel, QString::fromUtf8(core::kernelName(v.kernel)));
    s.setValue(keys::kRenderSize, v.size);
    s.setValue(keys::kRenderVoxelModel, QString::fromUtf8(core::voxelModelName(v.voxelModel)));
    s.setValue(keys::kRenderTransform, QString::fromUtf8(core::transformName(v.transform)));
    s.setValue(keys::kRenderOversampling, v.oversampling);
    s.setValue(keys::kRenderValues, QString::fromUtf8(core::valueMappingName(v.mapping)));
    s.setValue(keys::kRenderDeapodize, v.deapodize);
    s.setValue(keys::kRenderTargetFps, v.targetFps);
    s.setValue(keys::kRenderPixelAperture, v.pixelAperture);
    s.setValue(keys::kRenderClip, v.clip);
    s.setValue(keys::kRenderNonNegative, v.nonNegative);
    s.setValue(keys::kRenderSoftwareGpu, v.softwareGpu);
}

ViewSettings RenderingPanel::viewSettings() const {
    const Values v = values();
    return {v.kernel, v.size, v.voxelModel};
}

void RenderingPanel::showViewSettings(const ViewSettings& s) {
    const QSignalBlocker b1(m_kernel), b2(m_size), b3(m_voxelModel);
    m_kernel->setCurrentIndex(m_kernel->findData(int(s.kernel)));
    m_size->setCurrentIndex(m_size->findData(s.size));
    m_voxelModel->setCurrentIndex(m_voxelModel->findData(int(s.voxelModel)));
}

void RenderingPanel::setViewCount(int n) {
    const QSignalBlocker b(m_appliesTo);
    m_appliesTo->clear();
    m_appliesTo->addItem(tr("All views"));
    for (int i = 0; i < n && n > 1; ++i) m_appliesTo->addItem(tr("View %1").arg(i + 1));
    m_appliesTo->setEnabled(n > 1);
}

int RenderingPanel::appliesTo() const { return m_appliesTo->currentIndex(); }

void RenderingPanel::setSpectrumMiB(double mib, int count, std::optional<double> preparingMiB) {
    QString text = count > 1 ? tr("%1 MiB in %2 spectra").arg(mib, 0, 'f', 1).arg(count)
                             : tr("%1 MiB").arg(mib, 0, 'f', 1);
    if (preparingMiB)
        text = tr("%1 in use; %2 MiB once the new spectrum is ready")
                   .arg(text)
                   .arg(*preparingMiB, 0, 'f', 1);
    m_memory->setText(text);
    m_memory->setWordWrap(true);
    m_memory->setToolTip(count > 1 ? tr("Compare mode: each view's kernel renders from its own "
                                        "spectrum (gridding-corrected for that kernel)")
                                   : QString());
}

core::PreprocessOptions RenderingPanel::spectrumSettings(const Values& v, core::Kernel kernel) {
    core::RenderSettings s = v.toRenderSettings();
    s.kernel = kernel;
    return s.toPreprocessOptions();
}

core::RenderSettings RenderingPanel::Values::toRenderSettings(core::RenderSettings s) const {
    s.kernel = kernel;
    s.size = size;
    s.voxelModel = voxelModel;
    s.transform = transform;
    s.oversampling = oversampling;
    s.values = mapping;
    s.deapodize = deapodize ? std::nullopt : std::optional<bool>(false);
    s.pixelAperture = pixelAperture;
    s.clip = clip;
    s.nonNegative = nonNegative;
    return s;
}

} // namespace fvr::ui
