// fvr-workstation: the Qt6 GUI.
#include <QApplication>
#include <QCommandLineParser>
#include <QSurfaceFormat>

#include <cstdio>

#include <fvr/core/xray/patient_views.h>
#include <fvr/ui/app_info.h>
#include <fvr/ui/main_window.h>

int main(int argc, char** argv) {
    // The GPU renderer needs OpenGL 4.3 core (compute shaders); set before QApplication exists
    // (hellogl2). Without it the views fall back to the CPU renderer and say so.
    QSurfaceFormat fmt;
    fmt.setVersion(4, 3);
    fmt.setProfile(QSurfaceFormat::CoreProfile);
    fmt.setSwapInterval(0);
    QSurfaceFormat::setDefaultFormat(fmt);
    QApplication::setAttribute(Qt::AA_ShareOpenGLContexts);
    QApplication app(argc, argv);
    QApplication::setApplicationName(QString::fromUtf8(fvr::ui::applicationName()));
    QApplication::setOrganizationName(QString::fromUtf8(fvr::ui::organizationName()));
    QApplication::setApplicationVersion(QString::fromUtf8(fvr::ui::applicationVersion()));

    QCommandLineParser parser;
    parser.setApplicationDescription("Fourier volume rendering workstation");
    parser.addHelpOption();
    parser.addVersionOption();
    parser.addPositionalArgument("study",
                                 "DICOM folder, DICOMDIR or DICOM file, volume file (.mhd, .mha, "
                                 ".nii, .nii.gz) or phantom:shepp-logan[:N], as fvr-render opens "
                                 "them; without it the built-in phantom opens");
    QCommandLineOption series("series", "DICOM series to open (key or SeriesInstanceUID)", "uid");
    parser.addOption(series);
    QCommandLineOption compare(
        "compare", "Start with N synchronised views side by side (1, 2 or 4)", "n", "1");
    parser.addOption(compare);
    QCommandLineOption view("view", "Start with a patient view: AP, PA, LEFT, RIGHT, HEAD or FEET",
                            "view");
    parser.addOption(view);
    parser.process(app);

    fvr::ui::MainWindow window;
    window.show();
    window.setCompareCount(parser.value(compare).toInt());
    if (parser.isSet(view)) {
        try {
            const auto pv = fvr::core::parsePatientView(parser.value(view).toStdString());
            QObject::connect(&window.study(), &fvr::ui::StudyController::studyLoaded, &window,
                             [&window, pv] { window.showPatientView(pv); });
        } catch (const std::exception& e) {
            std::fprintf(stderr, "fvr-workstation: %s\n", e.what());
            return 2;
        }
    }
    const QStringList args = parser.positionalArguments();
    if (args.isEmpty()) {
        window.openStudy(fvr::ui::StudySource::phantom(128));
    } else {
        auto source = fvr::ui::StudySource::fromPath(args.first());
        source.seriesKey = parser.value(series);
        window.openStudy(source);
    }
    return app.exec();
}
