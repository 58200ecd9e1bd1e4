#pragma once
/** How every output file is written: through a temporary file in the same folder, renamed into
 *  place when complete, so that no reader ever sees a half-written file under the final name.
 *
 *  The temporary name is unique per process and writer: `.<name>.<pid>-<id>.<n>.part` beside
 *  `<name>` (hidden, the writer's process id, writerIdentity(), a counter of the process).
 *  Concurrent writers of the same final name never share a temporary file; the last rename
 *  wins, atomically. A temporary file left behind by a process that died (kill -9, power loss)
 *  ends in `.part` and names its writer: temporaryWriterPid() reads the pid back when the
 *  writer ran in this pid space, so a cleaner can tell whether it still runs. A temporary of
 *  another host or container (a folder shared over NFS, a dataset run's workers on several
 *  machines) has another identity: its pid means nothing here, and cleaners never remove it.
 *  The older form `.<name>.<pid>.<n>.part` (no identity) is still read as this pid space's.
 *  When `<name>` is too long for the file system's 255-byte names with the additions, it is
 *  shortened in the temporary name (the final name is never changed). */
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace fvr::core {

/** This process's pid space in 8 lower-case hex digits: FNV-1a of the host name and the pid
 *  namespace (/proc/self/ns/pid). Processes of one host share it (pids there can be checked
 *  with kill(pid, 0)); another host, or a container with its own pid namespace, has another
 *  (the same only by a 1 in 2^32 chance, or for two hosts of the same name outside
 *  containers). */
std::string writerIdentity();

/** A fresh temporary path for `path` as described above (nothing is created). */
std::filesystem::path temporaryPathFor(const std::filesystem::path& path);

/** The writer's process id when `tmp`'s file name has the form of temporaryPathFor()'s names
 *  with this process's writerIdentity() (`.<name>.<pid>-<id>.<n>.part`), or the older form
 *  without one (`.<name>.<pid>.<n>.part`); nullopt for any other name, and for a temporary of
 *  another identity (its writer's pid cannot be checked here: it must be kept). */
std::optional<long> temporaryWriterPid(const std::filesystem::path& tmp);

/**
 * Calls `write` with a temporary path (temporaryPathFor), then renames it to `path`. When
 * `write` throws or the rename fails, the temporary file is removed; the rename failure throws
 * WriteError "<path>: cannot move the written file into place: <reason>".
 */
void writeAtomically(const std::filesystem::path& path,
                     const std::function<void(const std::filesystem::path& tmp)>& write);

/** `bytes` as the content, through AtomicFileWriter (below). Throws WriteError naming `path`
 *  and the system's reason ("cannot open for writing: Not a directory", "write failed: No space
 *  left on device"). */
void writeFileAtomic(const std::filesystem::path& path, const std::string& bytes);

/**
 * A file written piece by piece (a stack written as it is produced) under the same rule:
 * the bytes go to a temporary file (temporaryPathFor), commit() renames it to `path`; destroyed
 * without a commit (an error, an exception), it removes the temporary file. Errors throw
 * WriteError naming `path` and the system's reason: "cannot open for writing: ...", "write
 * failed: No space left on device".
 */
class AtomicFileWriter {
public:
    explicit AtomicFileWriter(std::filesystem::path path);
    ~AtomicFileWriter();
    AtomicFileWriter(const AtomicFileWriter&) = delete;
    AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

    const std::filesystem::path& path() const { return m_path; }
    /** Appends `size` bytes (the whole of them, or throws). */
    void write(const void* data, std::size_t size);
    /** Closes the file and moves it into place; nothing can be written after. */
    void commit();

private:
    [[noreturn]] void fail(const std::string& what, int err);
    void discard() noexcept;

    std::filesystem::path m_path, m_tmp;
    int m_fd = -1;
};

} // namespace fvr::core
