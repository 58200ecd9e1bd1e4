#pragma once
/** The Geometry panel: how the views project (the Fourier renderers' parallel beam, or a
 *  C-arm's cone beam ray cast on the CPU), the C-arm's angles (LAO/RAO, CRAN/CAUD, as DICOM's
 *  positioner angles), its source-to-detector and source-to-isocentre distances, the ray model,
 *  and presets of real machines. The angles are the views' orientation: editing them turns the
 *  views, and a drag on a view shows here. */
#include <QWidget>

#include <fvr/core/render/cone_projector.h>
#include <fvr/ui/view_settings.h>

class QComboBox;
class QDoubleSpinBox;
class QLabel;
class QSettings;

namespace fvr::ui {

class GeometryPanel : public QWidget {
    Q_OBJECT
public:
    struct Values {
        ProjectionKind projection = ProjectionKind::Parallel;
        ConeSettings cone;
        bool operator==(const Values&) const = default;
    };

    /** A machine's distances: a cardiac C-arm (DeepDRR's Siemens Cios: SID 1020 mm), a chest
     *  radiograph (SID 1800 mm, the patient against the detector), a radiotherapy kV imager
     *  (source to isocentre 1000 mm, to the panel 1500 mm). */
    struct Preset {
        const char* name;
        double sid;
        double sod;
    };
    static const std::vector<Preset>& presets();

    explicit GeometryPanel(QWidget* parent = nullptr);

    Values values() const;
    /** Shows `v`; emits nothing. */
    void setValues(const Values& v);
    /** Shows the views' C-arm angles (degrees); emits nothing. */
    void showAngles(double primaryDeg, double secondaryDeg);
    double primaryAngle() const;
    double secondaryAngle() const;

    static Values load(const QSettings& s);
    static void save(QSettings& s, const Values& v);

    QComboBox* projectionCombo() const { return m_projection; }
    QComboBox* presetCombo() const { return m_preset; }
    QDoubleSpinBox* primarySpin() const { return m_primary; }
    QDoubleSpinBox* secondarySpin() const { return m_secondary; }
    QDoubleSpinBox* sidSpin() const { return m_sid; }
    QDoubleSpinBox* sodSpin() const { return m_sod; }
    QComboBox* rayModelCombo() const { return m_rayModel; }
    QLabel* angleLabel() const { return m_label; }

signals:
    /** The projection, distances or ray model changed by the user. */
    void changed();
    /** The angles changed by the user. */
    void anglesChanged(double primaryDeg, double secondaryDeg);

private:
    void updateLabel();
    void showPresetOf(double sid, double sod);

    QComboBox* m_projection = nullptr;
    QComboBox* m_preset = nullptr;
    QDoubleSpinBox* m_primary = nullptr;
    QDoubleSpinBox* m_secondary = nullptr;
    QLabel* m_label = nullptr;
    QDoubleSpinBox* m_sid = nullptr;
    QDoubleSpinBox* m_sod = nullptr;
    QComboBox* m_rayModel = nullptr;
};

} // namespace fvr::ui
