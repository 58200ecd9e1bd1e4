// The memory budget: what a process may still allocate (memory_budget.h).
#include <fvr/core/memory_budget.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <limits>
#include <sstream>

#include <sys/resource.h>
#include <unistd.h>

#include <fvr/core/errors.h>
#include <fvr/core/text.h>

namespace fvr::core {

namespace {

constexpr std::uint64_t kUnlimited = std::numeric_limits<std::uint64_t>::max();

/** MemAvailable (bytes) from /proc/meminfo; else the free pages sysconf reports. */
std::uint64_t availableMemory() {
    std::ifstream in("/proc/meminfo");
    std::string key, unit;
    std::uint64_t kb = 0;
    while (in >> key >> kb) {
        std::getline(in, unit);
        if (key == "MemAvailable:") return kb * 1024;
    }
    const long pages = sysconf(_SC_AVPHYS_PAGES), page = sysconf(_SC_PAGESIZE);
    return pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : kUnlimited;
}

/** Field `index` of /proc/self/statm in bytes (0: the whole virtual size, 5: data + stack). */
std::uint64_t statmBytes(int index) {
    std::ifstream in("/proc/self/statm");
    std::uint64_t v = 0;
    for (int i = 0; i <= index; ++i)
        if (!(in >> v)) return 0;
    return v * std::uint64_t(sysconf(_SC_PAGESIZE));
}

/** What the soft limit `resource` leaves beyond `used` bytes (kUnlimited when none). */
std::uint64_t rlimitLeft(int resource, std::uint64_t used) {
    rlimit rl{};
    if (getrlimit(resource, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY) return kUnlimited;
    const auto limit = std::uint64_t(rl.rlim_cur);
    return limit > used ? limit - used : 0;
}

std::uint64_t readNumber(const std::string& file) {
    std::ifstream in(file);
    std::string s;
    if (!(in >> s) || s == "max") return kUnlimited;
    return parseNumber<std::uint64_t>(s).value_or(kUnlimited);
}

/** What the cgroup's memory limit leaves (v2 memory.max, v1 memory.limit_in_bytes), read at
 *  the process's own cgroup path and, inside a container's namespace, at the root. */
std::uint64_t cgroupLeft() {
    std::ifstream in("/proc/self/cgroup");
    std::string line, v1, v2;
    while (std::getline(in, line)) {
        if (line.rfind("0::", 0) == 0) v2 = line.substr(3);
        const auto at = line.find(":memory:");
        if (at != std::string::npos) v1 = line.substr(at + 8);
    }
    const auto left = [](const std::string& limit, const std::string& usage) {
        const std::uint64_t l = readNumber(limit);
        if (l == kUnlimited) return kUnlimited;
        const std::uint64_t u = readNumber(usage);
        return u == kUnlimited ? l : (l > u ? l - u : 0);
    };
    std::uint64_t best = kUnlimited;
    for (const std::string& dir : {"/sys/fs/cgroup" + v2, std::string("/sys/fs/cgroup")})
        best = std::min(best, left(dir + "/memory.max", dir + "/memory.current"));
    for (const std::string& dir :
         {"/sys/fs/cgroup/memory" + v1, std::string("/sys/fs/cgroup/memory")})
        best = std::min(best, left(dir + "/memory.limit_in_bytes", dir + "/memory.usage_in_bytes"));
    return best;
}

std::string mib(std::uint64_t bytes) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.1f MiB", double(bytes) / (1024.0 * 1024.0));
    return buf;
}

} // namespace

MemoryBudget memoryBudget() {
    if (const char* env = std::getenv(kMemoryLimitVariable); env && *env) {
        // Not strtod: the workstation runs in the user's locale, where "1.5" may not be a number.
        const double mb = parseNumber<double>(env).value_or(0.0);
        if (!(mb > 0.0) || !std::isfinite(mb) || mb > 1e12)
            throw SettingsError(std::string(kMemoryLimitVariable) +
                                ": expected a positive number of MiB, found '" + env + "'");
        return {std::uint64_t(mb * 1024.0 * 1024.0), kMemoryLimitVariable};
    }
    MemoryBudget b{availableMemory(), "MemAvailable in /proc/meminfo"};
    const auto tighter = [&b](std::uint64_t bytes, const char* what) {
        if (bytes < b.bytes) b = {bytes, what};
    };
    tighter(rlimitLeft(RLIMIT_AS, statmBytes(0)), "RLIMIT_AS");
    tighter(rlimitLeft(RLIMIT_DATA, statmBytes(5)), "RLIMIT_DATA");
    tighter(cgroupLeft(), "the cgroup's memory limit");
    return b;
}

void checkMemoryFor(std::uint64_t bytes, const std::string& source, const std::string& what) {
    const MemoryBudget b = memoryBudget();
    if (bytes <= b.bytes) return;
    std::ostringstream os;
    os << source << ": " << what << " needs " << bytes << " bytes (" << mib(bytes)
       << "), more than the " << b.bytes << " bytes (" << mib(b.bytes)
       << ") of memory this process may still take (" << b.limitedBy << "; " << kMemoryLimitVariable
       << " changes the limit)";
    throw LoadError(os.str());
}

} // namespace fvr::core
