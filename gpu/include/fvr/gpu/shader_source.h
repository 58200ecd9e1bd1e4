#pragma once
/** Shader text assembly: `#include "path"` resolution (each file once), host defines inserted
 *  after `#version`, and a line map so compiler messages point at the original file and line.
 *  No GL here: testable on its own. */
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace fvr::gpu {

class ShaderSource {
public:
    /** Returns a file's text, or nothing when it does not exist. */
    using Reader = std::function<std::optional<std::string>(const std::string& path)>;
    using Defines = std::vector<std::pair<std::string, std::string>>;

    /** Assembles `path` (e.g. "fft/rows.comp"); throws ShaderError for a missing file, an
     *  include cycle or a missing #version. */
    static ShaderSource assemble(const std::string& path, const Defines& defines,
                                 const Reader& reader);
    /** Reader for the shaders embedded in fvr::gpu (resources/shaders at build time), or
     *  FVR_SHADER_DIR when set (edit shaders without rebuilding). Either way it serves
     *  "common/bindings.glsl" from bindingsGlsl() (fvr/gpu/bindings.h). */
    static Reader defaultReader();
    /** The paths of the embedded shaders (files of resources/shaders, e.g. "fft/rows.comp"). */
    static std::vector<std::string> embeddedPaths();

    const std::string& text() const { return m_text; }
    const std::string& path() const { return m_path; }
    /** "file:line" of line `line` (1-based) of text(). */
    std::string locate(int line) const;
    /** Rewrites a driver's compile log ("0:12(5): error", "0(12) : error", "ERROR: 0:12:") so
     *  each message names file:line. */
    std::string mapLog(const std::string& log) const;

private:
    std::string m_path;
    std::string m_text;
    std::vector<std::pair<std::string, int>> m_lines; // origin of each output line
};

} // namespace fvr::gpu
