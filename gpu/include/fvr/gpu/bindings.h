#pragma once
/** The binding points that the host and the compute shaders share: shader storage buffers, the
 *  display image and the spectrum's and the volume's texture units. This header is their one home:
 * the shaders
 *  `#include "common/bindings.glsl"`, which ShaderSource::defaultReader() generates from
 *  bindingsGlsl() (the numbers below as `#define FVR_BINDING_<NAME> <point>` lines), so the host
 *  and the GLSL cannot disagree. A shader naming a binding missing from kGlslBindings fails to
 *  compile (undefined identifier). No GL here. */
#include <string>

namespace fvr::gpu {

/** Shader storage buffer binding points (GL_SHADER_STORAGE_BUFFER). OpenGL 4.3 guarantees 8 per
 *  compute shader, so the spectral-sum pass, which runs on its own, reuses points 1..5 for its
 *  material frames. */
enum class Binding : unsigned {
    PassOutput = 0, ///< each pass's output: slice, rows, columns, Hartley correction, sum
    PassInput = 1, ///< each pass's input: rows (unfused), columns, Hartley, display
    KernelTable = 2, ///< core::KernelTable::table of the interpolation kernel
    Twiddles = 3, ///< FftPlan::twiddles of the row and column passes
    KernelDerivative = 4, ///< core::KernelTable::derivativeTable (depth cueing)
    FilterAxis = 5, ///< core::SliceFilterTable::axis (blur, pixel aperture)
    SpectralTable = 6, ///< core::SpectralResponse::tableNodes (spectral sum)
    Material0 = 1, ///< spectral sum: the material frames, one per material (at most 5)
    Material1 = 2,
    Material2 = 3,
    Material3 = 4,
    Material4 = 5,
};

/** Image units (glBindImageTexture). */
enum class ImageUnit : unsigned {
    Display = 0, ///< the RGBA8 display texture the display mapping writes
};

/** Texture units (glActiveTexture, sampler uniforms). */
enum class TextureUnit : unsigned {
    Spectrum = 0, ///< the spectrum's 3D texture the slice samples
    Volume = 1, ///< the (mapped) volume's 3D texture the cone-beam ray caster samples
    Occupancy = 2, ///< the cone-beam ray caster's map of non-empty 8^3 blocks
};

/** One GLSL name: `#define FVR_<glsl> <point>`. */
struct BindingName {
    const char* glsl;
    unsigned point;
};

/** Every binding point and unit above with its GLSL name; bindingsGlsl() writes these. */
inline constexpr BindingName kGlslBindings[] = {
    {"BINDING_PASS_OUTPUT", unsigned(Binding::PassOutput)},
    {"BINDING_PASS_INPUT", unsigned(Binding::PassInput)},
    {"BINDING_KERNEL_TABLE", unsigned(Binding::KernelTable)},
    {"BINDING_TWIDDLES", unsigned(Binding::Twiddles)},
    {"BINDING_KERNEL_DERIVATIVE", unsigned(Binding::KernelDerivative)},
    {"BINDING_FILTER_AXIS", unsigned(Binding::FilterAxis)},
    {"BINDING_SPECTRAL_TABLE", unsigned(Binding::SpectralTable)},
    {"BINDING_MATERIAL_0", unsigned(Binding::Material0)},
    {"BINDING_MATERIAL_1", unsigned(Binding::Material1)},
    {"BINDING_MATERIAL_2", unsigned(Binding::Material2)},
    {"BINDING_MATERIAL_3", unsigned(Binding::Material3)},
    {"BINDING_MATERIAL_4", unsigned(Binding::Material4)},
    {"IMAGE_DISPLAY", unsigned(ImageUnit::Display)},
    {"TEXTURE_SPECTRUM", unsigned(TextureUnit::Spectrum)},
    {"TEXTURE_VOLUME", unsigned(TextureUnit::Volume)},
    {"TEXTURE_OCCUPANCY", unsigned(TextureUnit::Occupancy)},
};

/** The material frame binding of material `m` (0..4) in the spectral sum. */
constexpr Binding materialBinding(unsigned m) {
    constexpr Binding frames[] = {Binding::Material0, Binding::Material1, Binding::Material2,
                                  Binding::Material3, Binding::Material4};
    return frames[m];
}

constexpr unsigned point(Binding b) { return unsigned(b); }
constexpr unsigned point(ImageUnit u) { return unsigned(u); }
constexpr unsigned point(TextureUnit u) { return unsigned(u); }

/** The include path under which ShaderSource::defaultReader() serves bindingsGlsl(). */
inline constexpr const char* kBindingsInclude = "common/bindings.glsl";

/** The text of common/bindings.glsl: one `#define FVR_<name> <point>` line per kGlslBindings
 *  entry, after a comment saying where it comes from. */
std::string bindingsGlsl();

} // namespace fvr::gpu
