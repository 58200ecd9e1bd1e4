// The reader's basics around the views: the navigation keys, View ▸ Panels, Help ▸ Keyboard
// shortcuts and About.
#include <fvr/ui/main_window.h>

#include <QAction>
#include <QDialog>
#include <QDialogButtonBox>
#include <QDockWidget>
#include <QHeaderView>
#include <QLabel>
#include <QMenu>
#include <QMenuBar>
#include <QMessageBox>
#include <QTableWidget>
#include <QToolBar>
#include <QVBoxLayout>

#include <fvr/ui/app_info.h>

namespace fvr::ui {

namespace {
constexpr double kArrowStepDeg = 5.0;
constexpr double kPageStepDeg = 90.0;
constexpr double kZoomStep = 1.25;

QString plainText(const QAction* a) {
    QString t = a->text();
    t.remove('&');
    return t.replace(QStringLiteral("…"), QString());
}

/** Every action with a shortcut under `menu`, "File ▸ Open…" style. */
void collectShortcuts(const QMenu* menu, const QString& path, QList<QPair<QString, QString>>* out) {
    for (const QAction* a : menu->actions()) {
        if (a->menu()) {
            collectShortcuts(a->menu(), path + plainText(a) + QStringLiteral(" ▸ "), out);
            continue;
        }
        if (a->shortcuts().isEmpty()) continue;
        QStringList keys;
        for (const QKeySequence& k : a->shortcuts()) keys << k.toString(QKeySequence::NativeText);
        out->append({path + plainText(a), keys.join(QStringLiteral(", "))});
    }
}
} // namespace

void MainWindow::rotateViews(double horizontalDeg, double verticalDeg) {
    if (m_views.empty() || !m_study->volume()) return;
    // View 1 turns; the others follow it (connectView), as with a drag.
    m_views[0]->rotateBy(horizontalDeg, verticalDeg);
}

void MainWindow::zoomViews(double factor) {
    for (auto* v : m_views) v->setZoom(v->zoom() * factor);
}

void MainWindow::buildNavigation(QMenu* view) {
    QMenu* turn = view->addMenu(tr("&Turn and zoom"));
    struct Key {
        QString text;
        QList<QKeySequence> keys;
        std::function<void()> act;
    };
    const double a = kArrowStepDeg, p = kPageStepDeg;
    const Key keys[] = {
        {tr("Turn left %1°").arg(a), {Qt::Key_Left}, [this, a] { rotateViews(-a, 0); }},
        {tr("Turn right %1°").arg(a), {Qt::Key_Right}, [this, a] { rotateViews(a, 0); }},
        {tr("Tilt up %1°").arg(a), {Qt::Key_Up}, [this, a] { rotateViews(0, -a); }},
        {tr("Tilt down %1°").arg(a), {Qt::Key_Down}, [this, a] { rotateViews(0, a); }},
        {tr("Turn left %1°").arg(p), {Qt::Key_PageUp}, [this, p] { rotateViews(-p, 0); }},
        {tr("Turn right %1°").arg(p), {Qt::Key_PageDown}, [this, p] { rotateViews(p, 0); }},
        {tr("Zoom in"),
         {QKeySequence(Qt::Key_Plus), QKeySequence(Qt::Key_Equal)},
         [this] { zoomViews(kZoomStep); }},
        {tr("Zoom out"), {QKeySequence(Qt::Key_Minus)}, [this] { zoomViews(1.0 / kZoomStep); }},
    };
    for (const Key& k : keys) {
        QAction* action = turn->addAction(k.text, this, k.act);
        action->setShortcuts(k.keys);
        // Only while a view has the focus: a panel's spin box or list keeps its arrows.
        action->setShortcutContext(Qt::WidgetWithChildrenShortcut);
        m_viewHost->addAction(action);
    }
}

void MainWindow::buildPanelsMenu(QMenu* view) {
    QMenu* panels = view->addMenu(tr("&Panels"));
    // Closed panels come back from here (and the toolbar); the dock's own action keeps the
    // check mark true.
    for (QDockWidget* d : findChildren<QDockWidget*>()) panels->addAction(d->toggleViewAction());
    panels->addSeparator();
    for (QToolBar* t : findChildren<QToolBar*>()) panels->addAction(t->toggleViewAction());
}

QString MainWindow::aboutText() {
    return tr("<b>%1 %2</b> (commit %3)"
              "<p><b>Not for diagnostic use.</b> A research and teaching tool: its images are "
              "not cleared for clinical decisions.</p>"
              "<p>X-ray-like projections by Fourier volume rendering (Viola, Kanitsar, Gröller), "
              "and cone-beam ray casting. A parallel projection has no occlusion: every pixel "
              "is a line integral through the whole volume.</p>")
        .arg(QString::fromUtf8(applicationName()), QString::fromUtf8(applicationVersion()),
             QString::fromUtf8(applicationCommit()));
}

QList<QPair<QString, QString>> MainWindow::shortcutList() const {
    QList<QPair<QString, QString>> out;
    for (const QAction* a : menuBar()->actions())
        if (a->menu()) collectShortcuts(a->menu(), plainText(a) + QStringLiteral(" ▸ "), &out);
    const QString drag = tr("Mouse");
    out.append({drag + tr(": rotate (a cone beam: LAO/RAO, CRAN/CAUD)"), tr("Left drag")});
    out.append({drag + tr(": window width and level"), tr("Right drag, or Ctrl + left drag")});
    out.append({drag + tr(": pan"), tr("Middle drag")});
    out.append({drag + tr(": zoom"), tr("Wheel")});
    return out;
}

void MainWindow::showShortcutsDialog() {
    auto* dialog = new QDialog(this);
    dialog->setAttribute(Qt::WA_DeleteOnClose);
    dialog->setObjectName("dialog.shortcuts");
    dialog->setWindowTitle(tr("Keyboard shortcuts"));
    auto* layout = new QVBoxLayout(dialog);
    const auto rows = shortcutList();
    auto* table = new QTableWidget(int(rows.size()), 2, dialog);
    table->setHorizontalHeaderLabels({tr("Action"), tr("Keys")});
    table->verticalHeader()->hide();
    table->setEditTriggers(QAbstractItemView::NoEditTriggers);
    for (int i = 0; i < rows.size(); ++i) {
        table->setItem(i, 0, new QTableWidgetItem(rows[i].first));
        table->setItem(i, 1, new QTableWidgetItem(rows[i].second));
    }
    table->resizeColumnsToContents();
    table->horizontalHeader()->setStretchLastSection(true);
    layout->addWidget(table);
    layout->addWidget(new QLabel(tr("Turning and zooming keys act while a view has the focus "
                                    "(click one)."),
                                 dialog));
    auto* buttons = new QDialogButtonBox(QDialogButtonBox::Close, dialog);
    connect(buttons, &QDialogButtonBox::rejected, dialog, &QDialog::close);
    layout->addWidget(buttons);
    dialog->resize(560, 520);
    dialog->show();
}

void MainWindow::buildHelpMenu() {
    QMenu* help = menuBar()->addMenu(tr("&Help"));
    QAction* keys =
        help->addAction(tr("&Keyboard shortcuts"), this, &MainWindow::showShortcutsDialog);
    keys->setShortcut(QKeySequence(Qt::Key_F1));
    help->addAction(tr("&About"), this, [this] {
        QMessageBox::about(this, tr("About %1").arg(QString::fromUtf8(applicationName())),
                           aboutText());
    });
}

} // namespace fvr::ui
