// The user's own window presets: a window kept under a name, for the quantity it was set on
// (a window in mm means nothing on −ln(I/I0)), in the settings (QSettings) like the others.
#include <fvr/ui/main_window.h>

#include <QInputDialog>
#include <QSettings>
#include <QVariantMap>

#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/settings_model.h>

namespace fvr::ui {

namespace {
constexpr char kUserPresetsKey[] = "display/userPresets";
} // namespace

QString MainWindow::windowQuantity() const {
    if (m_views.empty()) return {};
    // A transmission output windows the film's log exposure, whatever the line integrals' units.
    if (currentTransmission().active()) return tr("log exposure");
    return m_views[0]->valueUnits();
}

QList<MainWindow::UserPreset> MainWindow::userPresets() const {
    QList<UserPreset> out;
    for (const QVariant& v : QSettings().value(kUserPresetsKey).toList()) {
        const QVariantMap m = v.toMap();
        UserPreset p{m.value("name").toString(), m.value("low").toDouble(),
                     m.value("high").toDouble(), m.value("quantity").toString()};
        if (!p.name.isEmpty() && p.high > p.low) out.append(p);
    }
    return out;
}

void MainWindow::storeUserPresets(const QList<UserPreset>& presets) {
    QVariantList list;
    for (const UserPreset& p : presets)
        list.append(QVariantMap{
            {"name", p.name}, {"low", p.low}, {"high", p.high}, {"quantity", p.quantity}});
    QSettings().setValue(kUserPresetsKey, list);
    QStringList labels;
    for (const UserPreset& p : presets)
        labels << QStringLiteral("%1 (%2)").arg(p.name,
                                                p.quantity.isEmpty() ? tr("any") : p.quantity);
    m_display->setUserPresets(labels);
}

bool MainWindow::saveWindowPreset(const QString& name) {
    const QString n = name.trimmed();
    if (n.isEmpty() || m_views.empty() || !m_study->volume()) {
        message(tr("Save preset: %1")
                    .arg(n.isEmpty() ? tr("a preset needs a name") : tr("no study is open")),
                true);
        return false;
    }
    const core::DisplayWindow w = m_views[0]->window();
    const QString quantity = windowQuantity();
    QList<UserPreset> presets = userPresets();
    // One preset per name and quantity: saving again replaces it.
    presets.erase(
        std::remove_if(presets.begin(), presets.end(),
                       [&](const UserPreset& p) { return p.name == n && p.quantity == quantity; }),
        presets.end());
    presets.append({n, w.low, w.high, quantity});
    storeUserPresets(presets);
    m_display->showUserPreset(int(presets.size()) - 1);
    message(tr("Window preset \"%1\" saved: W %2 / L %3 %4")
                .arg(n)
                .arg(w.high - w.low, 0, 'g', 4)
                .arg((w.high + w.low) / 2, 0, 'g', 4)
                .arg(quantity));
    return true;
}

bool MainWindow::applyUserPreset(int index) {
    const QList<UserPreset> presets = userPresets();
    if (index < 0 || index >= presets.size() || m_views.empty()) return false;
    const UserPreset& p = presets[index];
    const QString quantity = windowQuantity();
    if (!p.quantity.isEmpty() && p.quantity != quantity) {
        message(tr("Preset \"%1\" is a window on %2; the view shows %3: not applied")
                    .arg(p.name, p.quantity, quantity),
                true);
        syncWindowToPanel(m_views[0]->window(), WindowPreset::Custom);
        return false;
    }
    core::DisplayWindow w = m_views[0]->window();
    w.low = p.low;
    w.high = p.high;
    syncWindowToPanel(w, WindowPreset::Custom);
    m_display->showUserPreset(index);
    applyWindowFromPanel();
    noteStateChange(true, ChangeKind::Window);
    return true;
}

void MainWindow::deleteUserPreset(int index) {
    QList<UserPreset> presets = userPresets();
    if (index < 0 || index >= presets.size()) return;
    const QString name = presets[index].name;
    presets.removeAt(index);
    storeUserPresets(presets);
    message(tr("Window preset \"%1\" deleted").arg(name));
}

void MainWindow::connectUserPresets() {
    storeUserPresets(userPresets()); // the combo lists them
    connect(m_display, &DisplayPanel::userPresetRequested, this, &MainWindow::applyUserPreset);
    connect(m_display, &DisplayPanel::deletePresetRequested, this, &MainWindow::deleteUserPreset);
    connect(m_display, &DisplayPanel::savePresetRequested, this, [this] {
        bool ok = false;
        const QString name =
            QInputDialog::getText(this, tr("Save window preset"),
                                  tr("Name for this window (on %1):").arg(windowQuantity()),
                                  QLineEdit::Normal, QString(), &ok);
        if (ok) saveWindowPreset(name);
    });
}

} // namespace fvr::ui
