#pragma once
/** How every output file is written: through a temporary file in the same folder, renamed into
 *  place when complete, so that no reader ever sees a half-written file under the final name.
 *
 *  The temporary name is unique per process and writer: `.<name>.<pid>.<n>.part` beside
 *  `<name>` (hidden, the writer's process id, a counter of the process). Concurrent writers of
 *  the same final name never share a temporary file; the last rename wins, atomically. A
 *  temporary file left behind by a process that died (kill -9, power loss) ends in `.part` and
 *  names its writer's pid: temporaryWriterPid() reads it back, so a cleaner can tell whether the
 *  writer still runs. When `<name>` is too long for the file system's 255-byte names with the
 *  additions, it is shortened in the temporary name (the final name is never changed). */
#include <cstddef>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

namespace fvr::core {

/** A fresh temporary path for `path` as described above (nothing is created). */
std::filesystem::path temporaryPathFor(const std::filesystem::path& path);

/** The writer's process id when `tmp`'s file name has the form of temporaryPathFor()'s names
 *  (`.<name>.<pid>.<n>.part`); nullopt for any other name. */
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
