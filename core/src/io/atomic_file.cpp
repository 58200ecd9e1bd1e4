#include <fvr/core/io/atomic_file.h>

#include <cerrno>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

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
    AtomicFileWriter out(path);
    out.write(bytes.data(), bytes.size());
    out.commit();
}

AtomicFileWriter::AtomicFileWriter(fs::path path) : m_path(std::move(path)) {
    fs::path tmp = m_path;
    tmp += ".part";
    m_fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0666);
    if (m_fd < 0) fail("cannot open for writing", errno); // nothing of ours to remove
    m_tmp = std::move(tmp);
}

AtomicFileWriter::~AtomicFileWriter() { discard(); }

void AtomicFileWriter::write(const void* data, std::size_t size) {
    if (m_fd < 0) throw WriteError(m_path.string() + ": write after the file was closed");
    const char* p = static_cast<const char*>(data);
    while (size > 0) {
        const ssize_t n = ::write(m_fd, p, size);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) fail("write failed", n < 0 ? errno : ENOSPC);
        p += n;
        size -= std::size_t(n);
    }
}

void AtomicFileWriter::commit() {
    if (m_fd < 0) throw WriteError(m_path.string() + ": commit after the file was closed");
    const int fd = m_fd;
    m_fd = -1;
    if (::close(fd) != 0) { // NFS and quotas report here
        const int err = errno;
        std::error_code ec;
        fs::remove(m_tmp, ec);
        m_tmp.clear();
        throw WriteError(m_path.string() + ": write failed: " + std::strerror(err));
    }
    std::error_code ec;
    fs::rename(m_tmp, m_path, ec);
    if (ec) {
        fs::remove(m_tmp, ec);
        m_tmp.clear();
        throw WriteError(m_path.string() + ": cannot move the written file into place");
    }
    m_tmp.clear();
}

void AtomicFileWriter::fail(const std::string& what, int err) {
    discard();
    throw WriteError(m_path.string() + ": " + what + ": " + std::strerror(err));
}

void AtomicFileWriter::discard() noexcept {
    if (m_fd >= 0) ::close(m_fd);
    m_fd = -1;
    if (!m_tmp.empty()) {
        std::error_code ec;
        fs::remove(m_tmp, ec);
        m_tmp.clear();
    }
}

} // namespace fvr::core
