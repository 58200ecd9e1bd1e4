#pragma once
/** How every output file is written: through `<path>.part`, renamed into place when complete,
 *  so that no reader ever sees a half-written file under the final name. */
#include <cstddef>
#include <filesystem>
#include <functional>
#include <string>

namespace fvr::core {

/**
 * Calls `write` with the temporary path `<path>.part`, then renames it to `path`. When `write`
 * throws or the rename fails, the temporary file is removed; the rename failure throws
 * WriteError "<path>: cannot move the written file into place".
 */
void writeAtomically(const std::filesystem::path& path,
                     const std::function<void(const std::filesystem::path& tmp)>& write);

/** `bytes` as the content, through AtomicFileWriter (below). Throws WriteError naming `path`
 *  and the system's reason ("cannot open for writing: Not a directory", "write failed: No space
 *  left on device"). */
void writeFileAtomic(const std::filesystem::path& path, const std::string& bytes);

/**
 * A file written piece by piece (a stack written as it is produced) under the same rule:
 * the bytes go to `<path>.part`, commit() renames it to `path`; destroyed without a commit (an
 * error, an exception), it removes the temporary file. Errors throw WriteError naming `path` and
 * the system's reason: "cannot open for writing: ...", "write failed: No space left on device".
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
