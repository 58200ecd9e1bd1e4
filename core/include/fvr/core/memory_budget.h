#pragma once
/** How much memory this process may still take, so that sizes read from a file (a header's
 *  dimensions, a DICOM series' rows x columns x frames) are checked before they are allocated:
 *  a hostile or broken header ends in a message giving both numbers, not in gigabytes of
 *  allocation and "out of memory" (or the kernel's OOM killer). */
#include <cstdint>
#include <string>

namespace fvr::core {

/** The memory this process may still allocate and what limits it. */
struct MemoryBudget {
    std::uint64_t bytes = 0;
    /** What sets the limit, for messages: "MemAvailable in /proc/meminfo", "RLIMIT_AS",
     *  "RLIMIT_DATA", "the cgroup's memory limit" or "FVR_MEMORY_LIMIT_MB". */
    std::string limitedBy;
};

/** The environment variable that replaces the detected budget: a positive number of MiB (larger
 *  than the memory available to let swap take the rest, smaller to keep a process small). */
inline constexpr char kMemoryLimitVariable[] = "FVR_MEMORY_LIMIT_MB";

/**
 * FVR_MEMORY_LIMIT_MB when set; else the smallest of the memory available (MemAvailable in
 * /proc/meminfo, else sysconf(_SC_AVPHYS_PAGES)), what the process's RLIMIT_AS and RLIMIT_DATA
 * leave beyond its current size, and what its cgroup's memory limit leaves. Throws SettingsError
 * when FVR_MEMORY_LIMIT_MB is not a positive number.
 */
MemoryBudget memoryBudget();

/**
 * Throws LoadError "<source>: <what> needs N bytes (X MiB), more than the M bytes (Y MiB) of
 * memory this process may still take (<limitedBy>; FVR_MEMORY_LIMIT_MB changes the limit)" when
 * `bytes` exceeds memoryBudget(). Call it before allocating what a file declares.
 */
void checkMemoryFor(std::uint64_t bytes, const std::string& source, const std::string& what);

} // namespace fvr::core
