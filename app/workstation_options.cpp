#include "workstation_options.h"

#include <QApplication>
#include <QComboBox>
#include <QCommandLineParser>
#include <QObject>
#include <QRegularExpression>

#include <fvr/core/errors.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/text.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/rendering_panel.h>

namespace fvr::app {

namespace {

template <class Parse>
auto parsed(const QString& option, const QString& value, Parse parse) {
    try {
        return parse(value.toStdString());
    } catch (const std::exception& e) {
        // The core parsers name what they parse ("kernel: expected …").
        const std::string what = e.what(), name = option.toStdString();
        throw core::SettingsError("--" +
                                  (what.starts_with(name + ":") ? what : name + ": " + what));
    }
}

void declareOptions(QCommandLineParser& p) {
    p.setApplicationDescription("Fourier volume rendering workstation");
    p.addHelpOption();
    p.addVersionOption();
    p.addPositionalArgument("study",
                            "DICOM folder, DICOMDIR or DICOM file, volume file (.mhd, .mha, "
                            ".nii, .nii.gz), phantom:chest[:N] or phantom:shepp-logan[:N], as "
                            "fvr-render opens them; without it the built-in chest phantom opens");
    p.addOptions({
        {"series", "DICOM series to open (key or SeriesInstanceUID)", "uid"},
        {"compare", "Start with N synchronised views side by side (1, 2 or 4)", "n", "1"},
        {"view", "Start with a patient view: AP, PA, LEFT, RIGHT, HEAD or FEET", "view"},
        {"kernel",
         "View 1's interpolation kernel, or the views' in order (K1,K2,…): nearest, linear, "
         "bspline, catmull-rom, sinc4, kaiser-bessel4 or kaiser-bessel6 (names as fvr-render's "
         "--kernel)",
         "K"},
        {"voxel-model",
         "Every view's voxel model, or the views' in order (M1,M2,…): trilinear, bspline or "
         "bandlimited (as fvr-render's --voxel-model)",
         "M"},
        {"size", "Every view's slice/image size: 128, 256, 512, 1024 or 2048", "M"},
        {"window-size", "The main window's size, e.g. 1400x1000", "WxH"},
        {"export-views",
         "Once every view shows its full-quality frame, write DIR/view1.npy … (the float "
         "projection), DIR/view1.png … (the displayed image without the overlay) and "
         "DIR/views.json",
         "DIR"},
        {"screenshot", "Once every view is ready, write the whole window as PNG", "FILE"},
        {"quit", "Quit once the exports are written (exit code 0); 1 when the study fails to open, "
                 "3 on timeout"},
        {"script-timeout", "Seconds to wait for the views before giving up (default 600)", "S",
         "600"},
    });
}

int positiveInt(const QCommandLineParser& p, const QString& option) {
    bool ok = false;
    const int v = p.value(option).toInt(&ok);
    if (!ok || v <= 0)
        throw core::SettingsError("--" + option.toStdString() + ": expected a positive number, " +
                                  "found '" + p.value(option).toStdString() + "'");
    return v;
}

} // namespace

WorkstationOptions parseWorkstationOptions(const QApplication& app) {
    QCommandLineParser p;
    declareOptions(p);
    p.process(app);
    WorkstationOptions o;
    o.compare = positiveInt(p, "compare");
    if (o.compare != 1 && o.compare != 2 && o.compare != 4)
        throw core::SettingsError("--compare: expected 1, 2 or 4");
    if (p.isSet("view")) o.view = parsed("view", p.value("view"), core::parsePatientView);
    for (const QString& k : p.value("kernel").split(',', Qt::SkipEmptyParts))
        o.kernels.push_back(parsed("kernel", k, core::parseKernel));
    for (const QString& m : p.value("voxel-model").split(',', Qt::SkipEmptyParts))
        o.voxelModels.push_back(parsed("voxel-model", m, core::parseVoxelModel));
    if (int(o.kernels.size()) > o.compare || int(o.voxelModels.size()) > o.compare)
        throw core::SettingsError("--kernel, --voxel-model: at most one per view (--compare)");
    if (p.isSet("size")) {
        o.size = parsed("size", p.value("size"), [](const std::string& s) {
            const auto m = core::parseNumber<int>(s);
            if (!m) throw core::SettingsError("expected a whole number, found '" + s + "'");
            core::validateSettingsSize(*m);
            return *m;
        });
    }
    if (p.isSet("window-size")) {
        const auto m = QRegularExpression("^(\\d+)x(\\d+)$").match(p.value("window-size"));
        if (!m.hasMatch()) throw core::SettingsError("--window-size: expected WxH, e.g. 1400x1000");
        o.windowSize = QSize(m.captured(1).toInt(), m.captured(2).toInt());
    }
    o.script.exportDir = p.value("export-views");
    o.script.screenshotFile = p.value("screenshot");
    o.script.quit = p.isSet("quit");
    o.script.timeoutSeconds = positiveInt(p, "script-timeout");
    const QStringList args = p.positionalArguments();
    o.source = args.isEmpty() ? ui::StudySource::chest() : ui::StudySource::fromPath(args[0]);
    o.source.seriesKey = p.value("series");
    return o;
}

namespace {
/** Selects the item holding `data` in a panel combo, as a user's choice (its signals fire). */
void choose(QComboBox* combo, int data) {
    const int i = combo->findData(data);
    if (i >= 0) combo->setCurrentIndex(i);
}
} // namespace

void applyWorkstationOptions(ui::MainWindow& window, const WorkstationOptions& o) {
    if (o.windowSize) window.resize(*o.windowSize);
    window.setCompareCount(o.compare);
    ui::RenderingPanel& panel = *window.renderingPanel();
    // Through the panel as a user would: "Applies to" view i (compare mode), then the choice.
    auto forView = [&](int i, const auto& change) {
        if (o.compare > 1) panel.appliesToCombo()->setCurrentIndex(i + 1);
        change();
    };
    if (o.size)
        for (int i = 0; i < o.compare; ++i) forView(i, [&] { choose(panel.sizeCombo(), *o.size); });
    for (std::size_t i = 0; i < o.kernels.size(); ++i)
        forView(int(i), [&] { choose(panel.kernelCombo(), int(o.kernels[i])); });
    for (int i = 0; i < o.compare && !o.voxelModels.empty(); ++i) {
        const core::VoxelModel m =
            o.voxelModels[std::min<std::size_t>(i, o.voxelModels.size() - 1)];
        forView(i, [&] { choose(panel.voxelModelCombo(), int(m)); });
    }
    panel.appliesToCombo()->setCurrentIndex(0);
    if (o.view) {
        const core::PatientView pv = *o.view;
        QObject::connect(&window.study(), &ui::StudyController::studyLoaded, &window,
                         [&window, pv] { window.showPatientView(pv); });
    }
}

} // namespace fvr::app
