#pragma once
/** The Rendering panel: which views the controls apply to, the interpolation kernel, slice
 *  resolution and voxel model (per view), the spectrum's preprocessing (transform, oversampling,
 *  values, gridding correction), the interactive frame rate and the per-frame options. */
#include <QWidget>

#include <optional>

#include <fvr/core/render/kernels.h>
#include <fvr/core/render/preprocess.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/render/spectrum.h>
#include <fvr/ui/view_settings.h>

class QCheckBox;
class QComboBox;
class QFormLayout;
class QLabel;
class QSettings;
class QSpinBox;

namespace fvr::ui {

class RenderingPanel : public QWidget {
    Q_OBJECT
public:
    /** The panel's values; the defaults are core::RenderSettings' (the one home of them). */
    struct Values {
        core::Kernel kernel = core::RenderSettings{}.kernel;
        int size = core::RenderSettings{}.size;
        core::VoxelModel voxelModel = core::RenderSettings{}.voxelModel;
        core::TransformKind transform = core::RenderSettings{}.transform;
        double oversampling = core::RenderSettings{}.oversampling;
        core::ValueMapping mapping = core::RenderSettings{}.values;
        /** Gridding correction where it helps the kernel (RenderSettings::deapodize empty);
         *  off: never. */
        bool deapodize = core::RenderSettings{}.deapodize.value_or(true);
        int targetFps = 30;
        bool pixelAperture = core::RenderSettings{}.pixelAperture;
        bool clip = core::RenderSettings{}.clip;
        bool nonNegative = core::RenderSettings{}.nonNegative;
        /** Render on the GPU even when it is a software renderer (llvmpipe …: slower than the
         *  CPU renderer, so off by default). */
        bool softwareGpu = false;
        /** These values as render settings (the view, filters and X-ray output left at `base`'s).
         */
        core::RenderSettings toRenderSettings(core::RenderSettings base = {}) const;
        bool operator==(const Values&) const = default;
    };

    explicit RenderingPanel(QWidget* parent = nullptr);

    /** What the controls show. */
    Values values() const;
    /** Shows `v` (a value a combo does not offer leaves that combo as it is); emits nothing. */
    void setValues(const Values& v);
    /** The saved values (settings_keys.h); `v`'s where none is saved. Choices are saved by name
     *  (kernelName, ...); the enum numbers that earlier versions saved still load. */
    static Values load(const QSettings& s, Values v);
    static Values load(const QSettings& s); ///< over the defaults
    static void save(QSettings& s, const Values& v);
    /** The preprocessing `v` asks for, deapodized for `kernel` (view 1's) when gridding
     *  correction is on. With Values{}: the workstation's default spectrum. */
    static core::PreprocessOptions spectrumSettings(const Values& v, core::Kernel kernel);

    /** Kernel, size and voxel model as the controls show them. */
    ViewSettings viewSettings() const;
    /** Shows one view's kernel, size and voxel model; emits nothing. */
    void showViewSettings(const ViewSettings& s);
    /** The "Applies to" choices for n views side by side (enabled when n > 1); emits nothing. */
    void setViewCount(int n);
    /** 0: all views, i: view i. */
    int appliesTo() const;
    /** The "Spectrum memory" readout: `mib` in use, over `count` spectra (compare mode with
     *  gridding correction keeps one per kernel), and what the spectrum being prepared will
     *  take instead. */
    void setSpectrumMiB(double mib, int count = 1, std::optional<double> preparingMiB = {});

    /** The controls (tests drive them like a user). */
    QComboBox* kernelCombo() const { return m_kernel; }
    QComboBox* sizeCombo() const { return m_size; }
    QComboBox* transformCombo() const { return m_transform; }
    QComboBox* oversamplingCombo() const { return m_oversampling; }
    QComboBox* valuesCombo() const { return m_values; }
    QCheckBox* deapodizeCheck() const { return m_deapodize; }
    QSpinBox* targetFpsSpin() const { return m_targetFps; }
    QCheckBox* clipCheck() const { return m_clip; }
    QComboBox* voxelModelCombo() const { return m_voxelModel; }
    QComboBox* appliesToCombo() const { return m_appliesTo; }
    QLabel* memoryLabel() const { return m_memory; }
    QCheckBox* pixelApertureCheck() const { return m_pixelAperture; }
    QCheckBox* nonNegativeCheck() const { return m_nonNegative; }

signals:
    /** Any control changed by the user (what changed: SettingsModel's signals). */
    void changed();
    void appliesToChanged(int slot);

private:
    void addViewRows(QFormLayout* form);
    void addSpectrumRows(QFormLayout* form);
    void addFrameRows(QFormLayout* form);
    void connectControls();

    QComboBox* m_appliesTo = nullptr;
    QComboBox* m_kernel = nullptr;
    QComboBox* m_size = nullptr;
    QComboBox* m_voxelModel = nullptr;
    QComboBox* m_transform = nullptr;
    QComboBox* m_oversampling = nullptr;
    QComboBox* m_values = nullptr;
    QCheckBox* m_deapodize = nullptr;
    QLabel* m_memory = nullptr;
    bool m_softwareGpu = false; ///< not a control here: View ▸ Use a software GPU
    QSpinBox* m_targetFps = nullptr;
    QCheckBox* m_pixelAperture = nullptr;
    QCheckBox* m_clip = nullptr;
    QCheckBox* m_nonNegative = nullptr;
};

} // namespace fvr::ui
