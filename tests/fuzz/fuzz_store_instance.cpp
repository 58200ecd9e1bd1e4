// libFuzzer target: the local store's handling of a received C-STORE (detail::storeDataset, as
// the storage listener and C-GET call it). The bytes are read as a DICOM file, wholly into
// memory (as a dataset arrives from the network), then stored into a fresh store (the Studies
// and the Incoming area in turn), stored again (Identical) and stored changed (Quarantined).
// PacsError and WriteError are expected outcomes. A finding: a crash, a sanitizer report, any
// other exception, or any file the store makes outside its own namespace (outside its root, a
// name that is neither a valid UID nor one of the store's own, a temporary left behind).
#include "pacs/pacs_internal.h"

#include <fvr/core/errors.h>
#include <fvr/core/pacs/local_store.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <regex>
#include <string>

namespace fs = std::filesystem;
using namespace fvr::core;

namespace {

/** A private folder for the run; the store is its only entry, made and removed per input. */
const fs::path& baseDir() {
    static const fs::path base = [] {
        const char* dir = std::getenv("TMPDIR");
        std::string tmpl = std::string(dir && *dir ? dir : "/tmp") + "/fvr_fuzz_store_XXXXXX";
        if (!mkdtemp(tmpl.data())) {
            std::perror("mkdtemp");
            std::abort();
        }
        std::atexit([] {
            std::error_code ec;
            fs::remove_all(baseDir(), ec);
        });
        return fs::path(tmpl);
    }();
    return base;
}

[[noreturn]] void finding(const std::string& what, const fs::path& path) {
    std::fprintf(stderr, "fuzz_store_instance: %s: %s\n", what.c_str(), path.c_str());
    std::abort();
}

bool uidFile(const std::string& name) {
    return name.size() > 4 && name.ends_with(".dcm") &&
           pacs::isValidUid(std::string_view(name).substr(0, name.size() - 4));
}

/** `<area>/<study>/<series>/<sop>.dcm` under `dir`, nothing else. */
void checkArea(const fs::path& dir, int depth) {
    for (const auto& e : fs::directory_iterator(dir)) {
        const std::string name = e.path().filename().string();
        if (e.is_symlink()) finding("a symbolic link in the store", e.path());
        if (depth < 2 ? !(e.is_directory() && pacs::isValidUid(name))
                      : !(e.is_regular_file() && uidFile(name)))
            finding("a name outside the store's namespace", e.path());
        if (depth < 2) checkArea(e.path(), depth + 1);
    }
}

/** The whole tree: nothing beside the root, and under it only the store's own names. */
void checkStore(const fs::path& root) {
    for (const auto& e : fs::directory_iterator(baseDir()))
        if (e.path() != root && e.path().filename() != "input.dcm")
            finding("a file outside the store root", e.path());
    if (!fs::exists(root)) return;
    static const std::regex quarantined("[0-9]{8}T[0-9]{6}-([0-9.]+)-[0-9]+\\.dcm");
    for (const auto& e : fs::directory_iterator(root)) {
        const std::string name = e.path().filename().string();
        if (e.is_symlink()) finding("a symbolic link in the store", e.path());
        if (name == "index.json" || name == ".index.lock") {
            if (!e.is_regular_file()) finding("the store's own file is not a file", e.path());
        } else if (name == "incoming") {
            checkArea(e.path(), 0);
        } else if (name == "quarantine") {
            std::smatch m;
            for (const auto& q : fs::directory_iterator(e.path())) {
                const std::string qn = q.path().filename().string();
                if (!std::regex_match(qn, m, quarantined) || !pacs::isValidUid(m[1].str()))
                    finding("a quarantine file of an unexpected name", q.path());
            }
        } else if (!(e.is_directory() && pacs::isValidUid(name))) {
            finding("a name outside the store's namespace", e.path());
        } else {
            checkArea(e.path(), 1);
        }
    }
}

void store(pacs::LocalStore& s, DcmDataset& ds, pacs::Area area) {
    try {
        pacs::detail::storeDataset(s, ds, area);
    } catch (const pacs::PacsError&) {
    } catch (const WriteError&) {}
}

} // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    static int inputs = 0;
    // From a file (DCMTK then checks each declared length against the bytes left before it
    // allocates: from a buffer it allocates up to 4 GB first, which would only slow the run).
    const fs::path input = baseDir() / "input.dcm";
    if (std::FILE* f = std::fopen(input.c_str(), "wb")) {
        if (size > 0 && std::fwrite(data, 1, size, f) != size) std::abort();
        std::fclose(f);
    } else {
        std::abort();
    }
    DcmFileFormat file;
    if (file.loadFile(input.c_str()).bad()) return 0; // not DICOM: nothing reaches the store
    // All in memory, as a dataset received over the network is.
    if (file.loadAllDataIntoMemory().bad()) return 0;

    const fs::path root = baseDir() / "store";
    {
        pacs::LocalStore s(root);
        DcmDataset& ds = *file.getDataset();
        const pacs::Area area = ++inputs % 2 ? pacs::Area::Studies : pacs::Area::Incoming;
        store(s, ds, area);
        store(s, ds, area); // the same again: Identical
        ds.putAndInsertString(DCM_PatientComments, "changed"); // other bytes: Quarantined
        store(s, ds, area);
        store(s, ds, area == pacs::Area::Studies ? pacs::Area::Incoming : pacs::Area::Studies);
    }
    checkStore(root);
    std::error_code ec;
    fs::remove_all(root, ec);
    return 0;
}
