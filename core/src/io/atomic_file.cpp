#include <fvr/core/io/atomic_file.h>

#include <atomic>
#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include <fcntl.h>
#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {
namespace fs = std::filesystem;

namespace {

constexpr std::size_t kMaxNameBytes = 255; // NAME_MAX of the usual Linux file systems
constexpr std::string_view kTempSuffix = ".part";

/** Digits only, at least one. */
bool allDigits(std::string_view s) {
    return !s.empty() && s.find_first_not_of("0123456789") == std::string_view::npos;
}

/** Lower-case hexadecimal digits only, exactly `n` of them. */
bool hexDigits(std::string_view s, std::size_t n) {
    return s.size() == n && s.find_first_not_of("0123456789abcdef") == std::string_view::npos;
}

/** The text that tells this process's pid space apart: the host name and the pid namespace
 *  (/proc/self/ns/pid reads "pid:[<inode>]": the same for every process of one kernel's pid
 *  space, another for a container with its own). */
std::string pidSpaceText() {
    char host[256] = {};
    if (::gethostname(host, sizeof host - 1) != 0) host[0] = '\0';
    std::string text = host;
    text += '\n';
    char ns[128] = {};
    const ssize_t n = ::readlink("/proc/self/ns/pid", ns, sizeof ns - 1);
    if (n > 0) text.append(ns, static_cast<std::size_t>(n));
    return text;
}

} // namespace

std::string writerIdentity() {
    static const std::string identity = [] {
        std::uint32_t hash = 2166136261u; // FNV-1a, 32 bits
        for (const unsigned char c : pidSpaceText()) hash = (hash ^ c) * 16777619u;
        char hex[9];
        std::snprintf(hex, sizeof hex, "%08x", static_cast<unsigned>(hash));
        return std::string(hex);
    }();
    return identity;
}

fs::path temporaryPathFor(const fs::path& path) {
    static std::atomic<unsigned long long> counter{0};
    std::string tail(1, '.'); // appended piece by piece (GCC 12 warns falsely on "." + string)
    tail += std::to_string(static_cast<long>(::getpid()));
    tail += '-';
    tail += writerIdentity();
    tail += '.';
    tail += std::to_string(counter.fetch_add(1));
    tail += kTempSuffix;
    std::string name(1, '.');
    name += path.filename().string();
    const std::size_t room = kMaxNameBytes - tail.size();
    if (name.size() > room) name.resize(room);
    name += tail;
    return path.parent_path() / name;
}

std::optional<long> temporaryWriterPid(const fs::path& tmp) {
    const std::string file = tmp.filename().string();
    std::string_view name = file;
    if (name.size() < 2 || name.front() != '.' || !name.ends_with(kTempSuffix)) return std::nullopt;
    name.remove_suffix(kTempSuffix.size());
    const std::size_t counterDot = name.rfind('.');
    if (counterDot == std::string_view::npos || counterDot == 0) return std::nullopt;
    const std::size_t pidDot = name.rfind('.', counterDot - 1);
    if (pidDot == std::string_view::npos || pidDot == 0) return std::nullopt;
    std::string_view pid = name.substr(pidDot + 1, counterDot - pidDot - 1);
    if (!allDigits(name.substr(counterDot + 1))) return std::nullopt;
    // PID-IDENTITY (this form) or PID alone (the form before it): a pid of another pid space
    // (another host, a container) says nothing about the processes here.
    if (const std::size_t dash = pid.find('-'); dash != std::string_view::npos) {
        if (!hexDigits(pid.substr(dash + 1), 8) || pid.substr(dash + 1) != writerIdentity())
            return std::nullopt;
        pid = pid.substr(0, dash);
    }
    if (!allDigits(pid)) return std::nullopt;
    const std::optional<long> value = parseNumber<long>(pid);
    if (!value || *value <= 0) return std::nullopt;
    return *value;
}

void writeAtomically(const fs::path& path, const std::function<void(const fs::path& tmp)>& write) {
    const fs::path tmp = temporaryPathFor(path);
    std::error_code ec;
    try {
        write(tmp);
    } catch (...) {
        fs::remove(tmp, ec);
        throw;
    }
    fs::rename(tmp, path, ec);
    if (ec) {
        const std::string reason = ec.message();
        fs::remove(tmp, ec);
        throw WriteError(path.string() + ": cannot move the written file into place: " + reason);
    }
}

void writeFileAtomic(const fs::path& path, const std::string& bytes) {
    AtomicFileWriter out(path);
    out.write(bytes.data(), bytes.size());
    out.commit();
}

AtomicFileWriter::AtomicFileWriter(fs::path path) : m_path(std::move(path)) {
    fs::path tmp = temporaryPathFor(m_path);
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
        const std::string reason = ec.message();
        fs::remove(m_tmp, ec);
        m_tmp.clear();
        throw WriteError(m_path.string() + ": cannot move the written file into place: " + reason);
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
