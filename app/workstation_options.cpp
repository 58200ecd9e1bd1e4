#include "workstation_options.h"

#include <QApplication>
#include <QComboBox>
#include <QCommandLineParser>
#include <QDoubleSpinBox>
#include <QObject>
#include <QRegularExpression>

#include <algorithm>
#include <cmath>
#include <memory>

#include <fvr/core/errors.h>
#include <fvr/core/render/render_settings.h>
#include <fvr/core/text.h>
#include <fvr/ui/main_window.h>
#include <fvr/ui/panels/geometry_panel.h>
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
        {"projection",
         "Every view's projection, or the views' in order (P1,P2,…): parallel (Fourier) or cone "
         "(a C-arm's cone beam, ray cast)",
         "P"},
        {"carm",
         "Start at these C-arm angles (degrees): primary (LAO +, RAO -), secondary (CRAN +, CAUD "
         "-), e.g. 30,15",
         "A,B"},
        {"sid", "The cone beam's source-to-detector distance, mm", "mm"},
        {"sod", "The cone beam's source-to-isocentre distance, mm (less than --sid)", "mm"},
        {"ray-model", "The cone beam's voxel model: trilinear, box or bspline", "M"},
        {"match-xray",
         "Once the study is open, show this X-ray (XA, RF, DX, CR) beside the DRR rendered with "
         "its geometry (File > Open X-ray to match...)",
         "FILE"},
        {"open-session",
         "Open a saved session (File > Save session...): its study, views, windows and "
         "settings; instead of a study",
         "FILE"},
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

double number(const QCommandLineParser& p, const QString& option) {
    const auto v = core::parseNumber<double>(p.value(option).toStdString());
    if (!v || !std::isfinite(*v))
        throw core::SettingsError("--" + option.toStdString() + ": expected a number, found '" +
                                  p.value(option).toStdString() + "'");
    return *v;
}

void parseGeometry(const QCommandLineParser& p, WorkstationOptions& o) {
    for (const QString& m : p.value("projection").split(',', Qt::SkipEmptyParts)) {
        if (m == QStringLiteral("parallel"))
            o.projections.push_back(ui::ProjectionKind::Parallel);
        else if (m == QStringLiteral("cone"))
            o.projections.push_back(ui::ProjectionKind::Cone);
        else
            throw core::SettingsError("--projection: expected parallel or cone, found '" +
                                      m.toStdString() + "'");
    }
    if (int(o.projections.size()) > o.compare)
        throw core::SettingsError("--projection: at most one per view (--compare)");
    if (p.isSet("carm")) {
        const QStringList a = p.value("carm").split(',');
        const auto p0 =
            a.size() == 2 ? core::parseNumber<double>(a[0].toStdString()) : std::nullopt;
        const auto p1 =
            a.size() == 2 ? core::parseNumber<double>(a[1].toStdString()) : std::nullopt;
        if (!p0 || !p1 || std::abs(*p0) > 180.0 || std::abs(*p1) > 89.0)
            throw core::SettingsError("--carm: expected PRIMARY,SECONDARY in degrees (|primary| "
                                      "<= 180, |secondary| <= 89), found '" +
                                      p.value("carm").toStdString() + "'");
        o.carm = {*p0, *p1};
    }
    if (p.isSet("sid")) o.sid = number(p, "sid");
    if (p.isSet("sod")) o.sod = number(p, "sod");
    const double sid = o.sid.value_or(ui::ConeSettings{}.sid);
    const double sod = o.sod.value_or(ui::ConeSettings{}.sod);
    if (!(sod > 0.0) || !(sid > sod) || sid > 5000.0)
        throw core::SettingsError("--sid, --sod: expected 0 < SOD < SID <= 5000 mm, found SOD " +
                                  core::formatNumber(sod) + ", SID " + core::formatNumber(sid));
    if (p.isSet("ray-model"))
        o.rayModel = parsed("ray-model", p.value("ray-model"), core::parseRayModel);
}

} // namespace

WorkstationOptions parseWorkstationOptions(const QCoreApplication& app) {
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
            const auto sizes = core::settingsSizes();
            if (std::find(sizes.begin(), sizes.end(), *m) == sizes.end())
                throw core::SettingsError("expected one of the workstation's sizes, 128, 256, "
                                          "512, 1024 or 2048, found " +
                                          std::to_string(*m) +
                                          " (fvr-render and Python render any WxH)");
            return *m;
        });
    }
    parseGeometry(p, o);
    if (p.isSet("window-size")) {
        const auto m = QRegularExpression("^(\\d+)x(\\d+)$").match(p.value("window-size"));
        if (!m.hasMatch()) throw core::SettingsError("--window-size: expected WxH, e.g. 1400x1000");
        o.windowSize = QSize(m.captured(1).toInt(), m.captured(2).toInt());
    }
    o.matchXray = p.value("match-xray");
    o.session = p.value("open-session");
    if (!o.session.isEmpty() && !p.positionalArguments().isEmpty())
        throw core::SettingsError("--open-session: the session names its study; give no study too");
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

/** The Geometry panel's controls, as a user would set them, per view through "Applies to". */
template <class ForView>
void applyGeometryOptions(ui::MainWindow& window, const WorkstationOptions& o, ForView forView) {
    ui::GeometryPanel& g = *window.geometryPanel();
    for (int i = 0; i < o.compare; ++i) {
        forView(i, [&] {
            if (o.sid) g.sidSpin()->setValue(*o.sid);
            if (o.sod) g.sodSpin()->setValue(*o.sod);
            if (o.rayModel) choose(g.rayModelCombo(), int(*o.rayModel));
            if (!o.projections.empty())
                choose(g.projectionCombo(),
                       int(o.projections[std::min<std::size_t>(i, o.projections.size() - 1)]));
        });
    }
    if (!o.matchXray.isEmpty()) {
        const QString path = o.matchXray;
        auto done = std::make_shared<bool>(false); // once: at the study's first spectrum
        QObject::connect(&window.study(), &ui::StudyController::spectrumReady, &window,
                         [&window, path, done] {
                             if (*done) return;
                             *done = true;
                             window.matchXray(path);
                         });
    }
    if (o.carm) {
        const auto [a, b] = *o.carm;
        QObject::connect( // the command line's study only, as --view
            &window.study(), &ui::StudyController::studyLoaded, &window,
            [&window, a, b] {
                window.geometryPanel()->primarySpin()->setValue(a);
                window.geometryPanel()->secondarySpin()->setValue(b);
            },
            Qt::SingleShotConnection);
    }
}

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
    applyGeometryOptions(window, o, forView);
    panel.appliesToCombo()->setCurrentIndex(0);
    if (o.view) {
        const core::PatientView pv = *o.view;
        // The command line's study only: a study opened later starts as any other.
        QObject::connect(
            &window.study(), &ui::StudyController::studyLoaded, &window,
            [&window, pv] { window.showPatientView(pv); }, Qt::SingleShotConnection);
    }
}

} // namespace fvr::app
