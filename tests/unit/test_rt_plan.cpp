// RT Plans read into treatment beams: plans written here with DCMTK (the values known), every
// beam's first control point, its setup's patient position, and bad plans refused with the file
// and the missing or wrong tag named.
#include <fstream>
#include <string>

#include <gtest/gtest.h>

#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/rt_plan.h>
#include <fvr/core/errors.h>

#include "support/rt_plan_writer.h"
#include "test_support.h"

namespace {

using namespace fvr::core;
using fvr::test::TestBeam;
using fvr::test::TestPlan;

std::filesystem::path planPath(const std::string& name) {
    const auto dir = fvr::test::tmpDir() / "rt_plan";
    std::filesystem::create_directories(dir);
    return dir / (name + ".dcm");
}

/** The message of the LoadError that reading `plan` throws ("" when none). */
std::string errorOf(const std::string& name, const TestPlan& plan) {
    const auto path = planPath(name);
    fvr::test::writeTestRtPlan(path, plan);
    try {
        readRtPlan(path);
    } catch (const LoadError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find(path.string()), std::string::npos) << "the file is not named: " << m;
        return m;
    }
    ADD_FAILURE() << name << ": no error";
    return {};
}

TEST(RtPlan, ReadsEveryBeamsFirstControlPointAndItsSetupsPosition) {
    TestPlan p;
    p.setups = {{1, "HFS"}, {2, "FFP"}};
    TestBeam a;
    a.number = 3;
    a.name = "RAO";
    a.gantry = "315.5";
    a.collimator = "10";
    a.couch = "350";
    a.isocentre = "12.5\\-40\\101";
    a.setupReference = 1;
    TestBeam b;
    b.number = 7;
    b.name = "LAT";
    b.gantry = "90";
    b.sad = "800";
    b.isocentre = "0\\0\\-5";
    b.setupReference = 2;
    p.beams = {a, b};
    const auto path = planPath("two_beams");
    fvr::test::writeTestRtPlan(path, p);
    const RtPlan plan = readRtPlan(path);
    EXPECT_EQ(plan.label, "TEST PLAN");
    ASSERT_EQ(plan.beams.size(), 2u);
    const RtPlanBeam& x = plan.beams[0];
    EXPECT_EQ(x.number, 3);
    EXPECT_EQ(x.name, "RAO");
    EXPECT_EQ(x.deliveryType, "TREATMENT");
    EXPECT_EQ(x.beam.gantryDeg, 315.5); // control point 0, not control point 1's 123
    EXPECT_EQ(x.beam.collimatorDeg, 10.0);
    EXPECT_EQ(x.beam.couchDeg, 350.0);
    EXPECT_EQ(x.beam.isocentre, glm::dvec3(12.5, -40, 101));
    EXPECT_EQ(x.beam.sad, 1000.0);
    EXPECT_EQ(x.beam.sid, 1500.0); // the plan has no imager: the default
    EXPECT_EQ(x.beam.position, PatientPosition::HFS);
    const RtPlanBeam& y = plan.beams[1];
    EXPECT_EQ(y.number, 7);
    EXPECT_EQ(y.beam.gantryDeg, 90.0);
    EXPECT_EQ(y.beam.sad, 800.0);
    EXPECT_EQ(y.beam.position, PatientPosition::FFP);
    EXPECT_TRUE(plan.warnings.empty());
    EXPECT_EQ(readRtPlanBeams(path).size(), 2u);
    // The camera of a plan's beam is the camera of the same numbers given by hand.
    TreatmentBeam hand;
    hand.gantryDeg = 315.5;
    hand.collimatorDeg = 10;
    hand.couchDeg = 350;
    hand.isocentre = {12.5, -40, 101};
    const ProjectionMatrix p1 = treatmentBeamCamera(x.beam, 64, 48, 0.8, 0.8).matrix();
    const ProjectionMatrix p2 = treatmentBeamCamera(hand, 64, 48, 0.8, 0.8).matrix();
    for (int r = 0; r < 3; ++r) EXPECT_EQ(p1.rows[r], p2.rows[r]);
}

TEST(RtPlan, OneSetupServesBeamsThatReferenceNoneAndAMissingSadIsAssumedAndSaid) {
    TestPlan p;
    p.setups = {{1, "HFP"}};
    p.beams[0].sad.reset();
    const auto path = planPath("no_sad");
    fvr::test::writeTestRtPlan(path, p);
    const RtPlan plan = readRtPlan(path);
    ASSERT_EQ(plan.beams.size(), 1u);
    EXPECT_EQ(plan.beams[0].beam.position, PatientPosition::HFP);
    EXPECT_EQ(plan.beams[0].beam.sad, 1000.0);
    EXPECT_FALSE(plan.beams[0].sadStated);
    ASSERT_EQ(plan.warnings.size(), 1u);
    EXPECT_NE(plan.warnings[0].find("SourceAxisDistance (300a,00b4)"), std::string::npos)
        << plan.warnings[0];
}

void expectHas(const std::string& message, const std::string& part) {
    EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' not in: " << message;
}

TEST(RtPlan, MissingTagsAreNamedWithTheBeam) {
    TestPlan p;
    p.beams[0].number = 4;
    p.beams[0].gantry.reset();
    std::string m = errorOf("no_gantry", p);
    expectHas(m, "beam number 4");
    expectHas(m, "GantryAngle (300a,011e)");
    p = TestPlan{};
    p.beams[0].couch.reset();
    expectHas(errorOf("no_couch", p), "PatientSupportAngle (300a,0122)");
    p = TestPlan{};
    p.beams[0].collimator.reset();
    expectHas(errorOf("no_coll", p), "BeamLimitingDeviceAngle (300a,0120)");
    p = TestPlan{};
    p.beams[0].isocentre.reset();
    expectHas(errorOf("no_iso", p), "IsocenterPosition (300a,012c)");
    p = TestPlan{};
    p.beams[0].isocentre = "1\\2";
    expectHas(errorOf("short_iso", p), "found 2 values");
    p = TestPlan{};
    p.beams[0].controlPoints = false;
    expectHas(errorOf("no_cp", p), "ControlPointSequence (300a,0111)");
    p = TestPlan{};
    p.beamSequence = false;
    expectHas(errorOf("no_beams", p), "BeamSequence (300a,00b0)");
    p = TestPlan{};
    p.beams[0].gantry = "ninety";
    expectHas(errorOf("bad_gantry", p), "GantryAngle (300a,011e) 'ninety' is not a number");
    p = TestPlan{};
    p.beams[0].sad = "-5";
    expectHas(errorOf("bad_sad", p), "SourceAxisDistance (300a,00b4)");
}

TEST(RtPlan, PatientSetupProblemsAreNamed) {
    TestPlan p;
    p.setups.clear();
    expectHas(errorOf("no_setup", p), "PatientSetupSequence (300a,0180)");
    p = TestPlan{};
    p.setups = {{1, "HFS"}, {2, "FFS"}};
    expectHas(errorOf("ambiguous_setup", p), "ReferencedPatientSetupNumber (300c,006a)");
    p = TestPlan{};
    p.beams[0].setupReference = 9;
    expectHas(errorOf("dangling_setup", p), "9 names no item");
    p = TestPlan{};
    p.setups = {{1, ""}};
    expectHas(errorOf("no_position", p), "PatientPosition (0018,5100)");
    p = TestPlan{};
    p.setups = {{1, "SITTING"}};
    const std::string m = errorOf("sitting", p);
    expectHas(m, "'SITTING'");
    expectHas(m, "HFS, HFP, FFS, FFP");
}

TEST(RtPlan, OtherObjectsAreRefusedSayingWhatTheyAre) {
    TestPlan p;
    p.sopClass = UID_CTImageStorage;
    expectHas(errorOf("ct", p), "not an RT Plan");
    p.sopClass = UID_RTIonPlanStorage;
    expectHas(errorOf("ion", p), "RT Ion Plan");
    const auto missing = planPath("does_not_exist");
    std::filesystem::remove(missing);
    try {
        readRtPlan(missing);
        ADD_FAILURE() << "a missing file was read";
    } catch (const LoadError& e) {
        expectHas(e.what(), missing.string());
    }
    const auto text = planPath("text");
    { std::ofstream(text) << "not DICOM at all, just some text in a file"; }
    EXPECT_THROW(readRtPlan(text), LoadError);
}

TEST(RtPlan, ReadsPydicomsRtPlanTestFile) {
    // A plan written by another tool: pydicom's test file (Debian's python3-pydicom ships it;
    // packaging/install-deps.sh --tests installs it). Its values as dcmdump shows them.
    const std::filesystem::path dir = "/usr/lib/python3/dist-packages/pydicom/data/test_files";
    if (!std::filesystem::exists(dir / "rtplan.dcm"))
        GTEST_SKIP() << dir / "rtplan.dcm"
                     << " not found: install python3-pydicom (make test)";
    const RtPlan plan = readRtPlan(dir / "rtplan.dcm");
    EXPECT_EQ(plan.label, "Plan1");
    ASSERT_EQ(plan.beams.size(), 1u);
    const RtPlanBeam& b = plan.beams[0];
    EXPECT_EQ(b.number, 1);
    EXPECT_EQ(b.name, "Field 1");
    EXPECT_EQ(b.deliveryType, "TREATMENT");
    EXPECT_EQ(b.beam.sad, 1000.0);
    EXPECT_TRUE(b.sadStated);
    EXPECT_EQ(b.beam.gantryDeg, 0.0);
    EXPECT_EQ(b.beam.collimatorDeg, 0.0);
    EXPECT_EQ(b.beam.couchDeg, 0.0);
    EXPECT_EQ(b.beam.isocentre, glm::dvec3(235.711172833292, 244.135437110782, -724.97815409918));
    EXPECT_EQ(b.beam.position, PatientPosition::HFS);
    EXPECT_TRUE(plan.warnings.empty());
    // Its truncated copy ends inside IsocenterPosition: refused, naming the file.
    try {
        readRtPlan(dir / "rtplan_truncated.dcm");
        ADD_FAILURE() << "a truncated plan was read";
    } catch (const LoadError& e) {
        expectHas(e.what(), (dir / "rtplan_truncated.dcm").string());
        expectHas(e.what(), "not a readable DICOM file");
    }
}

} // namespace
