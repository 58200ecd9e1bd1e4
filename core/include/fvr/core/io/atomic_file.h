#pragma once
/** How every output file is written: through `<path>.part`, renamed into place when complete,
 *  so that no reader ever sees a half-written file under the final name. */
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

/** writeAtomically with `bytes` as the content. Throws WriteError naming `path` ("cannot open
 *  for writing", "write failed (disk full?)"). */
void writeFileAtomic(const std::filesystem::path& path, const std::string& bytes);

} // namespace fvr::core
