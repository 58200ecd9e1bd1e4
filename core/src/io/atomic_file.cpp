#include <fvr/core/io/atomic_file.h>

#include <fstream>

#include <fvr/core/errors.h>

namespace fvr::core {
namespace fs = std::filesystem;

void writeAtomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& write) {
    fs::path tmp = path;
    tmp += ".part";
    std::error_code ec;
    try {
        write(tmp);
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
    fs::rename(tmp, path, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw WriteError(path.string() + ": cannot move the written file into place");
    }
}

void writeFileAtomic(const fs::path& path, const std::string& bytes) {
    writeAtomically(path, [&](const fs::path& tmp) {
        std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
        if (!out) throw WriteError(path.string() + ": cannot open for writing");
        out.write(bytes.data(), std::streamsize(bytes.size()));
        out.flush();
        if (!out) throw WriteError(path.string() + ": write failed (disk full?)");
    });
}

} // namespace fvr::core
