#pragma once
// What the workstation's UI tests share: the QApplication (settings of this process's own), a
// study opened and rendered, and the fixture with a shown main window.
#include <QApplication>
#include <QSettings>
#include <QSignalSpy>
#include <QStandardPaths>
#include <QSurfaceFormat>
#include <QTest>

#include <memory>
#include <string>

#include <gtest/gtest.h>

#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/messages_panel.h>

#include "test_support.h"

namespace fvr::test {

using ui::MainWindow;
using ui::StudySource;

inline QApplication& app() {
    static int argc = 1;
    static char name[] = "fvr_ui_tests";
    static char* argv[] = {name, nullptr};
    static QApplication* a = [] {
        QSurfaceFormat fmt;
        fmt.setVersion(4, 3);
        fmt.setProfile(QSurfaceFormat::CoreProfile);
        QSurfaceFormat::setDefaultFormat(fmt);
        QApplication::setAttribute(Qt::AA_ShareOpenGLContexts);
        QStandardPaths::setTestModeEnabled(true);
        // Settings of this process's own: CTest runs the tests in parallel processes, and one
        // test's QSettings().clear() must not reach another's (a flaky persistence check).
        const auto dir =
            test::tmpDir() / ("settings-" + std::to_string(QCoreApplication::applicationPid()));
        QSettings::setPath(QSettings::NativeFormat, QSettings::UserScope,
                           QString::fromStdString(dir.string()));
        auto* x = new QApplication(argc, argv);
        QApplication::setOrganizationName("fvr-workstation-tests");
        QApplication::setApplicationName("fvr-ui-tests");
        return x;
    }();
    return *a;
}

/** Opens a study and waits until its spectrum is ready and view 0 has rendered. */
inline bool openAndWait(MainWindow& w, const StudySource& s, int timeoutMs = 60000) {
    QSignalSpy ready(&w.study(), &ui::StudyController::spectrumReady);
    const int before = w.views()[0]->framesRendered();
    w.openStudy(s);
    if (!ready.wait(timeoutMs)) {
        ADD_FAILURE() << "no spectrum; messages:\n" << w.messages()->toPlainText().toStdString();
        return false;
    }
    if (!QTest::qWaitFor([&] { return w.views()[0]->framesRendered() > before; }, timeoutMs)) {
        ADD_FAILURE() << "view 0 did not render; messages:\n"
                      << w.messages()->toPlainText().toStdString();
        return false;
    }
    return true;
}

class Workstation : public ::testing::Test {
protected:
    void SetUp() override {
        app();
        QSettings().clear(); // each test starts from the defaults
        // but with the GPU path under test even on a software OpenGL (llvmpipe here), where the
        // workstation's default is the CPU renderer (SoftwareOpenGlRendersOnTheCpu).
        QSettings().setValue("render/softwareGpu", true);
        window = std::make_unique<MainWindow>();
        window->resize(1200, 800);
        window->show();
        ASSERT_TRUE(QTest::qWaitForWindowExposed(window.get()));
    }
    void TearDown() override { window.reset(); }
    std::unique_ptr<MainWindow> window;
};

} // namespace fvr::test
