#include <fvr/gpu/shader_program.h>

#include <epoxy/gl.h>

#include <algorithm>

#include <fvr/gpu/errors.h>

namespace fvr::gpu {

namespace {
std::string shaderLog(GLuint shader) {
    GLint len = 0;
    glGetShaderiv(shader, GL_INFO_LOG_LENGTH, &len);
    std::string log(std::size_t(std::max(len, 1)), '\0');
    glGetShaderInfoLog(shader, len, nullptr, log.data());
    return log.c_str(); // without the terminating zeros
}

std::string programLog(GLuint program) {
    GLint len = 0;
    glGetProgramiv(program, GL_INFO_LOG_LENGTH, &len);
    std::string log(std::size_t(std::max(len, 1)), '\0');
    glGetProgramInfoLog(program, len, nullptr, log.data());
    return log.c_str();
}
} // namespace

unsigned compileComputeProgram(const ShaderSource& source, const std::string& name) {
    const GLuint sh = glCreateShader(GL_COMPUTE_SHADER);
    const char* text = source.text().c_str();
    glShaderSource(sh, 1, &text, nullptr);
    glCompileShader(sh);
    GLint ok = 0;
    glGetShaderiv(sh, GL_COMPILE_STATUS, &ok);
    if (!ok) {
        const std::string log = shaderLog(sh);
        glDeleteShader(sh);
        throw ShaderError("shader " + name + " failed to compile:\n" + source.mapLog(log));
    }
    const GLuint prog = glCreateProgram();
    glAttachShader(prog, sh);
    glLinkProgram(prog);
    glDeleteShader(sh);
    glGetProgramiv(prog, GL_LINK_STATUS, &ok);
    if (!ok) {
        const std::string log = programLog(prog);
        glDeleteProgram(prog);
        throw ShaderError("shader " + name + " failed to link:\n" + source.mapLog(log));
    }
    return prog;
}

void bindStorage(Binding binding, unsigned buffer) {
    glBindBufferBase(GL_SHADER_STORAGE_BUFFER, point(binding), buffer);
}

} // namespace fvr::gpu
