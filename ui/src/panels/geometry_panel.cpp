#include <fvr/ui/panels/geometry_panel.h>

#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QLabel>
#include <QSettings>
#include <QSignalBlocker>

#include <fvr/core/errors.h>
#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

const std::vector<GeometryPanel::Preset>& GeometryPanel::presets() {
    static const std::vector<Preset> p = {
        {"Cardiac C-arm (SID 1020, SOD 750 mm)", 1020.0, 750.0},
        {"Chest radiograph (SID 1800, SOD 1650 mm)", 1800.0, 1650.0},
        {"Radiotherapy kV imager (SID 1500, SAD 1000 mm)", 1500.0, 1000.0},
    };
    return p;
}

namespace {
QDoubleSpinBox* spin(QWidget* parent, double lo, double hi, int decimals, const QString& suffix) {
    auto* s = new QDoubleSpinBox(parent);
    s->setRange(lo, hi);
    s->setDecimals(decimals);
    s->setSuffix(suffix);
    s->setKeyboardTracking(false);
    return s;
}
} // namespace

GeometryPanel::GeometryPanel(QWidget* parent) : QWidget(parent) {
    auto* form = new QFormLayout(this);
    m_projection = new QComboBox(this);
    m_projection->addItem(tr("Parallel (Fourier)"), int(ProjectionKind::Parallel));
    m_projection->addItem(tr("Cone beam (ray cast)"), int(ProjectionKind::Cone));
    m_projection->setToolTip(
        tr("Parallel: the Fourier renderer's parallel projection (fast at any volume size). Cone "
           "beam: the point source of a real X-ray machine, ray cast on the CPU: what a C-arm or "
           "a radiograph shows, magnified by SID / distance from the source."));
    form->addRow(tr("Projection"), m_projection);
    m_preset = new QComboBox(this);
    m_preset->addItem(tr("Custom"));
    for (const Preset& p : presets()) m_preset->addItem(tr(p.name));
    form->addRow(tr("Machine"), m_preset);
    m_primary = spin(this, -180.0, 180.0, 1, QStringLiteral("°"));
    m_primary->setWrapping(true);
    m_primary->setToolTip(tr("Primary angle: LAO positive, RAO negative (DICOM's positioner "
                             "primary angle). Drag a view left or right to move it."));
    form->addRow(tr("LAO / RAO"), m_primary);
    m_secondary = spin(this, -89.0, 89.0, 1, QStringLiteral("°"));
    m_secondary->setToolTip(tr("Secondary angle: cranial positive, caudal negative. Drag a view "
                               "up or down to move it."));
    form->addRow(tr("CRAN / CAUD"), m_secondary);
    m_label = new QLabel(this);
    form->addRow(QString(), m_label);
    m_sid = spin(this, 100.0, 5000.0, 0, tr(" mm"));
    m_sid->setToolTip(tr("Source to detector (SID)"));
    form->addRow(tr("Source–detector"), m_sid);
    m_sod = spin(this, 50.0, 4990.0, 0, tr(" mm"));
    m_sod->setToolTip(tr("Source to isocentre (the volume's centre): less than the SID"));
    form->addRow(tr("Source–isocentre"), m_sod);
    m_rayModel = new QComboBox(this);
    m_rayModel->addItem(tr("Trilinear (exact integral)"), int(core::RayModel::Trilinear));
    m_rayModel->addItem(tr("Box voxels (Siddon, as plastimatch)"), int(core::RayModel::Box));
    m_rayModel->addItem(tr("Cubic B-spline"), int(core::RayModel::BSpline));
    form->addRow(tr("Voxel model"), m_rayModel);
    setValues(Values{});
    showAngles(0.0, 0.0);

    connect(m_projection, &QComboBox::currentIndexChanged, this, &GeometryPanel::changed);
    connect(m_rayModel, &QComboBox::currentIndexChanged, this, &GeometryPanel::changed);
    auto distances = [this] {
        // The isocentre lies between the source and the detector.
        if (m_sod->value() >= m_sid->value()) {
            const QSignalBlocker b(m_sod);
            m_sod->setValue(m_sid->value() - 10.0);
        }
        showPresetOf(m_sid->value(), m_sod->value());
        emit changed();
    };
    connect(m_sid, &QDoubleSpinBox::valueChanged, this, distances);
    connect(m_sod, &QDoubleSpinBox::valueChanged, this, distances);
    connect(m_preset, &QComboBox::activated, this, [this](int i) {
        if (i <= 0) return;
        const Preset& p = presets()[std::size_t(i - 1)];
        const QSignalBlocker b1(m_sid), b2(m_sod);
        m_sid->setValue(p.sid);
        m_sod->setValue(p.sod);
        emit changed();
    });
    auto angles = [this] {
        updateLabel();
        emit anglesChanged(m_primary->value(), m_secondary->value());
    };
    connect(m_primary, &QDoubleSpinBox::valueChanged, this, angles);
    connect(m_secondary, &QDoubleSpinBox::valueChanged, this, angles);
}

GeometryPanel::Values GeometryPanel::values() const {
    Values v;
    v.projection = ProjectionKind(m_projection->currentData().toInt());
    v.cone.sid = m_sid->value();
    v.cone.sod = m_sod->value();
    v.cone.model = core::RayModel(m_rayModel->currentData().toInt());
    return v;
}

void GeometryPanel::setValues(const Values& v) {
    const QSignalBlocker b1(m_projection), b2(m_sid), b3(m_sod), b4(m_rayModel);
    m_projection->setCurrentIndex(m_projection->findData(int(v.projection)));
    m_sid->setValue(v.cone.sid);
    m_sod->setValue(v.cone.sod);
    m_rayModel->setCurrentIndex(m_rayModel->findData(int(v.cone.model)));
    showPresetOf(v.cone.sid, v.cone.sod);
}

void GeometryPanel::showPresetOf(double sid, double sod) {
    const QSignalBlocker b(m_preset);
    int index = 0;
    for (std::size_t i = 0; i < presets().size(); ++i)
        if (presets()[i].sid == sid && presets()[i].sod == sod) index = int(i) + 1;
    m_preset->setCurrentIndex(index);
}

void GeometryPanel::showAngles(double primaryDeg, double secondaryDeg) {
    const QSignalBlocker b1(m_primary), b2(m_secondary);
    m_primary->setValue(primaryDeg);
    m_secondary->setValue(secondaryDeg);
    updateLabel();
}

double GeometryPanel::primaryAngle() const { return m_primary->value(); }
double GeometryPanel::secondaryAngle() const { return m_secondary->value(); }

void GeometryPanel::updateLabel() {
    m_label->setText(
        QString::fromStdString(core::cArmLabel(m_primary->value(), m_secondary->value())));
}

GeometryPanel::Values GeometryPanel::load(const QSettings& s) {
    Values v;
    v.projection = s.value(keys::kGeometryProjection).toString() == QStringLiteral("cone")
                       ? ProjectionKind::Cone
                       : ProjectionKind::Parallel;
    const double sid = s.value(keys::kGeometrySid, v.cone.sid).toDouble();
    const double sod = s.value(keys::kGeometrySod, v.cone.sod).toDouble();
    if (sid >= 100.0 && sid <= 5000.0 && sod >= 50.0 && sod < sid) {
        v.cone.sid = sid;
        v.cone.sod = sod;
    }
    try {
        if (s.contains(keys::kGeometryRayModel))
            v.cone.model =
                core::parseRayModel(s.value(keys::kGeometryRayModel).toString().toStdString());
    } catch (const core::SettingsError&) {
        // A name this version does not know: the default.
    }
    return v;
}

void GeometryPanel::save(QSettings& s, const Values& v) {
    s.setValue(keys::kGeometryProjection, v.projection == ProjectionKind::Cone
                                              ? QStringLiteral("cone")
                                              : QStringLiteral("parallel"));
    s.setValue(keys::kGeometrySid, v.cone.sid);
    s.setValue(keys::kGeometrySod, v.cone.sod);
    s.setValue(keys::kGeometryRayModel, QString::fromUtf8(core::rayModelName(v.cone.model)));
}

} // namespace fvr::ui
