// fvr-render and the workstation open paths by the same core rule (io/open_study.h): the same
// default series of a multi-series folder, a single DICOM file opens in both, and values without
// units are taken for Hounsfield units in both. The CLI is the real binary; the workstation side
// is its StudyController, as the menus drive it.
#include <QCoreApplication>
#include <QSignalSpy>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <fvr/core/io/open_study.h>
#include <fvr/ui/study.h>

#include "test_support.h"

namespace {
namespace fs = std::filesystem;
using fvr::test::sharedData;
using fvr::ui::StudyController;
using fvr::ui::StudySource;

QCoreApplication& app() {
    static int argc = 1;
    static char name[] = "fvr_open_rule_tests";
    static char* argv[] = {name, nullptr};
    static auto* a = new QCoreApplication(argc, argv);
    return *a;
}

using Cli = fvr::test::CommandOutput; ///< out: stdout (JSON), or stderr with stderrOnly

/** Runs fvr-render; `out` gets its stdout, or its stderr with `stderrOnly`. */
Cli runCli(const std::string& args, bool stderrOnly = false) {
    return fvr::test::runCommand(std::string(FVR_RENDER_EXE) + " " + args +
                                 (stderrOnly ? " 2>&1 >/dev/null" : " 2>/dev/null"));
}

nlohmann::json cliInfo(const fs::path& input, const std::string& more = {}) {
    std::string args = "'";
    args += input.string();
    args += "' --info ";
    args += more;
    const Cli r = runCli(args);
    EXPECT_EQ(r.status, 0) << r.out;
    return nlohmann::json::parse(r.out);
}

/** Opens `source` in a StudyController and waits for its spectrum. */
bool openInWorkstation(StudyController& study, const StudySource& source) {
    QSignalSpy ready(&study, &StudyController::spectrumReady);
    QSignalSpy failed(&study, &StudyController::failed);
    study.open(source);
    if (!ready.wait(120000)) {
        ADD_FAILURE() << "no spectrum for " << source.path.toStdString() << " ("
                      << (failed.isEmpty() ? std::string("timeout")
                                           : failed.first().at(1).toString().toStdString())
                      << ")";
        return false;
    }
    return true;
}

TEST(OpenRule, DefaultSeriesIsTheSameInCliAndWorkstation) {
    app();
    FVR_REQUIRE_DATA("dicom_edge/enhanced_multiframe_mr");
    const fs::path dir = sharedData() / "dicom_edge/enhanced_multiframe_mr";
    // Workstation: the series dialog's first (preselected) entry.
    StudyController study;
    QSignalSpy choice(&study, &StudyController::seriesChoiceNeeded);
    study.open(StudySource::fromPath(QString::fromStdString(dir.string())));
    ASSERT_TRUE(choice.wait(60000));
    const QStringList keys = choice.first().at(1).toStringList();
    ASSERT_EQ(keys.size(), 6);
    // fvr-render: --info marks the series it opens by default; the core rule names the same.
    const nlohmann::json info = cliInfo(dir);
    std::string cliDefault;
    int defaults = 0;
    for (const auto& s : info.at("series"))
        if (s.at("default").get<bool>()) {
            cliDefault = s.at("key").get<std::string>();
            ++defaults;
        }
    EXPECT_EQ(defaults, 1);
    EXPECT_EQ(cliDefault, keys.first().toStdString());
    const auto scan = fvr::core::scanDicomFolder(dir);
    EXPECT_EQ(scan.series[fvr::core::defaultSeriesIndex(scan)].key, cliDefault);
    EXPECT_EQ(cliInfo(dir, "--series " + cliDefault).at("dims")[2].get<int>(), 32);
    // And fvr-render renders that series when none is named: 32 Philips slices, not 6 Siemens
    // (the sidecar records the volume), saying which it chose.
    const std::string out = (fvr::test::tmpDir() / "open_rule_default.npy").string();
    std::string args = "'"; // appended piece by piece: GCC 12 warns (-Wrestrict) on a chain
    args += dir.string();
    args += "' --size 128 --out '";
    args += out;
    args += "'";
    const Cli r = runCli(args, true);
    ASSERT_EQ(r.status, 0) << r.out;
    EXPECT_NE(r.out.find("loaded " + cliDefault + " (the loadable one with most slices"),
              std::string::npos)
        << r.out;
    std::ifstream sidecar(out + ".json");
    const auto side = nlohmann::json::parse(sidecar);
    EXPECT_EQ(side.at("volume").at("dims")[2].get<int>(), 32) << side.at("volume").dump();
}

TEST(OpenRule, SingleDicomFileOpensInBoth) {
    app();
    FVR_REQUIRE_DATA("dicom/ct_head_slicer_64x64x93/CTHead1.dcm");
    const fs::path file = sharedData() / "dicom/ct_head_slicer_64x64x93/CTHead1.dcm";
    StudyController study;
    const StudySource src = StudySource::fromPath(QString::fromStdString(file.string()));
    EXPECT_EQ(src.kind, StudySource::Kind::DicomFile);
    ASSERT_TRUE(openInWorkstation(study, src));
    const auto& v = *study.volume();
    const nlohmann::json info = cliInfo(file);
    EXPECT_EQ(info.at("dims").get<std::vector<std::int64_t>>(),
              (std::vector<std::int64_t>{v.dims[0], v.dims[1], v.dims[2]}));
    EXPECT_EQ(v.dims[2], 1);
    EXPECT_EQ(info.at("units").get<std::string>(), fvr::core::unitsName(v.units));
}

TEST(OpenRule, HounsfieldGuessIsTheSameInCliAndWorkstation) {
    app();
    FVR_REQUIRE_DATA("volumes/body_ct_hu_3mm/example_ct.mhd");
    for (const char* name : {"example_ct.mhd", "example_ct.nii.gz"}) {
        const fs::path file = sharedData() / "volumes/body_ct_hu_3mm" / name;
        StudyController study;
        ASSERT_TRUE(
            openInWorkstation(study, StudySource::fromPath(QString::fromStdString(file.string()))));
        EXPECT_EQ(study.volume()->units, fvr::core::ValueUnits::HounsfieldUnits) << name;
        EXPECT_TRUE(study.warnings().join('\n').contains("look like Hounsfield units")) << name;
        // Attenuation from HU, as the CLI's default values for HU.
        EXPECT_EQ(study.spectrumSettings().mapping, fvr::core::ValueMapping::Mu) << name;
        EXPECT_EQ(cliInfo(file).at("units").get<std::string>(),
                  fvr::core::unitsName(fvr::core::ValueUnits::HounsfieldUnits))
            << name;
    }
    // An 8-bit volume is not CT in either.
    FVR_REQUIRE_DATA("volumes/bonsai_256");
    for (const auto& e : fs::directory_iterator(sharedData() / "volumes/bonsai_256")) {
        StudyController study;
        ASSERT_TRUE(openInWorkstation(
            study, StudySource::fromPath(QString::fromStdString(e.path().string()))));
        EXPECT_EQ(study.volume()->units, fvr::core::ValueUnits::Unknown);
        EXPECT_EQ(cliInfo(e.path()).at("units").get<std::string>(),
                  fvr::core::unitsName(fvr::core::ValueUnits::Unknown));
    }
}

} // namespace
