#include <fvr/gpu/shader_source.h>

#include <cstdlib>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include <fvr/gpu/bindings.h>
#include <fvr/gpu/errors.h>

#include "embedded_shaders.h"

namespace fvr::gpu {

namespace {
void expand(const std::string& path, const ShaderSource::Reader& reader,
            std::set<std::string>& done, std::vector<std::string>& stack, std::string& out,
            std::vector<std::pair<std::string, int>>& lines) {
    for (const auto& s : stack)
        if (s == path) throw ShaderError(path + ": include cycle");
    if (done.count(path)) return; // each file once
    const auto text = reader(path);
    if (!text)
        throw ShaderError(stack.empty()
                              ? path + ": shader not found"
                              : stack.back() + ": included file '" + path + "' not found");
    done.insert(path);
    stack.push_back(path);
    std::istringstream in(*text);
    std::string line;
    int n = 0;
    static const std::regex include(R"(^\s*#\s*include\s+"([^"]+)\"\s*$)");
    while (std::getline(in, line)) {
        ++n;
        std::smatch m;
        if (std::regex_match(line, m, include)) {
            expand(m[1].str(), reader, done, stack, out, lines);
            continue;
        }
        out += line;
        out += '\n';
        lines.emplace_back(path, n);
    }
    stack.pop_back();
}
} // namespace

ShaderSource ShaderSource::assemble(const std::string& path, const Defines& defines,
                                    const Reader& reader) {
    ShaderSource s;
    s.m_path = path;
    std::string body;
    std::vector<std::pair<std::string, int>> lines;
    std::set<std::string> done;
    std::vector<std::string> stack;
    expand(path, reader, done, stack, body, lines);
    // #version must stay first: insert the defines right after it.
    const auto nl = body.find('\n');
    if (body.rfind("#version", 0) != 0 || nl == std::string::npos)
        throw ShaderError(path + ":1: expected '#version' on the first line");
    s.m_text = body.substr(0, nl + 1);
    s.m_lines.push_back(lines.front());
    for (const auto& [name, value] : defines) {
        s.m_text += "#define " + name + " " + value + "\n";
        s.m_lines.emplace_back("<host define " + name + ">", 0);
    }
    s.m_text += body.substr(nl + 1);
    s.m_lines.insert(s.m_lines.end(), lines.begin() + 1, lines.end());
    return s;
}

ShaderSource::Reader ShaderSource::defaultReader() {
    return [](const std::string& path) -> std::optional<std::string> {
        // Generated from the host's binding points, also under FVR_SHADER_DIR: one home.
        if (path == kBindingsInclude) return bindingsGlsl();
        if (const char* dir = std::getenv("FVR_SHADER_DIR"); dir && *dir) {
            std::ifstream in(std::string(dir) + "/" + path);
            if (!in) return std::nullopt;
            std::stringstream ss;
            ss << in.rdbuf();
            return ss.str();
        }
        for (std::size_t i = 0; i < detail::kEmbeddedShaderCount; ++i)
            if (path == detail::kEmbeddedShaders[i].path)
                return std::string(detail::kEmbeddedShaders[i].text);
        return std::nullopt;
    };
}

std::vector<std::string> ShaderSource::embeddedPaths() {
    std::vector<std::string> paths;
    for (std::size_t i = 0; i < detail::kEmbeddedShaderCount; ++i)
        paths.emplace_back(detail::kEmbeddedShaders[i].path);
    return paths;
}

std::string ShaderSource::locate(int line) const {
    if (line < 1 || line > int(m_lines.size())) return m_path + ":?";
    const auto& [file, n] = m_lines[std::size_t(line - 1)];
    return file + ":" + std::to_string(n);
}

std::string ShaderSource::mapLog(const std::string& log) const {
    static const std::regex loc(R"((?:^|\s)(?:ERROR:\s*)?0[:(](\d+)[)]?)");
    std::istringstream in(log);
    std::string line, out;
    while (std::getline(in, line)) {
        std::smatch m;
        if (std::regex_search(line, m, loc)) out += locate(std::stoi(m[1].str())) + ": ";
        out += line + "\n";
    }
    return out;
}

} // namespace fvr::gpu
