#include "fftw_support.h"

#include <cstdlib>
#include <filesystem>
#include <string>

#include <unistd.h>

namespace fvr::core::detail {

namespace {
std::filesystem::path wisdomPath() {
    if (const char* p = std::getenv("FVR_FFTW_WISDOM")) return p;
    std::filesystem::path base;
    if (const char* x = std::getenv("XDG_CACHE_HOME"); x && *x)
        base = x;
    else if (const char* h = std::getenv("HOME"); h && *h)
        base = std::filesystem::path(h) / ".cache";
    else
        return {};
    return base / "fvr-workstation" / "fftwf-wisdom";
}
bool g_dirty = false;
} // namespace

std::mutex& planMutex() {
    static std::mutex m;
    return m;
}

void ensureFftwInitialised() {
    static std::once_flag once;
    std::call_once(once, [] {
        std::lock_guard lock(planMutex());
        fftwf_init_threads();
        const auto p = wisdomPath();
        if (!p.empty() && std::filesystem::exists(p)) fftwf_import_wisdom_from_filename(p.c_str());
        // Bound the time MEASURE planning may take for a new size.
        fftwf_set_timelimit(3.0);
    });
}

unsigned plannerFlags(bool measure) {
    if (measure) {
        g_dirty = true;
        return FFTW_MEASURE;
    }
    return FFTW_ESTIMATE;
}

void saveWisdom() {
    std::lock_guard lock(planMutex());
    if (!g_dirty) return;
    g_dirty = false;
    const auto p = wisdomPath();
    if (p.empty()) return;
    std::error_code ec;
    std::filesystem::create_directories(p.parent_path(), ec);
    const auto tmp = p.string() + ".tmp" + std::to_string(::getpid());
    if (fftwf_export_wisdom_to_filename(tmp.c_str()))
        std::filesystem::rename(tmp, p, ec);
    else
        std::filesystem::remove(tmp, ec);
}

} // namespace fvr::core::detail
