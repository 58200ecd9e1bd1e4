// GpuFourierRenderer::spectralSum: the polychromatic spectral sum as one compute pass over the
// material frames on the GPU (resources/shaders/xray/spectral_sum.comp).
#include <fvr/gpu/gpu_renderer.h>

#include <epoxy/gl.h>

#include <utility>

#include <fvr/core/errors.h>
#include <fvr/gpu/bindings.h>
#include <fvr/gpu/errors.h>
#include <fvr/gpu/shader_program.h>

namespace fvr::gpu {

void GpuFourierRenderer::spectralSum(const std::vector<const GpuFourierRenderer*>& materials,
                                     const std::shared_ptr<const core::SpectralResponse>& response,
                                     SpectralOutput output, int show) {
    using core::SettingsError;
    if (!response || materials.size() != response->materials())
        throw SettingsError("GPU spectral sum: expected one frame per material of the response");
    if (materials.size() > 5) throw SettingsError("GPU spectral sum: at most 5 materials");
    if (output == SpectralOutput::Material && (show < 0 || std::size_t(show) >= materials.size()))
        throw SettingsError("GPU spectral sum: no material " + std::to_string(show));
    const int M = materials.front()->m_size;
    for (const auto* m : materials)
        if (!m || m->m_size != M || !M)
            throw SettingsError("GPU spectral sum: the material frames differ in size or are "
                                "missing");
    if (m_size != M) throw SettingsError("GPU spectral sum: render a frame of this size first");
    if (m_tableFor != response) { // upload the table once per response
        const auto& nodes = response->tableNodes();
        if (!m_table) glGenBuffers(1, &m_table);
        glBindBuffer(GL_SHADER_STORAGE_BUFFER, m_table);
        glBufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(nodes.size() * sizeof(float)),
                     nodes.data(), GL_STATIC_DRAW);
        m_tableFor = response;
    }
    const auto& r = *response;
    const int n = core::SpectralResponse::kTableSize;
    const GLuint prog =
        program("xray/spectral_sum.comp", {{"MATERIALS", std::to_string(materials.size())}});
    glUseProgram(prog);
    auto loc = [&](const char* name) { return glGetUniformLocation(prog, name); };
    glUniform1i(loc("uCount"), M * M);
    glUniform1i(loc("uN"), n);
    glUniform1i(loc("uStride"), r.tableStride());
    glUniform1i(loc("uHasY"), r.axisY() >= 0 ? 1 : 0);
    glUniform1f(loc("uSx"), float((n - 1) / r.tableExtent(0)));
    glUniform1f(loc("uSy"), float((n - 1) / r.tableExtent(1)));
    glUniform1f(loc("uUnit"), 0.1f); // rho x mm -> g/cm^2
    glUniform1i(loc("uAxisX"), r.axisX());
    glUniform1i(loc("uAxisY"), std::max(0, r.axisY()));
    glUniform1i(loc("uOthers"), int(r.otherMaterials().size()));
    int other[4] = {0, 0, 0, 0};
    float scale[4] = {0, 0, 0, 0};
    for (std::size_t o = 0; o < r.otherMaterials().size() && o < 4; ++o) {
        other[o] = r.otherMaterials()[o];
        scale[o] = float(r.otherScales()[o]);
    }
    glUniform1iv(loc("uOther"), 4, other);
    glUniform1fv(loc("uScale"), 4, scale);
    glUniform1i(loc("uOutput"), int(output));
    glUniform1i(loc("uShow"), show);
    for (std::size_t m = 0; m < materials.size(); ++m)
        bindStorage(materialBinding(unsigned(m)), materials[m]->m_image);
    bindStorage(Binding::SpectralTable, m_table);
    bindStorage(Binding::PassOutput, m_hartleyT); // scratch of M x M floats
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    glDispatchCompute(GLuint((M * M + 255) / 256), 1, 1);
    glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT);
    std::swap(m_image, m_hartleyT); // the sum is this renderer's frame now
    m_displayed.reset();
    if (const GLenum err = glGetError(); err != GL_NO_ERROR)
        throw GlError("GPU spectral sum failed: GL error " + std::to_string(err));
}

} // namespace fvr::gpu
