// libFuzzer target: the single-file DICOM reader (fvr::core::loadDicomFile) and the X-ray
// geometry reader (fvr::core::readXrayGeometry) on arbitrary bytes.
// The bytes go to a private temporary file (the reader takes paths: DCMTK reads pixel data
// lazily from the file). Any DicomError is an expected outcome; every other exception, crash,
// sanitizer report, leak, timeout or oversized allocation is a finding.
#include <fvr/core/dicom/dicom.h>
#include <fvr/core/dicom/xray_geometry.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>

#include <unistd.h>

namespace {

std::string& scratchPath() {
    static std::string path = [] {
        const char* dir = std::getenv("TMPDIR");
        std::string tmpl = std::string(dir && *dir ? dir : "/tmp") + "/fvr_fuzz_dicom_XXXXXX";
        const int fd = mkstemp(tmpl.data());
        if (fd < 0) {
            std::perror("mkstemp");
            std::abort();
        }
        close(fd);
        std::atexit([] { std::remove(scratchPath().c_str()); });
        return tmpl;
    }();
    return path;
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const std::string& path = scratchPath();
    std::FILE* f = std::fopen(path.c_str(), "wb");
    if (!f) std::abort();
    if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
    std::fclose(f);
    try {
        const fvr::core::DicomVolume v = fvr::core::loadDicomFile(path);
        // Touch the result so that a wrong size shows up under ASan.
        volatile float sink = v.volume.voxels.empty() ? 0.0f : v.volume.voxels.back();
        (void)sink;
        if (std::int64_t(v.volume.voxels.size()) != v.volume.voxelCount()) std::abort();
    } catch (const fvr::core::DicomError&) {
        // expected for malformed input
    }
    try {
        const fvr::core::XrayGeometry g = fvr::core::readXrayGeometry(path);
        const std::size_t frameValues = std::size_t(g.width) * std::size_t(g.height);
        if (g.pixels.size() != frameValues * g.frames.size()) std::abort();
        volatile float sink = g.pixels.empty() ? 0.0f : g.pixels.back();
        (void)sink;
    } catch (const fvr::core::DicomError&) {
        // expected for malformed input and for images that are no X-ray
    }
    return 0;
}
