// The reader's history and keys: undo/redo of view, window and setting changes, a saved session
// that reopens to the same screen, the user's own window presets, the navigation keys, View ▸
// Panels, Help ▸ Keyboard shortcuts and About.
#include <QAction>
#include <QComboBox>
#include <QDockWidget>
#include <QDoubleSpinBox>
#include <QFile>
#include <QMenu>
#include <QMenuBar>
#include <QRegularExpression>
#include <QUndoStack>

#include <cmath>
#include <numbers>

#include <fvr/ui/app_info.h>
#include <fvr/ui/panels/display_panel.h>
#include <fvr/ui/panels/rendering_panel.h>
#include <fvr/ui/panels/xray_panel.h>
#include <fvr/ui/settings_model.h>

#include "ui_support.h"

namespace fvr::test {
namespace {

double angleDeg(const core::Vec3& a, const core::Vec3& b) {
    const double c = glm::dot(a, b) / (glm::length(a) * glm::length(b));
    return std::acos(std::clamp(c, -1.0, 1.0)) * 180.0 / std::numbers::pi;
}

/** The window active, as a user's is: shortcuts act only in the active window. */
void activate(QWidget* w) {
    w->activateWindow();
    ASSERT_TRUE(QTest::qWaitForWindowActive(w));
}

/** Waits until every view shows its full-quality frame of the settings in effect. */
bool settled(MainWindow& w, int timeoutMs = 60000) {
    return QTest::qWaitFor(
        [&] {
            for (auto* v : w.views())
                if (!v->showsCurrentFrame()) return false;
            return true;
        },
        timeoutMs);
}

QString stateText(const ui::WorkstationState& s) {
    QString t = QStringLiteral("compare %1 diff %2 kernel %3 size %4 d (%5 %6 %7)")
                    .arg(s.compareCount)
                    .arg(s.difference)
                    .arg(core::kernelName(s.compareSlots[0].kernel))
                    .arg(s.compareSlots[0].size)
                    .arg(s.frame.d.x)
                    .arg(s.frame.d.y)
                    .arg(s.frame.d.z);
    for (const auto& v : s.views)
        t += QStringLiteral(" | window %1..%2 zoom %3")
                 .arg(v.window.low)
                 .arg(v.window.high)
                 .arg(v.zoom);
    return t;
}

#define EXPECT_STATE(a, b)                                                                         \
    EXPECT_TRUE((a).sameAs(b)) << stateText(a).toStdString() << "\n vs\n"                          \
                               << stateText(b).toStdString()

TEST_F(Workstation, ArrowAndPageKeysTurnTheViewAndPlusMinusZoom) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    activate(window.get());
    auto* v = window->views()[0];
    v->setFocus();
    const core::ViewFrame f0 = v->viewFrame();
    QTest::keyClick(v, Qt::Key_Right);
    const core::ViewFrame f1 = v->viewFrame();
    // A turn about the screen's vertical axis: the direction moves by 5°, the up stays.
    EXPECT_NEAR(angleDeg(f0.d, f1.d), 5.0, 1e-9);
    EXPECT_NEAR(angleDeg(f0.u, f1.u), 0.0, 1e-6);
    // As a drag to the right turns it (the object follows the mouse).
    EXPECT_LT(glm::length(f1.d - f0.rotated(f0.u, 5.0 * std::numbers::pi / 180.0).d), 1e-12);
    QTest::keyClick(v, Qt::Key_Left);
    EXPECT_NEAR(angleDeg(f0.d, v->viewFrame().d), 0.0, 1e-6);
    QTest::keyClick(v, Qt::Key_Up);
    EXPECT_NEAR(angleDeg(f0.d, v->viewFrame().d), 5.0, 1e-9);
    EXPECT_NEAR(angleDeg(f0.r, v->viewFrame().r), 0.0, 1e-6); // about the horizontal axis
    QTest::keyClick(v, Qt::Key_Down);
    QTest::keyClick(v, Qt::Key_PageDown);
    EXPECT_NEAR(angleDeg(f0.d, v->viewFrame().d), 90.0, 1e-9);
    QTest::keyClick(v, Qt::Key_PageUp);
    EXPECT_NEAR(angleDeg(f0.d, v->viewFrame().d), 0.0, 1e-6);
    QTest::keyClick(v, Qt::Key_Plus);
    EXPECT_NEAR(v->zoom(), 1.25, 1e-12);
    QTest::keyClick(v, Qt::Key_Minus);
    QTest::keyClick(v, Qt::Key_Minus);
    EXPECT_NEAR(v->zoom(), 0.8, 1e-12);
    // A panel's spin box keeps its arrows: Up steps the window width, the view does not turn.
    QDoubleSpinBox* width = window->displayPanel()->windowWidthSpin();
    width->setFocus();
    const double w0 = width->value();
    const core::ViewFrame before = v->viewFrame();
    QTest::keyClick(width, Qt::Key_Up);
    EXPECT_GT(width->value(), w0);
    EXPECT_NEAR(angleDeg(before.d, v->viewFrame().d), 0.0, 1e-9);
}

TEST_F(Workstation, UndoAndRedoStepThroughViewWindowAndSettingChanges) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ASSERT_TRUE(settled(*window));
    window->flushStateChange();
    EXPECT_FALSE(window->undoStack()->canUndo()); // opening a study is not a step
    const ui::WorkstationState s0 = window->currentState();
    activate(window.get());
    auto* v = window->views()[0];
    v->setFocus();
    QTest::keyClick(v, Qt::Key_Right); // three keys within 400 ms: one step
    QTest::keyClick(v, Qt::Key_Right);
    QTest::keyClick(v, Qt::Key_Up);
    window->flushStateChange();
    const ui::WorkstationState s1 = window->currentState();
    // The window, by hand in the panel.
    QDoubleSpinBox* width = window->displayPanel()->windowWidthSpin();
    width->setValue(width->value() * 0.5);
    window->flushStateChange();
    const ui::WorkstationState s2 = window->currentState();
    // A setting: the kernel (a new spectrum where gridding correction is on).
    QComboBox* kernel = window->renderingPanel()->kernelCombo();
    kernel->setCurrentIndex(kernel->findData(int(core::Kernel::Linear)));
    ASSERT_TRUE(settled(*window));
    window->flushStateChange();
    const ui::WorkstationState s3 = window->currentState();
    ASSERT_EQ(s3.compareSlots[0].kernel, core::Kernel::Linear);
    ASSERT_EQ(window->undoStack()->count(), 3);

    window->undo();
    EXPECT_STATE(window->currentState(), s2);
    EXPECT_EQ(window->views()[0]->settings().kernel, s0.compareSlots[0].kernel);
    EXPECT_EQ(window->renderingPanel()->kernelCombo()->currentData().toInt(),
              int(s0.compareSlots[0].kernel));
    ASSERT_TRUE(settled(*window));
    EXPECT_STATE(window->currentState(), s2); // no automatic window once the spectrum came
    window->undo();
    EXPECT_STATE(window->currentState(), s1);
    EXPECT_NEAR(window->displayPanel()->windowWidthSpin()->value(),
                s1.views[0].window.high - s1.views[0].window.low, 1e-3);
    window->undo();
    EXPECT_STATE(window->currentState(), s0);
    EXPECT_FALSE(window->undoStack()->canUndo());
    window->redo();
    window->redo();
    window->redo();
    ASSERT_TRUE(settled(*window));
    EXPECT_STATE(window->currentState(), s3);
    // A new change after an undo drops the redo steps, as every editor does.
    window->undo();
    window->zoomViews(2.0);
    window->flushStateChange();
    EXPECT_FALSE(window->undoStack()->canRedo());
}

TEST_F(Workstation, ASettingAndATurnRightAfterItAreTwoUndoSteps) {
    ASSERT_TRUE(openAndWait(*window, StudySource::chest(48))); // HU: it has a transmission
    ASSERT_TRUE(settled(*window));
    window->flushStateChange();
    const ui::WorkstationState start = window->currentState();
    ui::XrayPanel::Values x = window->settings().xray();
    x.output = ui::XrayOutput::Transmission;
    window->settings().setXray(x); // then, within the burst interval, a turn
    window->rotateViews(10, 0);
    window->flushStateChange();
    ASSERT_EQ(window->undoStack()->count(), 2);
    window->undo(); // the turn only
    EXPECT_EQ(window->settings().xray().output, ui::XrayOutput::Transmission);
    EXPECT_LT(glm::length(window->views()[0]->viewFrame().d - start.frame.d), 1e-9);
    window->undo();
    EXPECT_EQ(window->settings().xray().output, start.xray.output);
}

TEST_F(Workstation, UndoReturnsCompareAndDifferenceModes) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(40)));
    window->flushStateChange();
    const ui::WorkstationState single = window->currentState();
    window->setCompareCount(2);
    window->flushStateChange();
    window->setDifferenceMode(true);
    window->flushStateChange();
    window->undo();
    EXPECT_FALSE(window->currentState().difference);
    EXPECT_EQ(window->views().size(), 2u);
    window->undo();
    EXPECT_EQ(window->views().size(), 1u);
    EXPECT_STATE(window->currentState(), single);
    window->redo();
    window->redo();
    EXPECT_TRUE(window->currentState().difference);
    EXPECT_EQ(window->views().size(), 2u);
}

TEST_F(Workstation, ASavedSessionReopensToTheSameScreen) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    window->setCompareCount(2);
    ASSERT_TRUE(settled(*window));
    window->rotateViews(30, -10);
    window->zoomViews(1.5);
    window->views()[1]->setPan({12, -7});
    QDoubleSpinBox* level = window->displayPanel()->windowLevelSpin();
    level->setValue(level->value() + 3.0);
    ASSERT_TRUE(settled(*window));
    window->flushStateChange();
    const ui::WorkstationState saved = window->currentState();
    const auto before = window->views()[0]->projection();
    ASSERT_TRUE(before);
    const QString path = QString::fromStdString((tmpDir() / "reader.fvrsession").string());
    ASSERT_TRUE(window->saveSession(path));

    // Another window, as after a restart, opens it.
    window.reset();
    QSettings().clear();
    window = std::make_unique<MainWindow>();
    window->resize(1200, 800);
    window->show();
    ASSERT_TRUE(QTest::qWaitForWindowExposed(window.get()));
    QSignalSpy restored(window.get(), &MainWindow::sessionRestored);
    ASSERT_TRUE(window->openSession(path));
    ASSERT_TRUE(restored.wait(60000)) << window->messages()->toPlainText().toStdString();
    ASSERT_TRUE(settled(*window));
    EXPECT_STATE(window->currentState(), saved);
    ASSERT_EQ(window->views().size(), 2u);
    const auto after = window->views()[0]->projection();
    ASSERT_TRUE(after);
    ASSERT_EQ(after->pixels.size(), before->pixels.size());
    double maxDiff = 0;
    for (std::size_t i = 0; i < after->pixels.size(); ++i)
        maxDiff = std::max(maxDiff, double(std::abs(after->pixels[i] - before->pixels[i])));
    EXPECT_LT(maxDiff, 1e-4); // the same image, not just the same numbers in the panels
    EXPECT_NEAR(window->displayPanel()->windowLevelSpin()->value(),
                (saved.views[0].window.low + saved.views[0].window.high) / 2, 1e-3);
}

TEST_F(Workstation, AFileThatIsNotASessionIsRefusedByName) {
    const QString path = QString::fromStdString((tmpDir() / "not-a-session.fvrsession").string());
    {
        QFile f(path);
        ASSERT_TRUE(f.open(QIODevice::WriteOnly));
        f.write("just some text\n");
    }
    EXPECT_FALSE(window->openSession(path));
    const QString text = window->messages()->toPlainText();
    EXPECT_TRUE(text.contains(path) && text.contains("not a session")) << text.toStdString();
    EXPECT_FALSE(window->openSession(path + ".missing"));
    EXPECT_FALSE(window->saveSession(path)); // no study open
}

TEST_F(Workstation, UserWindowPresetsAreKeptPerQuantity) {
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    ASSERT_TRUE(settled(*window));
    auto* display = window->displayPanel();
    display->windowWidthSpin()->setValue(4.0);
    display->windowLevelSpin()->setValue(10.0);
    ASSERT_TRUE(window->saveWindowPreset("Narrow"));
    ASSERT_EQ(window->userPresets().size(), 1);
    EXPECT_EQ(window->userPresets()[0].quantity, window->views()[0]->valueUnits());
    const int item = display->presetCombo()->findData(ui::DisplayPanel::kUserPresetData);
    ASSERT_GE(item, 0);
    EXPECT_TRUE(display->presetCombo()->itemText(item).contains("Narrow"));
    // Another window, then the preset from the combo as a user picks it.
    display->windowWidthSpin()->setValue(40.0);
    display->presetCombo()->setCurrentIndex(item);
    emit display->presetCombo()->activated(item);
    const core::DisplayWindow w = window->views()[0]->window();
    EXPECT_NEAR(w.high - w.low, 4.0, 1e-9);
    EXPECT_NEAR((w.high + w.low) / 2, 10.0, 1e-9);
    // Kept in the settings: a new window lists it.
    window.reset();
    window = std::make_unique<MainWindow>();
    ASSERT_EQ(window->userPresets().size(), 1);
    EXPECT_GE(window->displayPanel()->presetCombo()->findData(ui::DisplayPanel::kUserPresetData),
              0);
    window->show();
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(48)));
    // On another quantity (transmitted intensity) the preset is refused, by name.
    ui::XrayPanel::Values x = window->settings().xray();
    x.output = ui::XrayOutput::Transmission;
    window->settings().setXray(x);
    ASSERT_TRUE(settled(*window));
    const core::DisplayWindow t = window->views()[0]->window();
    EXPECT_FALSE(window->applyUserPreset(0));
    EXPECT_EQ(window->views()[0]->window().low, t.low);
    EXPECT_TRUE(window->messages()->toPlainText().contains("\"Narrow\" is a window on"));
    window->deleteUserPreset(0);
    EXPECT_TRUE(window->userPresets().isEmpty());
    EXPECT_LT(window->displayPanel()->presetCombo()->findData(ui::DisplayPanel::kUserPresetData),
              0);
}

TEST_F(Workstation, ViewPanelsMenuBringsBackAClosedPanel) {
    auto* dock = window->findChild<QDockWidget*>("dock.display");
    ASSERT_TRUE(dock);
    dock->close();
    ASSERT_FALSE(dock->isVisible());
    QAction* panels = nullptr;
    for (QAction* a : window->menuBar()->actions())
        if (a->menu() && a->text().remove('&') == "View")
            for (QAction* b : a->menu()->actions())
                if (b->menu() && b->text().remove('&') == "Panels") panels = b;
    ASSERT_TRUE(panels);
    QAction* show = nullptr;
    for (QAction* a : panels->menu()->actions())
        if (a->text() == dock->windowTitle()) show = a;
    ASSERT_TRUE(show);
    EXPECT_FALSE(show->isChecked());
    show->trigger();
    EXPECT_TRUE(dock->isVisible());
    EXPECT_TRUE(show->isChecked());
}

TEST_F(Workstation, KeyboardShortcutsListEveryMenuShortcutOnceWithoutClashes) {
    const auto rows = window->shortcutList();
    QMap<QString, QString> byKey;
    bool undo = false, left = false;
    for (const auto& [action, keys] : rows) {
        if (action.startsWith("Mouse")) continue;
        if (action == "Edit ▸ Undo" &&
            keys.contains(QKeySequence(QKeySequence::Undo).toString(QKeySequence::NativeText)))
            undo = true;
        if (action.endsWith("Turn left 5°") && keys == QKeySequence(Qt::Key_Left).toString())
            left = true;
        for (const QString& k : keys.split(", ")) {
            // Two actions on one key: Qt runs neither ("ambiguous shortcut").
            EXPECT_FALSE(byKey.contains(k)) << k.toStdString() << ": " << action.toStdString()
                                            << " and " << byKey.value(k).toStdString();
            byKey[k] = action;
        }
    }
    EXPECT_TRUE(undo);
    EXPECT_TRUE(left);
    EXPECT_GE(byKey.size(), 25);
}

TEST_F(Workstation, AboutSaysNotForDiagnosticUseWithVersionAndCommit) {
    const QString about = MainWindow::aboutText();
    EXPECT_TRUE(about.contains("Not for diagnostic use")) << about.toStdString();
    EXPECT_TRUE(about.contains(QString::fromUtf8(ui::applicationVersion())));
    const QString commit = QString::fromUtf8(ui::applicationCommit());
    EXPECT_TRUE(commit == "unknown" ||
                QRegularExpression("^[0-9a-f]{10}\\+?$").match(commit).hasMatch())
        << commit.toStdString();
    EXPECT_TRUE(about.contains(commit));
}

} // namespace
} // namespace fvr::test

namespace fvr::test {
namespace {

/** The largest step between horizontal neighbours of the view's grey image, away from its
 *  orientation labels' text: an edge's sharpness on screen. */
int sharpestStep(ui::ProjectionView& v) {
    const QImage g = v.screenshot().convertToFormat(QImage::Format_Grayscale8);
    const double dpr = double(g.width()) / v.width();
    const auto labels = v.orientationLabelRects();
    int best = 0;
    for (int y = 0; y < g.height(); ++y)
        for (int x = 0; x + 1 < g.width(); ++x) {
            const QPoint p(int(x / dpr), int(y / dpr));
            if (std::any_of(labels.begin(), labels.end(),
                            [&](const QRect& r) { return r.adjusted(-3, -3, 3, 3).contains(p); }))
                continue;
            best = std::max(best, std::abs(int(g.pixelColor(x + 1, y).value()) -
                                           int(g.pixelColor(x, y).value())));
        }
    return best;
}

TEST_F(Workstation, ZoomRendersAtTheScreensResolutionNotMagnifiedPixels) {
    ui::RenderingPanel::Values r = window->settings().rendering();
    r.size = 128;
    window->settings().setRendering(r);
    // 128³ voxels across a field of view of their diagonal (222 voxels) on 128 pixels: the
    // pixels are coarser than the voxels, so a zoomed-in frame has more to show.
    ASSERT_TRUE(openAndWait(*window, StudySource::phantom(128)));
    ASSERT_TRUE(settled(*window));
    auto* v = window->views()[0];
    EXPECT_EQ(v->displayedSize(), 128); // zoom 1: the slice resolution
    window->overlayAction()->setChecked(false); // the image alone in the screenshots
    window->zoomViews(2.0);
    ASSERT_TRUE(settled(*window));
    // 2× the slice's pixels (256), or the screen's where that is less.
    const int side = std::min(v->width(), v->height()) * 2;
    EXPECT_EQ(v->displayedSize(), side >= 256 ? 256 : 128);
    const int zoomed = v->displayedSize();
    window->overlayAction()->setChecked(true);
    QTest::qWait(50);
    EXPECT_TRUE(v->overlayText().contains(QStringLiteral("rendered %1×%1").arg(zoomed)))
        << v->overlayText().toStdString();
    window->overlayAction()->setChecked(false);
    // Exports and measurements keep the slice resolution.
    const auto p = v->projection();
    ASSERT_TRUE(p);
    EXPECT_EQ(p->width, 128);
    ASSERT_TRUE(settled(*window));
    EXPECT_EQ(v->displayedSize(), zoomed);
    // Sharper on screen than the magnified pixels of the same zoom: the phantom's skull edge
    // spans fewer screen pixels.
    const int sharp = sharpestStep(*v);
    v->setZoomRendering(false);
    ASSERT_TRUE(settled(*window));
    EXPECT_EQ(v->displayedSize(), 128);
    const int magnified = sharpestStep(*v);
    EXPECT_GT(sharp, 1.3 * magnified) << sharp << " vs " << magnified;
    // Difference views compare slice-resolution frames.
    v->setZoomRendering(true);
    window->setCompareCount(2);
    window->setDifferenceMode(true);
    window->zoomViews(4.0);
    ASSERT_TRUE(settled(*window));
    for (auto* view : window->views()) EXPECT_EQ(view->displayedSize(), 128);
}

} // namespace
} // namespace fvr::test
