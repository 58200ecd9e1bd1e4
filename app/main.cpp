// fvr-workstation: the Qt6 GUI.
#include <QApplication>
#include <QSurfaceFormat>

#include <cstdio>
#include <memory>
#include <string_view>

#include <fvr/ui/app_info.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/messages_panel.h>
#include <fvr/ui/scripted_run.h>

#include "workstation_options.h"

namespace {

/** Whether the command line asks only for help or the version, which need no display. */
bool onlyPrints(int argc, char** argv) {
    for (int i = 1; i < argc; ++i) {
        const std::string_view a = argv[i];
        if (a == "--") return false;
        if (a == "-h" || a == "--help" || a == "--help-all" || a == "-v" || a == "--version" ||
            a == "-?")
            return true;
    }
    return false;
}

/** Names the application (its help and version say so). */
void nameApplication() {
    QCoreApplication::setApplicationName(QString::fromUtf8(fvr::ui::applicationName()));
    QCoreApplication::setOrganizationName(QString::fromUtf8(fvr::ui::organizationName()));
    QCoreApplication::setApplicationVersion(QString::fromUtf8(fvr::ui::applicationVersion()));
}

} // namespace

int main(int argc, char** argv) {
    if (onlyPrints(argc, argv)) { // without a display (no X server, ssh): no QApplication
        QCoreApplication core(argc, argv);
        nameApplication();
        try {
            fvr::app::parseWorkstationOptions(core); // prints and exits
        } catch (const std::exception& e) {
            std::fprintf(stderr, "fvr-workstation: %s\n", e.what());
            return 2;
        }
        return 0;
    }
    // The GPU renderer needs OpenGL 4.3 core (compute shaders); set before QApplication exists
    // (hellogl2). Without it the views fall back to the CPU renderer and say so.
    QSurfaceFormat fmt;
    fmt.setVersion(4, 3);
    fmt.setProfile(QSurfaceFormat::CoreProfile);
    fmt.setSwapInterval(0);
    QSurfaceFormat::setDefaultFormat(fmt);
    QApplication::setAttribute(Qt::AA_ShareOpenGLContexts);
    QApplication app(argc, argv);
    nameApplication();

    fvr::app::WorkstationOptions options;
    try {
        options = fvr::app::parseWorkstationOptions(app);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "fvr-workstation: %s\n", e.what());
        return 2;
    }
    fvr::ui::MainWindow window;
    window.show();
    fvr::app::applyWorkstationOptions(window, options);
    // Scripted exports (--export-views, --screenshot, --quit) watch the study from its start.
    std::unique_ptr<fvr::ui::ScriptedRun> script;
    if (options.script.active())
        script = std::make_unique<fvr::ui::ScriptedRun>(window, options.script);
    if (!options.session.isEmpty()) {
        // A saved session: its study and screen (File ▸ Open session).
        if (!window.openSession(options.session)) {
            std::fprintf(stderr, "fvr-workstation: %s\n",
                         qPrintable(window.messages()->toPlainText().trimmed().split('\n').last()));
            if (options.script.quit) return 1;
        }
    } else {
        window.openStudy(options.source);
    }
    return app.exec();
}
