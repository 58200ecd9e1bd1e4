#pragma once
/** The Display panel: window presets, window width and level, invert, auto window, and the
 *  mouse and key hints. */
#include <QWidget>

#include <vector>

#include <fvr/core/io/image_io.h>

class QCheckBox;
class QComboBox;
class QDoubleSpinBox;
class QPushButton;
class QSettings;

namespace fvr::ui {

/** The window presets, stored as the preset combo's item data (never chosen by their label). */
/** Where the window came from: a preset, or Custom (set by hand: the spin boxes or a drag). */
enum class WindowPreset { Auto, FullRange, Bone, SoftTissue, Custom };

class DisplayPanel : public QWidget {
    Q_OBJECT
public:
    struct Values {
        double width = 1.0;
        double level = 0.5;
        bool invert = false;
        bool operator==(const Values&) const = default;
    };

    explicit DisplayPanel(QWidget* parent = nullptr);

    Values values() const;
    /** Shows `v`; emits nothing. */
    void setValues(const Values& v);
    /** The saved values (settings_keys.h); `v`'s where none is saved. Only invert is saved (the
     *  window follows each image). */
    static Values load(const QSettings& s, Values v);
    static Values load(const QSettings& s); ///< over the defaults
    static void save(QSettings& s, const Values& v);

    /** The window the controls describe, with the transmission it applies to. */
    core::DisplayWindow window(const core::Transmission& transmission) const;
    /** Shows a view's window (width, level, invert) and where it came from; emits nothing. */
    void showWindow(const core::DisplayWindow& w, WindowPreset from);
    /** The user's own presets, listed after the built-in ones (labels as given). */
    void setUserPresets(const QStringList& labels);
    /** Shows user preset `index` as the window's origin; emits nothing. */
    void showUserPreset(int index);

    /** The controls (tests drive them like a user). */
    QComboBox* presetCombo() const { return m_preset; }
    QDoubleSpinBox* windowWidthSpin() const { return m_width; }
    QDoubleSpinBox* windowLevelSpin() const { return m_level; }
    QCheckBox* invertCheck() const { return m_invert; }
    QPushButton* savePresetButton() const { return m_savePreset; }
    QPushButton* deletePresetButton() const { return m_deletePreset; }
    /** The combo's item data of user preset 0 (user preset i: this + i). */
    static constexpr int kUserPresetData = 100;

signals:
    /** Any control changed by the user. */
    void changed();
    /** Width, level or invert changed by the user. */
    void windowChanged();
    /** A preset was chosen (the Auto window button asks for WindowPreset::Auto). */
    void presetRequested(fvr::ui::WindowPreset preset);
    /** User preset `index` was chosen. */
    void userPresetRequested(int index);
    /** "Save preset…": the window on screen as a preset of the user's. */
    void savePresetRequested();
    /** "Delete preset": user preset `index`. */
    void deletePresetRequested(int index);

private:
    void showPreset(WindowPreset preset);

    QComboBox* m_preset = nullptr;
    QDoubleSpinBox* m_width = nullptr;
    QDoubleSpinBox* m_level = nullptr;
    QCheckBox* m_invert = nullptr;
    QPushButton* m_savePreset = nullptr;
    QPushButton* m_deletePreset = nullptr;
};

/** The window a preset gives for an image (`pixels`: what the window applies to); keeps `invert`.
 */
core::DisplayWindow presetWindow(WindowPreset preset, const std::vector<float>& pixels,
                                 bool invert);

} // namespace fvr::ui
