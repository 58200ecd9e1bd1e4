#pragma once
// The Orthanc every PACS test talks to: one per test program (a GoogleTest Environment), the
// shared series uploaded once.
#include <filesystem>
#include <memory>
#include <string>

#include <gtest/gtest.h>

#include <fvr/core/pacs/pacs.h>

#include "orthanc_server.h"

namespace fvr::test {

inline const char* kPhilips = "dicom/ct_phantom_philips_512x512x140";
inline const char* kSlicer = "dicom/ct_head_slicer_64x64x93";
inline const char* kOurAe = "FVRTEST";

class PacsEnvironment : public ::testing::Environment {
public:
    void SetUp() override; ///< startOrthanc(), its exception kept as setupError()
    void TearDown() override;

    static PacsEnvironment& get();
    /** Why the PACS tests skip (no Orthanc, no shared data), empty when they run. */
    const std::string& skipReason() const { return m_skip; }
    /** Why Orthanc could not be set up (it did not start, an upload failed, with its log):
     *  every PACS test fails with it. */
    const std::string& setupError() const { return m_error; }
    OrthancServer& orthanc() { return *m_orthanc; }
    core::pacs::Node node() const;
    core::pacs::LocalAe local() const;
    /** The synthetic study with a Latin-1 patient name (ISO_IR 100): its UID and the name. */
    std::string latin1StudyUid;
    std::string latin1NameUtf8 = "M\xc3\x9cLLER^J\xc3\x96RG";
    std::filesystem::path dir;

private:
    void startOrthanc();

    std::unique_ptr<OrthancServer> m_orthanc;
    std::string m_skip, m_error;
    int m_listenPort = 0;
};

/** Skips the test with the environment's reason, or fails it with its setup error. */
#define FVR_REQUIRE_ORTHANC()                                                                      \
    do {                                                                                           \
        if (!::fvr::test::PacsEnvironment::get().skipReason().empty())                             \
            GTEST_SKIP() << ::fvr::test::PacsEnvironment::get().skipReason();                      \
        if (!::fvr::test::PacsEnvironment::get().setupError().empty())                             \
            GTEST_FAIL() << ::fvr::test::PacsEnvironment::get().setupError();                      \
    } while (0)

/** A fresh (emptied) local store folder for one test, under the environment's folder. */
inline std::filesystem::path storeRoot(const std::string& name) {
    const std::filesystem::path root = PacsEnvironment::get().dir / "stores" / name;
    std::filesystem::remove_all(root);
    return root;
}

/** A DICOM file's string tag (DCMTK), "" when absent. */
std::string dicomTag(const std::filesystem::path& file, const std::string& tagName);

} // namespace fvr::test
