#include <fvr/ui/panels/display_panel.h>

#include <QCheckBox>
#include <QComboBox>
#include <QDoubleSpinBox>
#include <QFormLayout>
#include <QHBoxLayout>
#include <QLabel>
#include <QPushButton>
#include <QSettings>
#include <QSignalBlocker>
#include <QStandardItemModel>

#include <algorithm>

#include <fvr/ui/settings_keys.h>

namespace fvr::ui {

DisplayPanel::DisplayPanel(QWidget* parent) : QWidget(parent) {
    auto* df = new QFormLayout(this);
    m_preset = new QComboBox(this);
    m_preset->addItem(tr("Auto (0.5–99.5 %)"), int(WindowPreset::Auto));
    m_preset->addItem(tr("Full range"), int(WindowPreset::FullRange));
    m_preset->addItem(tr("Bone (upper 70 %)"), int(WindowPreset::Bone));
    m_preset->addItem(tr("Soft tissue (10–70 %)"), int(WindowPreset::SoftTissue));
    m_preset->addItem(tr("Custom (set by hand)"), int(WindowPreset::Custom));
    // Custom is a state, not a choice: shown after a manual change, never offered.
    if (auto* model = qobject_cast<QStandardItemModel*>(m_preset->model()))
        model->item(m_preset->count() - 1)->setEnabled(false);
    df->addRow(tr("Preset"), m_preset);
    m_width = new QDoubleSpinBox(this);
    m_width->setDecimals(3);
    m_width->setRange(1e-6, 1e12);
    m_width->setKeyboardTracking(false);
    df->addRow(tr("Window width"), m_width);
    m_level = new QDoubleSpinBox(this);
    m_level->setDecimals(3);
    m_level->setRange(-1e12, 1e12);
    m_level->setKeyboardTracking(false);
    df->addRow(tr("Window level"), m_level);
    m_invert = new QCheckBox(tr("Invert"), this);
    m_invert->setToolTip(
        tr("Line integrals: bone dark. Transmitted intensity: the film look (bone white) when on, "
           "the fluoroscopy look (bone dark) when off."));
    df->addRow(QString(), m_invert);
    auto* autoBtn = new QPushButton(tr("Auto window"), this);
    df->addRow(QString(), autoBtn);
    m_savePreset = new QPushButton(tr("Save preset…"), this);
    m_savePreset->setToolTip(tr("Keep this window as a preset of your own (for this quantity)"));
    m_deletePreset = new QPushButton(tr("Delete preset"), this);
    m_deletePreset->setEnabled(false);
    auto* presetButtons = new QHBoxLayout;
    presetButtons->addWidget(m_savePreset);
    presetButtons->addWidget(m_deletePreset);
    df->addRow(QString(), presetButtons);
    auto* hint = new QLabel(
        tr("<small>Left drag or arrows: rotate · wheel or +/−: zoom · middle drag: pan · right "
           "drag or Ctrl+left: window/level · 1–6: AP, PA, left, right, head, feet · R: reset · "
           "F1: all keys</small>"),
        this);
    hint->setWordWrap(true);
    df->addRow(hint);

    auto windowEdited = [this] {
        emit windowChanged();
        emit changed();
    };
    auto windowSetByHand = [this, windowEdited] {
        showPreset(WindowPreset::Custom);
        windowEdited();
    };
    connect(m_width, &QDoubleSpinBox::valueChanged, this, windowSetByHand);
    connect(m_level, &QDoubleSpinBox::valueChanged, this, windowSetByHand);
    connect(m_invert, &QCheckBox::toggled, this, windowEdited);
    connect(autoBtn, &QPushButton::clicked, this,
            [this] { emit presetRequested(WindowPreset::Auto); });
    connect(m_preset, &QComboBox::activated, this, [this](int index) {
        const int item = m_preset->itemData(index).toInt();
        if (item >= kUserPresetData)
            emit userPresetRequested(item - kUserPresetData);
        else
            emit presetRequested(WindowPreset(item));
    });
    connect(m_preset, &QComboBox::currentIndexChanged, this, [this] {
        m_deletePreset->setEnabled(m_preset->currentData().toInt() >= kUserPresetData);
    });
    connect(m_savePreset, &QPushButton::clicked, this, &DisplayPanel::savePresetRequested);
    connect(m_deletePreset, &QPushButton::clicked, this, [this] {
        const int item = m_preset->currentData().toInt();
        if (item >= kUserPresetData) emit deletePresetRequested(item - kUserPresetData);
    });
}

DisplayPanel::Values DisplayPanel::values() const {
    return {m_width->value(), m_level->value(), m_invert->isChecked()};
}

void DisplayPanel::setValues(const Values& v) {
    const QSignalBlocker b1(m_width), b2(m_level), b3(m_invert);
    m_width->setValue(v.width);
    m_level->setValue(v.level);
    m_invert->setChecked(v.invert);
}

DisplayPanel::Values DisplayPanel::load(const QSettings& s) { return load(s, Values()); }

DisplayPanel::Values DisplayPanel::load(const QSettings& s, Values v) {
    v.invert = s.value(keys::kDisplayInvert, v.invert).toBool();
    return v;
}

void DisplayPanel::save(QSettings& s, const Values& v) {
    s.setValue(keys::kDisplayInvert, v.invert);
}

core::DisplayWindow DisplayPanel::window(const core::Transmission& transmission) const {
    core::DisplayWindow w;
    w.low = m_level->value() - m_width->value() / 2;
    w.high = m_level->value() + m_width->value() / 2;
    w.invert = m_invert->isChecked();
    w.transmission = transmission;
    return w;
}

void DisplayPanel::showWindow(const core::DisplayWindow& w, WindowPreset from) {
    setValues({w.high - w.low, (w.high + w.low) / 2, w.invert});
    showPreset(from);
}

void DisplayPanel::setUserPresets(const QStringList& labels) {
    const QSignalBlocker block(m_preset);
    const QVariant current = m_preset->currentData();
    for (int i = m_preset->count() - 1; i >= 0; --i)
        if (m_preset->itemData(i).toInt() >= kUserPresetData ||
            (m_preset->itemText(i).isEmpty() && !m_preset->itemData(i).isValid()))
            m_preset->removeItem(i); // the user presets and their separator
    if (!labels.isEmpty()) m_preset->insertSeparator(m_preset->count());
    for (int i = 0; i < labels.size(); ++i)
        m_preset->addItem(QStringLiteral("★ ") + labels[i], kUserPresetData + i);
    const int index = m_preset->findData(current);
    m_preset->setCurrentIndex(index >= 0 ? index : m_preset->findData(int(WindowPreset::Custom)));
    m_deletePreset->setEnabled(m_preset->currentData().toInt() >= kUserPresetData);
}

void DisplayPanel::showUserPreset(int index) {
    const QSignalBlocker block(m_preset);
    const int i = m_preset->findData(kUserPresetData + index);
    if (i >= 0) m_preset->setCurrentIndex(i);
    m_deletePreset->setEnabled(i >= 0);
}

void DisplayPanel::showPreset(WindowPreset preset) {
    const QSignalBlocker block(m_preset);
    m_preset->setCurrentIndex(m_preset->findData(int(preset)));
    m_deletePreset->setEnabled(false);
}

core::DisplayWindow presetWindow(WindowPreset preset, const std::vector<float>& pixels,
                                 bool invert) {
    std::vector<float> v = pixels;
    std::sort(v.begin(), v.end());
    auto q = [&](double f) { return double(v[std::size_t(f * (v.size() - 1))]); };
    core::DisplayWindow w;
    switch (preset) {
    case WindowPreset::FullRange: w = {v.front(), v.back(), false}; break;
    case WindowPreset::Bone:
        // Thin bone seen edge-on (a skull vault, ribs) projects to 40-45 % of the range where
        // the skull base reaches the top: the window starts at 30 % and ends at the 99.9th
        // percentile so that both show (it started at 55 % and blacked the vault out).
        w = {q(0.005) + 0.30 * (q(0.995) - q(0.005)), q(0.999), false};
        break;
    case WindowPreset::SoftTissue:
        w = {q(0.005) + 0.10 * (q(0.995) - q(0.005)), q(0.005) + 0.70 * (q(0.995) - q(0.005)),
             false};
        break;
    case WindowPreset::Auto:
    case WindowPreset::Custom: // not a preset (a window set by hand): the auto window
        w = core::autoWindow(pixels);
        break;
    }
    if (!(w.high > w.low)) w.high = w.low + 1.0;
    w.invert = invert;
    return w;
}

} // namespace fvr::ui
